"""The shipped viewer files: the Foxglove layout is what picking_bringup.viewers makes, and the RViz
configuration draws the same topics with the durability their publishers offer."""

import json

import yaml

from picking_bringup.viewers import VIEWED, foxglove_layout
from picking_description import viewer_path


def test_the_shipped_foxglove_layout_is_the_one_the_code_makes():
    assert viewer_path('picking_arm.foxglove.json').read_text() == foxglove_layout(), \
        'run: python -m picking_bringup.viewers src/picking_description/viewers/picking_arm.foxglove.json'


def test_the_layout_for_an_arm_in_a_namespace_names_its_topics_and_frames_under_it():
    layout = json.loads(foxglove_layout('/arm2'))
    three_d = layout['content']['items'][0]['content']['config']
    assert three_d['followTf'] == 'arm2/base_link'
    assert '/arm2/robot_description' in three_d['topics'] and '/tree_markers' in three_d['topics']
    assert '/arm2/joint_states.position[0]' in json.dumps(layout)


def test_the_rviz_configuration_draws_every_viewed_topic_as_its_publisher_offers_it():
    rviz = yaml.safe_load(viewer_path('picking_arm.rviz').read_text())
    displays = rviz['Visualization Manager']['Displays']
    topics = {}
    for d in displays:
        t = d.get('Topic') or d.get('Description Topic')
        if t:
            topics[t['Value']] = t['Durability Policy']
    assert topics == VIEWED
    assert rviz['Visualization Manager']['Global Options']['Fixed Frame'] == 'base_link'
