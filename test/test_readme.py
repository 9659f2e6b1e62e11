"""The README's Python examples run as pasted, from the repository root."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = re.findall(r'```python\n(.*?)```', (ROOT / 'README.md').read_text(), re.S)


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 2


@pytest.mark.parametrize('block', BLOCKS, ids=lambda b: b.splitlines()[1][:40])
def test_a_readme_example_runs_as_pasted(block, monkeypatch):
    monkeypatch.chdir(ROOT)
    exec(compile(block, 'README.md', 'exec'), {})
