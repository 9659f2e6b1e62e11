"""A node process stopped while it is still importing ends quietly (exit code 0, no traceback)."""

import signal
import subprocess
import sys

import pytest

#: A module as slow to import as a node's: it says when its import has begun, then takes its time.
SLOW = '''
import sys, time
print('importing', flush=True)
time.sleep(30)

def main():
    return 0
'''


def _started(tmp_path, source, target):
    (tmp_path / 'slow_node.py').write_text(source)
    code = (f'import sys; sys.path.insert(0, {str(tmp_path)!r}); from picking_common.startup import quietly; '
            f'sys.exit(quietly({target!r}))')
    return subprocess.Popen([sys.executable, '-c', code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_a_node_stopped_while_it_imports_exits_0_saying_nothing(tmp_path, sig):
    proc = _started(tmp_path, SLOW, 'slow_node:main')
    try:
        assert proc.stdout.readline().strip() == 'importing'
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode == 0 and 'Traceback' not in err, err


def test_a_node_asked_for_its_stacks_while_it_imports_writes_them_and_goes_on(tmp_path):
    proc = _started(tmp_path, SLOW, 'slow_node:main')
    try:
        assert proc.stdout.readline().strip() == 'importing'
        proc.send_signal(signal.SIGUSR1)
        lines = [proc.stderr.readline() for _ in range(3)]
        assert proc.poll() is None
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert any('slow_node.py' in line for line in lines), lines
    assert proc.returncode == 0


def test_a_node_that_runs_gives_its_own_exit_code(tmp_path):
    proc = _started(tmp_path, 'def main():\n    return 3\n', 'slow_node:main')
    proc.communicate(timeout=20)
    assert proc.returncode == 3


def test_without_it_python_prints_a_traceback(tmp_path):
    # (Why the nodes start through it: the same import under Python's own handler.)
    (tmp_path / 'slow_node.py').write_text(SLOW)
    # (Python keeps Ctrl-C ignored in a process started with it ignored, as a test runner may start this one.)
    proc = subprocess.Popen([sys.executable, '-c', f'import sys; sys.path.insert(0, {str(tmp_path)!r}); '
                             'import slow_node'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stdout.readline().strip() == 'importing'
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode != 0 and 'KeyboardInterrupt' in err

