"""The interface packages built here are the upstream definitions: the same type hash (Jazzy's RIHS01),
so every ROS tool and node built against upstream reads them."""

import json
import sys
from pathlib import Path

import pytest

UPSTREAM = {
    # ros-perception/vision_msgs 4.1 (Jazzy), as its generated type descriptions record it.
    'vision_msgs/msg/Detection3DArray': 'RIHS01_793f5eab9595ac1c0da07873cc859db42eae51f0ee76056db8562515d830e018',
    # ros-controls/control_msgs (Jazzy), as its generated type description sources record it.
    'control_msgs/msg/JointTrajectoryControllerState':
        'RIHS01_6cb9ac0858fc11b54bd6c0a46f032ea243c16856182276d8eb0875f6ce6a8335',
}


@pytest.mark.parametrize('name, expected', sorted(UPSTREAM.items()))
def test_a_built_interface_has_the_upstream_type_hash(name, expected):
    package, kind, message = name.split('/')
    found = [p for p in map(Path, sys.path) if (p / package).is_dir()]
    described = [Path(sys.prefix, 'share', package, kind, f'{message}.json')] + \
        [p.parent.parent.parent / 'share' / package / kind / f'{message}.json' for p in found]
    path = next((d for d in described if d.exists()), None)
    assert path is not None, f'no type description of {name} installed'
    hashes = {h['type_name']: h['hash_string'] for h in json.loads(path.read_text())['type_hashes']}
    assert hashes[name] == expected
