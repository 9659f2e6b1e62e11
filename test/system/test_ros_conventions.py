"""The three nodes as the standard ROS tools see them: parameters through the parameter services (`ros2 param
list / describe / get / set / dump` use these), the graph (`ros2 node info`), /diagnostics, goal ids, the
simulator's start at home, and the controller's first log lines in order."""

import re
import time

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosstack import FINAL, RELIABLE, Client, ensure_rclpy, make_pose

from picking_bringup.shipped import config_dir
from picking_common.status import status_values
from picking_controller.parameters import PARAMS as CONTROLLER
from picking_core.pick_cycle import PickSettings
from picking_planner.parameters import PARAMS as PLANNER
from picking_sim.parameters import PARAMS as SIM
from picking_sim.parameters import STATE_PUBLISHER

NODES = {'picking_sim': SIM, 'picking_controller': CONTROLLER, 'picking_planner': PLANNER,
         'picking_state_publisher': STATE_PUBLISHER}
NS = '/conventions'


@pytest.fixture(scope='module')
def arm(tmp_path_factory):
    """The stack as picking-stack starts it (every shipped file, no initial_positions given), and a
    planner given a key it does not have."""
    from picking_bringup.stack import Stack as Launcher
    ensure_rclpy()
    stack = Launcher(NS, tmp_path_factory.mktemp('logs'), args={'picking-planner': ['-p', 'grasp_tme:=0.3']})
    client = Client(NS)
    diagnostics = []
    client.create_subscription(DiagnosticArray, '/diagnostics', diagnostics.append, RELIABLE)
    try:
        stack.wait_ready()
        client.wait_ready()
        yield stack, client, diagnostics
    finally:
        codes = stack.stop()
        client.close()
    assert set(codes.values()) == {0}, codes


def call(client, future, what, timeout=10.0):
    return client.wait_for(lambda: future.done() and future.result(), timeout, what)


def params(client, node):
    c = AsyncParameterClient(client, f'{NS}/{node}')
    assert c.wait_for_services(timeout_sec=10.0), f'{node} offers no parameter services'
    return c


@pytest.mark.parametrize('node', NODES)
def test_every_parameter_is_declared_described_and_dumped_with_a_value(arm, node):
    _, client, _ = arm
    c = params(client, node)
    names = call(client, c.list_parameters(), 'list').result.names
    table = {p.name: p for p in NODES[node]}
    assert set(table) <= set(names), set(table) - set(names)
    # `ros2 param dump` asks for every name: every one has a value (none "not set").
    values = call(client, c.get_parameters(names), 'get').values
    assert len(values) == len(names) and all(v.type != ParameterType.PARAMETER_NOT_SET for v in values)
    for d in call(client, c.describe_parameters(list(table)), 'describe').descriptors:
        p = table[d.name]
        assert d.description and d.read_only == p.read_only, d
        if p.range is not None:
            got = d.integer_range or d.floating_point_range
            assert got and (got[0].from_value, got[0].to_value) == pytest.approx(p.range), d


@pytest.mark.parametrize('node, name, value, refused', [
    ('picking_controller', 'update_rate', -1.0, 'read-only'),
    ('picking_sim', 'publish_rate', 50.0, 'read-only'),
    ('picking_sim', 'noise_std', -1.0, 'range'),
    ('picking_planner', 'urdf_path', 'x.urdf', 'read-only'),
    ('picking_planner', 'speed_scale', 3.0, 'range'),
    ('picking_planner', 'method', 'spline', 'method'),
])
def test_a_parameter_that_cannot_take_a_value_says_so_and_keeps_its_own(arm, node, name, value, refused):
    _, client, _ = arm
    c = params(client, node)
    before = call(client, c.get_parameters([name]), 'get').values[0]
    result = call(client, c.set_parameters([Parameter(name, value=value)]), 'set').results[0]
    assert not result.successful and re.search(refused, result.reason, re.I), result.reason
    assert call(client, c.get_parameters([name]), 'get').values[0] == before


def test_a_settable_parameter_takes_effect(arm):
    _, client, _ = arm
    sim = params(client, 'picking_sim')
    assert call(client, sim.set_parameters([Parameter('noise_std', value=0.002)]), 'set').results[0].successful
    try:
        client.wait_for(lambda: len(client.states) > 50, 10.0, 'joint_states')
        time.sleep(0.3)
        with client.lock:
            q = np.array([m.position[0] for _, m in client.states[-20:]])
        assert q.std() > 2e-4                         # the noise is there
    finally:
        call(client, sim.set_parameters([Parameter('noise_std', value=0.0)]), 'set')
    ctrl = params(client, 'picking_controller')
    assert call(client, ctrl.set_parameters([Parameter('goal_tolerance', value=0.01)]), 'set').results[0].successful
    call(client, ctrl.set_parameters([Parameter('goal_tolerance', value=0.005)]), 'set')


