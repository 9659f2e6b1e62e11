"""The layout holds itself: what each package of the workspace may import (docs/architecture.md).

The imports are read from the source (every ``import`` and ``from ... import`` statement,
at any depth, relative ones resolved), not by importing the modules.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
#: What the pure core may import beyond the standard library and itself.
CORE_LIBRARIES = ('numpy', 'scipy', 'numba', 'ruckig', 'coal', 'yaml', 'hypothesis')
#: The pure modules of the node packages: tested without ROS like the core.
PURE_IN_NODES = ('picking_controller.core', 'picking_controller.events', 'picking_controller.validation',
                 'picking_controller.splicing', 'picking_controller.monitoring', 'picking_controller.limiting',
                 'picking_controller.sampler', 'picking_controller.goals', 'picking_sim.servo', 'picking_sim.witness')
#: The workspace's packages that run nodes or tools (everything but the core, the description and common).
NODE_PACKAGES = ('picking_planner', 'picking_controller', 'picking_sim', 'picking_bringup')
#: Modules that speak ROS: the middleware and message packages.
ROS = ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'nav_msgs',
       'trajectory_msgs', 'diagnostic_msgs', 'visualization_msgs', 'control_msgs', 'action_msgs',
       'picking_interfaces', 'picking_common')
STDLIB = set(sys.stdlib_module_names) | {'__future__'}


def module_name(path):
    rel = path.relative_to(SRC).with_suffix('')
    parts = rel.parts[1:]                          # drop the package folder (src/<pkg>/<pkg>/...)
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def imports_of(path, name):
    """Every module ``path`` (the module ``name``) imports, as absolute names."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[:len(base) - node.level + 1]
                stem = '.'.join(base + ([node.module] if node.module else []))
            else:
                stem = node.module
            found.append(stem)
            found += [f'{stem}.{alias.name}' for alias in node.names]
    return found


def modules():
    out = {}
    for path in sorted(SRC.glob('*/*/**/*.py')):
        if '/test/' in str(path) or path.parts[-2] == 'test' or 'build' in path.parts:
            continue
        out[module_name(path)] = path
    return out


def under(name, prefixes):
    return any(name == p or name.startswith(p + '.') for p in prefixes)


def violations(mods, rule):
    """``(module, import)`` pairs that break ``rule(module, imported) -> bool`` (True: forbidden)."""
    return [(name, imp) for name, path in mods.items() for imp in imports_of(path, name) if rule(name, imp)]


def core_imports_more_than_its_libraries(module, imported):
    """The core imports the standard library, its numeric libraries and itself: no ROS, no node, no file of the
    workspace's other packages."""
    top = imported.split('.')[0]
    return under(module, ('picking_core',)) and top not in STDLIB and top not in CORE_LIBRARIES + ('picking_core',)


def description_imports_the_workspace(module, imported):
    """The description is looked up by everyone and looks up no one."""
    return under(module, ('picking_description',)) and imported.split('.')[0].startswith('picking')


def pure_module_of_a_node_package_imports_ros(module, imported):
    return under(module, PURE_IN_NODES) and under(imported, ROS)


def controller_or_sim_import_the_planner(module, imported):
    return under(module, ('picking_controller', 'picking_sim')) and under(imported, ('picking_planner', 'picking_bringup'))


def common_knows_a_node(module, imported):
    return under(module, ('picking_common',)) and under(imported, NODE_PACKAGES)


def a_package_imports_another_ones_node_or_tools(module, imported):
    """A node (``<package>.node``, the harvester) and the bring-up tools are imported by no other package."""
    own = module.split('.')[0]
    nodes = ('picking_planner.node', 'picking_planner.harvester', 'picking_controller.node', 'picking_sim.node')
    return (imported.split('.')[0] != own and own != 'picking_bringup' and under(imported, nodes)) or \
        (own != 'picking_bringup' and under(imported, ('picking_bringup',)))


