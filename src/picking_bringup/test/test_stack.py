"""picking-stack's run: the exit code and the logs it shows, with plain child processes for nodes."""

import argparse
import os
import sys
import threading
import time
from pathlib import Path

from picking_bringup.stack import NodeProcess, run

#: Exits 1 when asked to stop, after saying why on its output (as a node's faulthandler would).
UNCLEAN = ('import signal, sys, time\n'
           'def bye(*_):\n'
           '    print("a thread would not stop", flush=True)\n'
           '    sys.exit(1)\n'
           'signal.signal(signal.SIGINT, bye)\n'
           'print("up", flush=True)\n'
           'while True: time.sleep(0.05)\n')
CLEAN = UNCLEAN.replace('sys.exit(1)', 'sys.exit(0)').replace('a thread would not stop', 'bye')


class Stack:
    """The part of a Stack that ``run`` uses."""

    def __init__(self, log_dir, scripts):
        self.log_dir, self.ns = log_dir, '/'
        self.processes = [NodeProcess(Path(sys.executable).name, ['-c', s], log_dir / f'{i}.log')
                          for i, s in enumerate(scripts)]
        for i, p in enumerate(self.processes):        # exit codes go by name: each its own
            p.name = f'{i}'

    def wait_ready(self, timeout, stopping=None):
        for p in self.processes:
            deadline = time.monotonic() + timeout
            while 'up' not in p.output() and time.monotonic() < deadline:
                time.sleep(0.02)

    def alive(self):
        return {f'{i}': p.alive() for i, p in enumerate(self.processes)}

    def stop(self):
        return {f'{i}': p.stop(timeout=5.0) for i, p in enumerate(self.processes)}


def args():
    return argparse.Namespace(timeout=10.0, duration=0.2, platform=None, paper=False, foxglove=None)


def test_a_node_that_does_not_stop_cleanly_fails_the_run_and_shows_its_log(tmp_path, capsys):
    stack = Stack(tmp_path, [CLEAN, UNCLEAN])
    assert run(stack, args(), threading.Event()) == 1
    err = capsys.readouterr().err
    assert '1 did not stop cleanly; its log:' in err and 'a thread would not stop' in err, err
    assert '0 did not stop cleanly' not in err


def test_nodes_that_stop_cleanly_give_0_and_no_log(tmp_path, capsys):
    stack = Stack(tmp_path, [CLEAN, CLEAN])
    assert run(stack, args(), threading.Event()) == 0
    assert 'its log' not in capsys.readouterr().err
    assert os.path.exists(tmp_path / '0.log')


def test_a_simulator_that_hangs_no_apples_has_its_planner_claim_apples_by_the_plan(tmp_path, monkeypatch):
    """With nothing to grasp the gripper closes on air: the planner's grasp check would miss every apple."""
    import shutil

    from picking_bringup import stack as bringup
    from picking_bringup.shipped import config_dir
    started = {}
    monkeypatch.setattr(bringup.Stack, 'start', lambda self, name: started.__setitem__(name, list(self.args[name])))
    bringup.Stack(log_dir=tmp_path)
    assert started['picking-planner'][:2] == ['-p', 'grasp_check:=false']
    bringup.Stack(log_dir=tmp_path, args={'picking-sim': ['-p', 'tree:=synthetic 6 1']})
    assert 'grasp_check:=false' not in started['picking-planner']
    config = tmp_path / 'config'
    shutil.copytree(config_dir(), config)
    sim = config / 'sim.yaml'
    sim.write_text(sim.read_text().replace('tree: ""', 'tree: "orchard 12 3"'))
    bringup.Stack(log_dir=tmp_path, config=config)
    assert 'grasp_check:=false' not in started['picking-planner']
    bringup.Stack(log_dir=tmp_path, without=('picking-sim',))          # a real arm: its gripper is judged
    assert 'grasp_check:=false' not in started['picking-planner']


def test_an_arm_gives_every_node_its_urdf_and_its_settings_after_their_own(tmp_path, monkeypatch):
    import pytest

    from picking_bringup import stack as bringup
    from picking_description import urdf_path
    started = {}
    monkeypatch.setattr(bringup.Stack, 'start', lambda self, name: started.__setitem__(name, self))
    stack = bringup.Stack(log_dir=tmp_path, arm='ur5e')
    for name in bringup.NODES:
        assert f'urdf_path:={urdf_path("ur5e")}' in stack.args[name]
        assert stack.files[name][-1] == 'arms/ur5e.yaml' and (stack.config / stack.files[name][-1]).exists()
    with pytest.raises(ValueError, match="no arm 'nope': config/arms has fr3, ur5e"):
        bringup.Stack(log_dir=tmp_path, arm='nope')


#: Says when it was asked to stop and when it is done, taking a moment in between (as a node's teardown does).
SLOW_STOP = ('import signal, sys, time\n'
             'def bye(*_):\n'
             '    print("asked", time.monotonic(), flush=True)\n'
             '    time.sleep(0.3)\n'
             '    print("done", time.monotonic(), flush=True)\n'
             '    sys.exit(0)\n'
             'signal.signal(signal.SIGINT, bye)\n'
             'print("up", flush=True)\n'
             'while True: time.sleep(0.05)\n')


def test_stop_all_stops_each_process_after_the_one_before_has_exited(tmp_path):
    """Nodes that stop together send each other the discovery callbacks during which the wheels' Fast DDS can hang
    destroying a participant: each is asked only once the one before it is gone."""
    from picking_bringup.stack import stop_all
    stack = Stack(tmp_path, [SLOW_STOP] * 3)
    stack.wait_ready(10.0)
    assert stop_all(stack.processes) == [0, 0, 0]
    times = []
    for p in stack.processes:
        said = dict(line.split() for line in p.output().splitlines() if line.split()[0] in ('asked', 'done'))
        times.append((float(said['asked']), float(said['done'])))
    for (_, done), (asked, _) in zip(times, times[1:]):
        assert asked > done, times


def test_a_node_starts_in_a_process_group_of_its_own_naming_its_launcher(tmp_path):
    """A terminal's Ctrl-C goes to its foreground process group: it reaches the launcher, which stops the nodes in
    order, and not every node at once."""
    import os

    from picking_common.startup import LAUNCHER_PID
    script = 'import os; print(os.getpgid(0), os.environ["' + LAUNCHER_PID + '"], flush=True)'
    p = NodeProcess(Path(sys.executable).name, ['-c', script], tmp_path / 'p.log')
    assert p.reap(time.monotonic() + 10.0) == 0
    group, launcher = p.output().split()
    assert int(group) == p.pid != os.getpgid(0)
    assert int(launcher) == os.getpid()
