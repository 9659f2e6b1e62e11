"""`. env.sh` gives the ROS 2 command-line tools this workspace, as the README says: `ros2 pkg list` (the ament
index on AMENT_PREFIX_PATH), `ros2 run <pkg> <exe>` (``lib/<pkg>/<exe>`` under the package's prefix) and
`ros2 interface show` (the interface files in ``share/``), and DDS on loopback in a domain of its own."""

import json
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('picking_core', 'picking_description', 'picking_common', 'picking_planner', 'picking_controller',
            'picking_sim', 'picking_bringup', 'control_msgs', 'tf2_msgs', 'picking_interfaces')
RUNNABLE = (('picking_planner', 'planner'), ('picking_planner', 'harvester'), ('picking_controller', 'controller'),
            ('picking_sim', 'sim'), ('picking_sim', 'state_publisher'))
INTERFACES = (('control_msgs', 'action/FollowJointTrajectory.action'), ('tf2_msgs', 'msg/TFMessage.msg'),
              ('picking_interfaces', 'action/Pick.action'))

LOOK = '''
import json, os
from ament_index_python.packages import get_package_prefix, get_package_share_directory, get_packages_with_prefixes
print(json.dumps({
    'packages': sorted(get_packages_with_prefixes()),
    'runnable': {f'{p}/{e}': os.access(os.path.join(get_package_prefix(p), 'lib', p, e), os.X_OK) for p, e in %r},
    'interfaces': {f'{p}/{f}': os.path.exists(os.path.join(get_package_share_directory(p), f)) for p, f in %r},
    'range': os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'), 'domain': os.environ.get('ROS_DOMAIN_ID')}))
''' % (RUNNABLE, INTERFACES)


def test_env_sh_gives_the_ros2_tools_this_workspace():
    assert (ROOT / 'install' / 'setup.bash').exists(), 'run colcon build first (make test does)'
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH', 'ROS_DOMAIN_ID')}
    done = subprocess.run(['bash', '-c', f'. {ROOT / "env.sh"} && python -c "$LOOK"'], capture_output=True,
                          text=True, timeout=60, env={**env, 'LOOK': LOOK}, cwd='/')
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(PACKAGES) <= set(seen['packages']), set(PACKAGES) - set(seen['packages'])
    assert all(seen['runnable'].values()), seen['runnable']
    assert all(seen['interfaces'].values()), seen['interfaces']
    assert seen['range'] == 'LOCALHOST' and seen['domain'] == '42'
