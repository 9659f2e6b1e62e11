"""Fixtures of the repository's tests (system/: the nodes as processes): every ROS process stays on loopback, in a
domain of this run's own."""

import os
import subprocess
import sys
import time

import pytest

# Set before any rclpy import in this process and inherited by every child.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(os.getpid() % 90 + 10))
os.environ.setdefault('MPLBACKEND', 'Agg')

BIN = os.path.dirname(sys.executable)


@pytest.fixture
def run_tool():
    """Run one of the project's console scripts; returns the CompletedProcess."""
    def run(name, *args, timeout=120):
        return subprocess.run([os.path.join(BIN, name), *map(str, args)], capture_output=True,
                              text=True, timeout=timeout, env=os.environ.copy())
    return run


LOG_TAIL = 60          # lines of each node's log in a failing test's report


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    item.started_at = time.monotonic()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failing system test's report ends with the logs of the nodes that ran during it, and the stacks of every
    thread of each (those still running are asked now; rosstack's running_stack asks its nodes as the failure stops
    them)."""
    report = (yield).get_result()
    if not report.failed:
        return
    from picking_bringup.stack import NodeProcess, write_stacks
    since = getattr(item, 'started_at', 0.0)
    ran = [p for p in NodeProcess.started if p.stopped_at is None or p.stopped_at >= since]
    write_stacks(ran)
    for proc in ran:
        log, stacks = _stacks_apart(proc.output())
        lines = log.splitlines()[-LOG_TAIL:]
        report.sections.append((f'{proc.name} (pid {proc.pid}) log, last {len(lines)} lines', '\n'.join(lines)))
        if stacks:
            report.sections.append((f'{proc.name} (pid {proc.pid}) threads', stacks))


def _stacks_apart(output):
    """A node's log lines and the lines of the thread stacks its faulthandler wrote among them ('' if none)."""
    log, stacks = [], []
    for line in output.splitlines():
        dump = line.startswith(('Thread 0x', 'Current thread 0x', '  File "', '  <no Python frame>'))
        (stacks if dump else log).append(line)
    return '\n'.join(log), '\n'.join(stacks)


def pytest_addoption(parser):
    parser.addoption('--cpu-load', type=int, default=0, metavar='N',
                     help='run the tests beside N CPU-bound processes (make test-load: 4 on the two cores)')


def pytest_configure(config):
    config.addinivalue_line('markers', 'load: one of the end-to-end tests make test-load runs on a busy machine')


@pytest.fixture(scope='session', autouse=True)
def cpu_load(request):
    """N busy processes for the whole run (--cpu-load N), as a perception pipeline loads the arm's
    computer; each is stopped by its pid at the end, and the load average is reported."""
    n = request.config.getoption('--cpu-load')
    burners = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(n)]
    try:
        yield n
    finally:
        if burners:
            load = os.getloadavg()
            for p in burners:
                p.kill()
                p.wait()
            request.config.load_report = f'{n} CPU-bound processes; load average at the end {load[0]:.1f}'


def pytest_terminal_summary(terminalreporter, config):
    """The goals the test clients followed, by how they ended (none may be left without a result)."""
    if getattr(config, 'load_report', None):
        terminalreporter.write_line(f'under load: {config.load_report}')
    try:
        from rosstack import FINAL, GOALS, KILLED
    except ImportError:                      # no system test ran
        return
    if GOALS:
        ends = {state: sum(1 for s in GOALS.values() if s == state) for state in (*FINAL, KILLED)}
        lost = sum(1 for s in GOALS.values() if s not in (*FINAL, KILLED))
        terminalreporter.write_line(f'goals followed: {len(GOALS)}; ' + ', '.join(
            f'{state} {n}' for state, n in ends.items()) + f'; without a result: {lost}')
