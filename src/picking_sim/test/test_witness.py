"""The simulator's witness: each contact of the measured arm with the scene is one episode, reported
when it starts and when it ends."""

import numpy as np

from picking_core.collision import CollisionChecker, Scene
from picking_core.kinematics import ArmModel
from picking_core.kinematics.capsules import ArmCapsules
from picking_description import default_urdf
from picking_sim.witness import Witness

HOME = np.array([0.0, 0.2, 1.6, 0.0, -0.23, 0.0])


def test_a_pass_through_a_branch_is_one_episode_from_first_touch_to_letting_go():
    arm = ArmModel.from_urdf(default_urdf())
    tool = arm.fk(HOME)[:3, 3]
    # A vertical branch beside the tool; the waist turns the tool through it and back out.
    scene = Scene.from_dict({'branches': [{'name': 'twig', 'from': (tool + [0, 0.2, -0.3]).tolist(),
                                           'to': (tool + [0, 0.2, 0.3]).tolist(), 'radius': 0.01}]})
    witness = Witness(CollisionChecker(ArmCapsules.from_arm(arm), scene, clearance=0.0, self_check=False))
    turn = np.concatenate([np.linspace(0.0, 0.6, 61), np.linspace(0.6, 0.0, 61)])
    q = np.repeat(HOME[None], len(turn), axis=0)
    q[:, 0] = turn
    t = np.arange(len(turn)) * 0.01
    events = witness.observe(t[:40], q[:40]) + witness.observe(t[40:], q[40:])
    assert witness.count >= 1 and not witness.open
    first = events[0]
    assert first.obstacle == 'twig' and first.link in ('tool0', 'wrist_3_link', 'wrist_1_link', 'forearm_link')
    ended = [e for e in events if e.end is not None]
    assert ended and all(e.depth > 0.0 and e.end > e.start for e in ended)
    assert 'contact ended' in ended[0].words() and 'cm deep at worst' in ended[0].words()
    # Far from the branch: nothing.
    assert Witness(witness.checker).observe(t[:5], np.repeat(HOME[None], 5, axis=0)) == []
