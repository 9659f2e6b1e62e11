"""The viewer files shipped in ``picking_description/viewers/``: a Foxglove layout, made here from the Foxglove
SDK's layout classes, and an RViz configuration (hand-written; its displays read :data:`VIEWED` too).

``python -m picking_bringup.viewers src/picking_description/viewers/picking_arm.foxglove.json`` writes the
Foxglove layout again after a change here (``--ns /arm2``: the layout for that arm); a test checks the shipped file
is what this makes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

#: What the viewers draw: topic (relative: in the arm's namespace) -> its durability (a viewer must ask for
#: transient local to get a latched message).
VIEWED = {
    'robot_description': 'Transient Local',   # the URDF, from picking-state-publisher
    'planned_path': 'Volatile',               # the tool path of each plan (nav_msgs/Path)
    'world_markers': 'Transient Local',       # the scene the simulator checks the arm against
    'scene': 'Transient Local',               # a perception node's branches and wires
    'harvest_markers': 'Volatile',            # the demo's tree: its order and each apple's outcome
    '/tree_markers': 'Volatile',              # the platform demo's tree, in the platform frame
    'canopy_points': 'Volatile',              # the canopy cloud (sensor_msgs/PointCloud2)
}
#: The arm's joints plotted (the first six of joint_states).
PLOTTED_JOINTS = 6


def absolute(topic, prefix):
    return topic if topic.startswith('/') else prefix + topic


def foxglove_layout(ns='/'):
    """The layout as JSON text: a 3D panel (the arm from robot_description and /tf, its plans, the world, the
    tree and the canopy), a plot of the joint positions and the planner's newest status, for the arm in ``ns``."""
    import foxglove.layouts as fl
    prefix = '/' + ns.strip('/') + '/' if ns.strip('/') else '/'
    markers = fl.BaseRendererRosMarkerTopicSettings(visible=True)
    kinds = {'robot_description': fl.BaseRendererUrdfTopicSettings(visible=True),
             'planned_path': fl.BaseRendererPosesTopicSettings(visible=True),
             'canopy_points': fl.BaseRendererPointCloudTopicSettings(visible=True)}
    three_d = fl.ThreeDeePanel(title='The arm, its plans and the world', config=fl.ThreeDeeConfig(
        follow_tf=f'{prefix.lstrip("/")}base_link',
        topics={absolute(t, prefix): kinds.get(t, markers) for t in VIEWED}))
    joints = fl.PlotPanel(title='Joint positions (rad)', config=fl.PlotConfig(show_legend=True, paths=[
        fl.PlotSeries(value=f'{prefix}joint_states.position[{i}]', timestamp_method='headerStamp')
        for i in range(PLOTTED_JOINTS)]))
    status = fl.RawMessagesPanel(title='Planner status', config=fl.RawMessagesConfig(
        topic_path=f'{prefix}planner_status'))
    layout = fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=2, content=three_d),
        fl.SplitItem(proportion=1, content=fl.SplitContainer(direction='column', items=[
            fl.SplitItem(proportion=1, content=joints), fl.SplitItem(proportion=1, content=status)]))]))
    return json.dumps(json.loads(layout.to_json()), indent=2, sort_keys=True) + '\n'


def main(argv=None):
    parser = argparse.ArgumentParser(prog='python -m picking_bringup.viewers', description='Write the Foxglove layout.')
    parser.add_argument('out', type=Path, nargs='?', help='the file to write (default: print it)')
    parser.add_argument('--ns', default='/', help="the arm's namespace (default: %(default)s)")
    args = parser.parse_args(argv)
    text = foxglove_layout(args.ns)
    if args.out is None:
        print(text, end='')
    else:
        args.out.write_text(text)
        print(f'wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