RULES = [core_imports_more_than_its_libraries, description_imports_the_workspace,
         pure_module_of_a_node_package_imports_ros, controller_or_sim_import_the_planner, common_knows_a_node,
         a_package_imports_another_ones_node_or_tools]


@pytest.mark.parametrize('rule', RULES, ids=lambda r: r.__name__)
def test_no_module_breaks_the_rule(rule):
    assert violations(modules(), rule) == []


def test_there_is_no_import_cycle_between_modules():
    mods = modules()
    graph = {name: {imp for imp in imports_of(path, name) if imp in mods and imp != name}
             for name, path in mods.items()}
    # Package __init__ files re-export their modules: an edge into a package's own children is not a cycle.
    done, stack = set(), []

    def visit(n):
        if n in stack:
            cycle = stack[stack.index(n):] + [n]
            if not all(b.startswith(a + '.') or a.startswith(b + '.') for a, b in zip(cycle, cycle[1:])):
                raise AssertionError(f'import cycle: {" -> ".join(cycle)}')
            return
        if n in done:
            return
        stack.append(n)
        for m in sorted(graph[n]):
            visit(m)
        stack.pop()
        done.add(n)

    for n in sorted(graph):
        visit(n)


@pytest.mark.parametrize('rule, module, source', [
    (core_imports_more_than_its_libraries, 'picking_core.trajectory.lspb', 'import rclpy\n'),
    (core_imports_more_than_its_libraries, 'picking_core.pick_cycle', 'from sensor_msgs.msg import JointState\n'),
    (core_imports_more_than_its_libraries, 'picking_core.harvest', 'from picking_description import urdf_path\n'),
    (core_imports_more_than_its_libraries, 'picking_core.platform', 'import matplotlib\n'),
    (description_imports_the_workspace, 'picking_description', 'from picking_core import kinematics\n'),
    (pure_module_of_a_node_package_imports_ros, 'picking_controller.core', 'from picking_common.status import Level\n'),
    (pure_module_of_a_node_package_imports_ros, 'picking_sim.servo', 'import rclpy\n'),
    (controller_or_sim_import_the_planner, 'picking_controller.node', 'from picking_planner.parameters import PARAMS\n'),
    (controller_or_sim_import_the_planner, 'picking_sim.node', 'from picking_bringup import demo\n'),
    (common_knows_a_node, 'picking_common.loop', 'from picking_controller.core import ControllerCore\n'),
    (a_package_imports_another_ones_node_or_tools, 'picking_planner.harvester', 'from picking_bringup.stack import Stack\n'),
    (a_package_imports_another_ones_node_or_tools, 'picking_sim.node', 'from picking_controller.node import ControllerNode\n'),
])
def test_each_rule_catches_a_forbidden_import(tmp_path, rule, module, source):
    """The rules are not vacuous: a module given one forbidden import breaks its rule."""
    mods = modules()
    assert module in mods
    assert violations(mods, rule) == []
    bad = tmp_path / mods[module].name
    bad.write_text(mods[module].read_text() + '\n' + source)
    assert violations({**mods, module: bad}, rule)


def test_a_cycle_is_caught(tmp_path):
    mods = modules()
    a, b = tmp_path / 'a.py', tmp_path / 'b.py'
    a.write_text('from picking_core import zz_b\n')
    b.write_text('from picking_core import zz_a\n')
    graph_mods = {**mods, 'picking_core.zz_a': a, 'picking_core.zz_b': b}
    import test_architecture as me
    original = me.modules
    me.modules = lambda: graph_mods
    try:
        with pytest.raises(AssertionError, match='import cycle'):
            me.test_there_is_no_import_cycle_between_modules()
    finally:
        me.modules = original


def test_the_parameters_page_is_written_from_the_declared_parameters():
    """docs/parameters.md is what tools/param_docs.py writes from the nodes' parameter tables (the
    descriptors the nodes declare): run it after changing a parameter."""
    done = subprocess.run([sys.executable, str(SRC.parent / 'tools' / 'param_docs.py'), '--check'], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
