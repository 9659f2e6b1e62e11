"""A node process stopped while it is still importing ends quietly (exit code 0, no traceback); a node started by
a launcher sees it go."""

import os
import signal
import subprocess
import sys
import time

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


#: A launcher that starts a "node" watching it with launcher_gone, says the node's pid, and waits to be killed.
LAUNCHER = '''
import os, subprocess, sys, time
node = (
    "import os, sys, time\\n"
    "from picking_common.startup import launcher_gone\\n"
    "gone = launcher_gone(os.environ)\\n"
    "print('watching', flush=True)\\n"
    "end = time.monotonic() + 30\\n"
    "while not gone() and time.monotonic() < end: time.sleep(0.05)\\n"
    "print('gone' if gone() else 'still there', flush=True)\\n")
child = subprocess.Popen([sys.executable, '-c', node], env={**os.environ, 'PICKING_LAUNCHER_PID': str(os.getpid())},
                         stdout=open(sys.argv[1], 'w'))
print(child.pid, flush=True)
time.sleep(60)
'''


def _launcher_killed(tmp_path, script, first):
    """Run launcher ``script`` (its node writes to the file its first argument names, ``tmp_path`` its second); once
    the node has written ``first``, kill the launcher; what the node wrote by the time it says 'gone' (20 s at most)."""
    out = tmp_path / 'node.out'
    launcher = subprocess.Popen([sys.executable, '-c', script, str(out), str(tmp_path)], stdout=subprocess.PIPE,
                                text=True)
    try:
        int(launcher.stdout.readline())                         # the node's pid: it runs
        deadline = time.monotonic() + 20
        while first not in out.read_text() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert 'gone' not in out.read_text()
        launcher.kill()
        launcher.wait()
        while 'gone' not in out.read_text() and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        launcher.kill()
    return out.read_text().split()


def test_a_node_sees_its_launcher_go(tmp_path):
    assert _launcher_killed(tmp_path, LAUNCHER, 'watching') == ['watching', 'gone']


#: A launcher whose "node" starts through quietly: its module takes 1.5 s to import, then watches with launcher_check.
SLOW_LAUNCHER = '''
import os, subprocess, sys, time
module = (
    "import time\\n"
    "print('importing', flush=True)\\n"
    "time.sleep(1.5)\\n"
    "def main():\\n"
    "    from picking_common.startup import launcher_check\\n"
    "    gone = launcher_check()\\n"
    "    end = time.monotonic() + 30\\n"
    "    while not gone() and time.monotonic() < end: time.sleep(0.05)\\n"
    "    print('gone' if gone() else 'still there', flush=True)\\n")
open(os.path.join(sys.argv[2], 'slow_watcher.py'), 'w').write(module)
node = f"import sys; sys.path.insert(0, {sys.argv[2]!r}); from picking_common.startup import quietly; quietly('slow_watcher:main')"
child = subprocess.Popen([sys.executable, '-c', node], env={**os.environ, 'PICKING_LAUNCHER_PID': str(os.getpid())},
                         stdout=open(sys.argv[1], 'w'))
print(child.pid, flush=True)
time.sleep(60)
'''


def test_a_node_whose_launcher_goes_while_it_still_imports_sees_it_go(tmp_path):
    # (Killed while the node's module still imports.)
    assert _launcher_killed(tmp_path, SLOW_LAUNCHER, 'importing') == ['importing', 'gone']


def test_a_launcher_variable_inherited_from_further_up_is_ignored():
    from picking_common.startup import LAUNCHER_PID, launcher_gone
    assert launcher_gone({LAUNCHER_PID: str(os.getppid())})() is False
    assert launcher_gone({LAUNCHER_PID: '1'})() is False          # not this process's parent: not its launcher
    assert launcher_gone({LAUNCHER_PID: 'x'})() is False
    assert launcher_gone({})() is False
