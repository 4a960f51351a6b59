"""A body's arms found from its mesh (garment/io/arms.py), raised for dressing, and the
layout's choice to raise them (garment/dress/layout.arms_out_of_the_way)."""

import numpy as np
import pytest
import trimesh

from garment.dress.frame import read_body
from garment.dress.layout import ARM_ANGLES, arms_out_of_the_way, seams_through_body
from garment.io.arms import find_arms, raised
from garment.io.bodies import to_scene_frame
from garment.io.obstacles import ObstacleGeometry
from sim.patches import Patch
from sim.seams.spec import PatchSeam
from tests.support.paths import ASSETS


@pytest.fixture(scope="module")
def body():
    """GarmentCode's mean_all body in A-pose, Z-up metres: hands beside the hips."""
    V, F, frame = read_body(ASSETS / "bodies" / "mean_all.obj")
    return to_scene_frame(V.astype(float), frame.scale, frame.up), F.astype(np.int32)


def test_the_two_arms_of_an_a_pose_body_are_found_and_raised_without_tearing_it(body):
    V, F = body
    arms = find_arms(V, F)
    assert len(arms) == 2
    sides = sorted(float(V[a.vertices, 0].mean()) for a in arms)
    assert sides[0] < -0.4 and sides[1] > 0.4  # one arm each side, hands ~0.6 m out
    for a in arms:
        hand = V[a.vertices, 2].min()
        assert hand < 0.95  # at the hips
    up = raised(V, arms, np.radians(40.0))
    moved = np.linalg.norm(up - V, axis=1) > 1e-12
    on_arm = np.zeros(len(V), bool)
    for a in arms:
        on_arm[a.vertices] = True
        # The hand comes up above the waist (1.05 m) ...
        assert up[a.vertices, 2].min() > 1.15
    # ... and nothing but the arms moves.
    assert not (moved & ~on_arm).any()
    # Blended into the torso: while the hands move 30 cm and more, no edge stretches by
    # a centimetre (a cut arm turned rigidly would open a gap as wide as its turn).
    assert np.linalg.norm(up - V, axis=1).max() > 0.3
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    before = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    after = np.linalg.norm(up[E[:, 0]] - up[E[:, 1]], axis=1)
    assert np.abs(after - before).max() < 0.01


def test_a_body_without_free_arms_has_none():
    trunk = trimesh.creation.capsule(height=1.4, radius=0.15, count=[24, 24])
    trunk.apply_translation([0.0, 0.0, 0.85])
    assert find_arms(np.asarray(trunk.vertices), np.asarray(trunk.faces)) == []


def test_raised_arms_are_lowered_as_the_body_grows_back(body):
    V, F = body
    g = ObstacleGeometry("body", V, F, raise_arms=40.0, grow=(0.3, 0.6))
    hand = [a.vertices for a in find_arms(V, F)]
    heights = [min(g.at(t)[h, 2].min() for h in hand) for t in (0.0, 0.3, 0.45, 0.6, 0.7)]
    assert heights[0] == heights[1] > 1.15  # raised until the growing starts
    assert heights[1] > heights[2] > heights[3]  # lowered while it grows
    np.testing.assert_array_equal(g.at(0.6), V)  # and down at its end
    np.testing.assert_array_equal(g.at(0.7), V)


def test_a_skirt_laid_over_the_hands_is_sewn_with_the_arms_raised(body):
    """Two skirt panels in front of and behind the right hand, joined by a side seam
    whose closing paths pass through the hand: the arms are raised by the least angle
    that takes them off every path. The same panels beside the hips (clear of the hand)
    leave the arms down."""
    V, F = body
    arm = max(find_arms(V, F), key=lambda a: V[a.vertices, 0].mean())
    hand = V[arm.vertices][np.argmin(V[arm.vertices, 2])]

    def panel(name, y, x0):
        return Patch.rectangle(name, (0.3, 0.3), (6, 6), origin=(x0, y, hand[2] - 0.15), axis_u=(1, 0, 0),
                               axis_v=(0, 0, 1))

    def side_seam(a, b):
        n, m = a.shape
        uv = np.c_[np.full(9, n - 2.0), np.linspace(0, m - 2, 9)]
        return PatchSeam("side", a.name, b.name, uv, uv.copy(), [], [])

    front, back = panel("front", hand[1] + 0.15, hand[0] - 0.3), panel("back", hand[1] - 0.15, hand[0] - 0.3)
    seams = [side_seam(front, back)]
    assert seams_through_body([front, back], seams, V, F)
    angle, arms = arms_out_of_the_way([front, back], seams, V, F)
    assert angle == ARM_ANGLES[0]
    up = raised(V, arms, np.radians(angle))
    assert not seams_through_body([front, back], seams, up, F)
    # Moved 40 cm towards the middle, the seam passes beside the hip, clear of the hand.
    for p in (front, back):
        p.world -= [0.4, 0.0, 0.0]
    assert arms_out_of_the_way([front, back], seams, V, F) == (0.0, [])
