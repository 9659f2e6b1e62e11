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
         'picking-planner', 'picking-harvester')
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
                                  ('picking-sim', 'extra'), ('picking-stack', '--domain', 999)])
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
        assert done.returncode == 0, (line, done.stderr)


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
            assert done.returncode == 0, (line, done.stdout, done.stderr)
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
        assert done.returncode == 0, (line, done.stdout, done.stderr)
        assert 'is up' in done.stdout and 'exit code 0' in done.stdout, done.stdout