def test_the_shipped_files_hold_declared_parameters_only_and_the_gripper_is_one(arm):
    stack, client, _ = arm
    for f, node in (('planner.yaml', 'picking_planner'), ('pick_cycle.yaml', 'picking_planner'),
                    ('paper_methods.yaml', 'picking_planner'), ('controller.yaml', 'picking_controller'),
                    ('sim.yaml', 'picking_sim')):
        data = yaml.safe_load((config_dir() / f).read_text())
        keys = set(data[f'/**/{node}']['ros__parameters'])
        flat = {k if not isinstance(v, dict) else None for k, v in data[f'/**/{node}']['ros__parameters'].items()}
        nested = {f'{k}.{kk}' for k, v in data[f'/**/{node}']['ros__parameters'].items() if isinstance(v, dict)
                  for kk in v}
        declared = {p.name for p in NODES[node]}
        assert (flat - {None}) | nested <= declared, ((flat - {None}) | nested) - declared
        assert keys
    got = call(client, params(client, 'picking_planner').get_parameters(['gripper_open', 'gripper_closed']), 'get')
    assert [v.double_value for v in got.values] == [0.09, 0.055]
    # A key the planner does not have is reported at start.
    assert 'unknown parameters given for this node, ignored: grasp_tme' in stack.planner.output()
    # ... and only that key: the other nodes, started from the shipped files, know every key given to them.
    for node in (stack.sim, stack.controller):
        assert 'unknown parameters' not in node.output(), node.output()


def test_diagnostics_name_each_nodes_health_and_the_arm(arm):
    _, client, diagnostics = arm
    client.wait_for(lambda: len({s.name for m in diagnostics for s in m.status}) >= 4, 10.0, '/diagnostics')
    statuses = {s.name: s for m in list(diagnostics) for s in m.status}
    for name in ('conventions/picking_controller: control loop', 'conventions/picking_controller: trajectory',
                 'conventions/picking_sim: servo', 'conventions/picking_planner: planner'):
        assert name in statuses, sorted(statuses)
        assert statuses[name].hardware_id == 'conventions/picking_arm'
    assert 'Hz' in statuses['conventions/picking_controller: control loop'].message


def test_the_graph_shows_who_reads_what(arm):
    _, client, _ = arm
    subs = {node: {t for t, _ in client.get_subscriber_names_and_types_by_node(node, NS)} for node in NODES}
    assert f'{NS}/joint_commands' in subs['picking_sim']
    assert f'{NS}/joint_states' in subs['picking_controller']
    assert {f'{NS}/joint_states', f'{NS}/joint_commands'} <= subs['picking_planner']
    # No helper nodes beside the stack's four (and this test's client).
    names = [n for n, ns in client.get_node_names_and_namespaces() if ns == NS]
    assert sorted(n for n in names if not n.startswith('test_client')) == sorted(NODES), names


def test_the_simulator_starts_at_home_and_the_controller_says_what_it_waits_for_first(arm):
    stack, client, _ = arm
    first = re.search(r'from (\[[^\]]*\])', stack.sim.output()).group(1)
    home = list(PickSettings().home_positions) + [PickSettings().gripper_open]
    assert yaml.safe_load(first) == pytest.approx(home, abs=1e-4)
    log = stack.controller.output()
    assert log.index('waiting for joint_states') < log.index('feedback received')


def test_goals_stamped_zero_get_ids_of_their_own(arm):
    _, client, _ = arm
    mark = client.mark()
    for xyz in ([0.6, 0.1, 0.4], [0.6, 3.0, 0.4]):            # the second out of reach: refused at once
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.pose = make_pose(xyz)
        client.pub_pose.publish(msg)
        time.sleep(0.5)
    client.wait_for(lambda: len({status_values(m).get('goal') for _, m in client.planner_status[mark['planner']:]})
                    >= 2, 20.0, 'two goals answered')
    ids = {status_values(m).get('goal') for _, m in client.planner_status[mark['planner']:]}
    assert '0.000000000' not in ids and len(ids) >= 2, ids
    # Each ends with a result under its own id (the reachable one reached, the other refused).
    client.wait_for(lambda: {status_values(m).get('goal') for _, m in client.planner_status[mark['planner']:]
                             if status_values(m).get('state') in FINAL} >= ids, 40.0, 'both goals to end')


def test_a_second_node_of_the_same_name_is_reported(arm, tmp_path):
    """Last in this module: a second planner in the arm's namespace says that two run (each would plan every goal)."""
    from picking_bringup.stack import NodeProcess
    second = NodeProcess('picking-planner', ['--ros-args', '-r', f'__ns:={NS}', '--params-file',
                                             str(config_dir() / 'planner.yaml')], tmp_path / 'second.log')
    try:
        _, client, _ = arm
        client.wait_for(lambda: 'nodes named /conventions/picking_planner run' in second.output(), 20.0,
                        'the second planner to say so')
    finally:
        assert second.stop() == 0
