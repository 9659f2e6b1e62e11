"""Every entry point as a newcomer meets it: `--help` (exit 0, usage), missing arguments (exit 2, usage), every
example its help text and the README print (offline ones here; those that need the nodes against a running arm),
and the demo report's Markdown tables."""

import os
import re
import shlex
import subprocess
from pathlib import Path

import pytest
from rosstack import BIN

ROOT = Path(__file__).resolve().parents[2]
TOOLS = ('picking-stack', 'picking-goal', 'picking-plan', 'picking-demo', 'picking-sim', 'picking-controller',
         'picking-planner', 'picking-harvester', 'picking-state-publisher', 'picking-foxglove')
SUBCOMMANDS = [('picking-goal', s) for s in ('pose', 'pick', 'path', 'harvest', 'tree', 'stop')] + \
    [('picking-plan', s) for s in ('cubic', 'quintic', 'lspb', 'via-lspb', 'quintic-via', 'arc', 'workspace')]


def run(*args, timeout=120):
    return subprocess.run([str(BIN / args[0]), *map(str, args[1:])], capture_output=True, text=True,
                          timeout=timeout, env=os.environ.copy())


@pytest.mark.parametrize('tool', TOOLS)
def test_help_prints_usage_and_exits_0(tool):
    done = run(tool, '--help', timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('usage:') and 'Traceback' not in done.stderr


@pytest.mark.parametrize('tool, sub', SUBCOMMANDS)
def test_each_subcommand_has_help(tool, sub):
    done = run(tool, sub, '--help')
    assert done.returncode == 0 and done.stdout.startswith('usage:'), done.stderr


@pytest.mark.parametrize('args', [('picking-goal',), ('picking-goal', 'pick'), ('picking-goal', 'pose', 0.6),
                                  ('picking-goal', 'pose', 0.6, 0.1), ('picking-goal', 'path'),
                                  ('picking-goal', 'pose', 0.6, 0.1, 0.4, '--method', 'spline'),
                                  ('picking-plan', 'lspb', '--q0', 15), ('picking-plan', 'cubic'),
                                  ('picking-goal', 'harvest'), ('picking-goal', 'harvest', '--tree', 0),
                                  ('picking-sim', 'extra'), ('picking-stack', '--domain', 999),
                                  ('picking-stack', '--without', 'picking-planner'),
                                  ('picking-goal', 'stop', '--timeout', 'x'), ('picking-goal', 'stop', 'now'),
                                  ('picking-goal', 'stop', '--ros-args', '--timeout', 1)])
def test_missing_or_bad_arguments_exit_2_with_the_usage(args):
    done = run(*args)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert 'usage:' in done.stderr and 'Traceback' not in done.stderr, done.stderr


def examples(text, tool):
    """The command lines of ``tool`` in a help text or the README."""
    return [line.strip().split('#')[0].strip() for line in text.splitlines() if line.strip().startswith(tool + ' ')]


def test_every_picking_plan_example_runs(tmp_path):
    helps = run('picking-plan', '--help').stdout
    found = examples(helps, 'picking-plan') + examples((ROOT / 'README.md').read_text(), 'picking-plan')
    assert len(found) >= 5
    for line in found:
        args = shlex.split(line)[1:]
        if '--out' not in args:
            args += ['--out', tmp_path / 'plan']
        done = run('picking-plan', *args)
        assert done.returncode == 0, '\n'.join((line, done.stderr))


def test_picking_plan_takes_its_options_after_the_method_and_rest_for_any_number_of_joints(tmp_path):
    done = run('picking-plan', 'cubic', '--q0', 0, 0, '--qf', 1.2, -0.5, '--duration', 2, '--out', tmp_path)
    assert done.returncode == 0, done.stderr
    done = run('picking-plan', 'lspb', '--q0', 15, '--qf', 75, '--duration', 3, '--accel', 42, '--out', tmp_path)
    assert done.returncode == 0 and 'degrees? add --deg' in done.stderr


def test_the_demo_report_tables_parse():
    """Every row of every Markdown table of a report has as many cells as its header (no stray pipes)."""
    from picking_bringup.demo_report import _table
    text = _table(['joint', 'peak |v| [rad/s]', 'a'], [('x', 1, 2), ('y|z', 3, 4)])
    for table in re.findall(r'(?:^\|.*\|\n?)+', text, re.M):
        widths = {len(re.split(r'(?<!\\)\|', row.strip())) for row in table.strip().splitlines()}
        assert len(widths) == 1, table


def goal_examples():
    helps = run('picking-goal', '--help').stdout
    return sorted(set(examples(helps, 'picking-goal') + examples((ROOT / 'README.md').read_text(), 'picking-goal')))


def test_every_picking_goal_example_reaches_its_goal_on_a_running_arm(tmp_path):
    """They need the nodes: against a stack brought up as the README says. (`picking-goal tree` needs a
    platform of arms and its coordinator: test_platform.py runs it on one.)"""
    from picking_bringup.stack import Stack
    found = [line for line in goal_examples() if not line.startswith('picking-goal tree')]
    assert len(found) >= 6
    stack = Stack('/cli', tmp_path)
    try:
        stack.wait_ready()
        for line in found:
            done = run(*shlex.split(line), '--ros-args', '-r', '__ns:=/cli', timeout=120)
            assert done.returncode == 0, '\n'.join((line, done.stdout, done.stderr))
            if 'stop' not in line:
                # (An action goal's id is its UUID; a harvest, a topic goal, is named by its stamp.)
                assert 'succeeded' in done.stdout and re.search(r'goal ([0-9a-f]{32}|\d+\.\d{9})', done.stdout), \
                    done.stdout
    finally:
        codes = stack.stop()
    assert set(codes.values()) == {0}, codes


def test_every_picking_stack_example_brings_the_arm_up_and_down(tmp_path):
    """Each example of `picking-stack --help`, for 2 s once the arm is up (in this run's own domain)."""
    found = examples(run('picking-stack', '--help').stdout, 'picking-stack')
    assert len(found) >= 3
    for line in found:
        args = shlex.split(line)[1:]
        if '--domain' in args:                      # this run's own domain, never another
            args[args.index('--domain') + 1] = os.environ['ROS_DOMAIN_ID']
        if '--for' in args:                         # our own duration instead
            del args[args.index('--for'):args.index('--for') + 2]
        done = run('picking-stack', *args, '--for', 2, '--log-dir', tmp_path, timeout=120)
        assert done.returncode == 0, '\n'.join((line, done.stdout, done.stderr))
        assert 'is up' in done.stdout and 'exit code 0' in done.stdout, done.stdout


def test_a_stack_without_its_simulator_waits_for_a_driver_and_keeps_each_runs_logs_apart(tmp_path):
    """--without picking-sim starts the rest and waits for a real arm's joint_states; none comes here, so it
    gives up at its timeout saying what it waited for. Each run's logs are in a folder of their own, the newest
    linked as latest."""
    done = run('picking-stack', '--without', 'picking-sim', '--timeout', 8, '--log-dir', tmp_path, timeout=120)
    assert done.returncode == 1 and 'no joint_commands' in done.stderr, (done.stdout, done.stderr)
    assert 'started picking-sim' not in done.stdout and 'started picking-controller' in done.stdout
    latest = tmp_path / 'latest'
    assert latest.is_symlink() and 'waiting for joint_states' in (latest / 'root' / 'picking-controller.1.log').read_text()
    again = run('picking-stack', '--without', 'picking-sim', '--timeout', 1, '--log-dir', tmp_path, timeout=120)
    assert again.returncode == 1
    runs = [d for d in tmp_path.iterdir() if d.is_dir() and not d.is_symlink()]
    assert len(runs) == 2 and latest.resolve() == max(runs, key=lambda d: d.stat().st_mtime).resolve()


def test_a_node_that_fails_to_start_has_its_reason_printed_by_the_stack(tmp_path):
    done = run('picking-stack', '-p', 'picking_sim:publish_rate:=-5.0', '--timeout', 30, '--log-dir', tmp_path)
    assert done.returncode == 1, (done.stdout, done.stderr)
    assert 'picking-sim stopped by itself with exit code 2' in done.stderr, done.stderr
    assert 'publish_rate' in done.stderr.split('picking-sim stopped by itself')[1], done.stderr
    assert 'Traceback' not in done.stderr


def test_picking_goal_stop_cancels_a_pick_another_process_sent(tmp_path):
    """A pick sent by one picking-goal, stopped by another while it moves: the stop names what it canceled, the
    pick ends canceled (exit 3) with the arm braked to rest, and a stop with nothing running says so."""
    import time

    from picking_bringup.stack import Stack
    # A slow pick (about 20 s): a new process may need seconds of DDS discovery before it can ask anything.
    stack = Stack('/stop', tmp_path, args={'picking-planner': ['-p', 'speed_scale:=0.2']})
    try:
        stack.wait_ready()
        ns = ['--ros-args', '-r', '__ns:=/stop']
        pick = subprocess.Popen([str(BIN / 'picking-goal'), 'pick', '0.7', '0.15', '0.65', '--rpy', '0', '90', '0', *ns],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ.copy())
        lines = []
        for line in pick.stdout:                      # until the arm moves
            lines.append(line)
            if 'P1 approach' in line:
                break
        done = run('picking-goal', 'stop', *ns, timeout=60)
        rest = pick.communicate(timeout=60)[0]
        # (Each cancel goes as soon as its server is found: the controller's may brake the arm first, ending the pick
        # before the planner's cancel reaches it, so the stop may name either.)
        assert done.returncode == 0 and 'canceling (' in done.stdout, done.stdout
        assert 'pick' in done.stdout or 'follow_joint_trajectory' in done.stdout, done.stdout
        assert pick.returncode == 3 and 'canceled:' in rest, ''.join(lines) + rest
        assert rest.count('canceled') == 1, rest              # said once, not "canceled: canceled: ..."
        time.sleep(0.5)
        idle = run('picking-goal', 'stop', *ns, timeout=60)
        assert idle.returncode == 0 and 'no goal was running' in idle.stdout, idle.stdout
    finally:
        codes = stack.stop()
    assert set(codes.values()) == {0}, codes


def _stack_started(tmp_path, until='is up'):
    """`picking-stack` in a process group of its own, as a terminal runs it in the foreground, once a line of its
    output says ``until``; with the pids of the nodes it started (by name)."""
    import queue
    import threading
    proc = subprocess.Popen([str(BIN / 'picking-stack'), '--log-dir', str(tmp_path)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=os.environ.copy(), process_group=0)
    said = queue.Queue()

    def read():
        for line in proc.stdout:
            said.put(line)
        said.put('')                                 # the end of its output
    threading.Thread(target=read, daemon=True).start()
    pids, lines = {}, []
    while not any(until in line for line in lines):
        try:
            line = said.get(timeout=120)
        except queue.Empty:
            line = ''
        if not line:
            _leave_nothing(proc, pids)
            raise AssertionError(f'picking-stack never said {until!r}:\n' + ''.join(lines))
        lines.append(line)
        if m := re.match(r'picking-stack: started (\S+) \(pid (\d+)\)', line):
            pids[m[1]] = int(m[2])
    proc.said = said
    return proc, pids


def _running(pid):
    try:
        return Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0] != 'Z'
    except (FileNotFoundError, ProcessLookupError):
        return False


def _leave_nothing(proc, pids):
    """Kill (by pid) whatever a failed test left running."""
    for pid in [proc.pid, *pids.values()]:
        if _running(pid):
            os.kill(pid, 9)


@pytest.mark.parametrize('when', ['is up', 'started picking-planner'])
def test_ctrl_c_in_the_terminal_stops_the_stack_node_by_node(tmp_path, when):
    """Ctrl-C goes to the terminal's foreground process group: `picking-stack` alone gets it (each node runs in a
    group of its own) and stops the nodes one after the other, each with exit code 0; while the arm is still coming
    up, it stops them as soon, saying so (exit code 1: it never came up)."""
    import signal
    proc, pids = _stack_started(tmp_path, when)
    try:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
        out = ''.join(iter(lambda: proc.said.get(timeout=5), ''))
    finally:
        _leave_nothing(proc, pids)
    if when == 'is up':
        assert proc.returncode == 0, out
    else:
        assert proc.returncode == 1 and 'stopped before the arm in / was up' in out, out
    for name, pid in pids.items():
        assert f'stopped {name} (pid {pid}): exit code 0' in out, out


def test_nodes_stop_by_themselves_when_their_stack_is_killed(tmp_path):
    """A `picking-stack` killed before it could stop its nodes leaves none running: each sees its launcher go."""
    import signal
    import time
    proc, pids = _stack_started(tmp_path)
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 30
    while any(_running(pid) for pid in pids.values()) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = {name: pid for name, pid in pids.items() if _running(pid)}
    for pid in left.values():                        # its threads' stacks to its log (faulthandler), for the report
        os.kill(pid, signal.SIGUSR1)
    time.sleep(1.0 if left else 0.0)
    _leave_nothing(proc, pids)
    logs = {p.name: p.read_text() for p in (tmp_path / 'latest' / 'root').glob('*.log')}
    assert not left, {name: logs[f'{name}.1.log'][-3000:] for name in left}
    for name in pids:
        assert f'its launcher (pid {proc.pid}) is gone: stopping' in logs[f'{name}.1.log'], logs[f'{name}.1.log']
