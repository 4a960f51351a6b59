"""Panels round one leg reaching across the body's mid-plane, bent back into their own half
(garment/dress/halves.py): two flared trouser cuffs laid flat overlap between the legs
(jumpsuit_777_03), and bent they no longer cross each other's seams."""

import numpy as np
import pytest
import trimesh

from garment.dress.halves import RADIUS, WALL, bend, into_own_half
from garment.dress.paths import seams_through_cloth
from sim.patches import Patch
from sim.seams.spec import PatchSeam
from tests.garment.dress.test_layout import independent_pairs, torso


def test_bend_keeps_lengths_along_the_panel_and_ends_in_the_wall():
    # A dense row across a 67 cm panel at y = -0.17, bent at the wall x = -0.015 towards +y.
    x = np.linspace(-0.48, 0.19, 2001)
    row = np.c_[x, np.full_like(x, -0.17), np.zeros_like(x)]
    out = bend(row, side=-1.0, turn=1.0, wall=-0.015)
    length = np.linalg.norm(np.diff(out, axis=0), axis=1).sum()
    assert length == pytest.approx(0.67, rel=1e-6)  # an isometry: the arc is as long as the flat row
    assert out[:, 0].max() == pytest.approx(-0.015, abs=1e-12)  # nothing past the wall
    np.testing.assert_array_equal(out[x < -0.015 - RADIUS], row[x < -0.015 - RADIUS])  # before the bend, unmoved
    # Past the quarter turn it runs straight along +y: from the start of the bend, the
    # rest of the row past a quarter circle.
    past = 0.19 - (-0.015 - RADIUS) - 0.5 * np.pi * RADIUS
    assert out[-1, 1] == pytest.approx(-0.17 + RADIUS + past, abs=1e-12)


def legs(radius=0.06, apart=0.32, height=0.8):
    """Two standing cylinders, x = -+apart / 2, from z = 0.1 m up: legs, no trunk."""
    parts = []
    for x in (-apart / 2, apart / 2):
        leg = trimesh.creation.cylinder(radius=radius, height=height, sections=32).subdivide_to_size(0.05)
        leg.apply_translation([x, 0.0, 0.1 + height / 2])
        parts.append(leg)
    return trimesh.util.concatenate(parts)


def cuffs():
    """jumpsuit_777_03's trouser cuffs, laid as GarmentCode lays them: two 67 cm loops (a
    front and a back panel each, sewn at both sides) below the ankles, the left one's
    panels just outside the right one's, overlapping between the legs by 38 cm."""
    def panel(name, x0, y):
        return Patch.rectangle(name, (0.67, 0.085), (19, 5), origin=(x0, y, 0.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))

    patches = [panel("r_front", -0.482, -0.171), panel("r_back", -0.482, 0.129),
               panel("l_front", -0.192, -0.177), panel("l_back", -0.192, 0.135)]

    def side(name_a, name_b, u, k=5):  # k samples up both panels' side at parameter u
        uv = np.c_[np.full(k, u), np.linspace(0, 3, k)]
        return PatchSeam(f"{name_a}-{name_b}@{u:g}", name_a, name_b, uv, uv.copy(), [], [])

    seams = [side("r_front", "r_back", 0.0), side("r_front", "r_back", 17.0),
             side("l_front", "l_back", 0.0), side("l_front", "l_back", 17.0)]
    return patches, seams


def test_two_cuffs_overlapping_between_the_legs_are_bent_into_their_own_halves():
    body = legs()
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    patches, seams = cuffs()
    caught = {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    # The left cuff's inner seam closes through both panels of the right cuff.
    assert caught == {("l_front-l_back@0", "r_front"), ("l_front-l_back@0", "r_back")}
    before = {p.name: p.world.copy() for p in patches}
    bent = into_own_half(patches, seams, V, F)
    assert set(bent) == {"r_front", "r_back", "l_front", "l_back"}
    assert not {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert independent_pairs(patches, body) == 0
    # Each cuff in its own half, front walls nearer the middle than back walls.
    for p in patches:
        side = -1.0 if p.name.startswith("r") else 1.0
        wall = WALL[1] if "front" in p.name else WALL[-1]
        assert (side * p.world[..., 0]).min() == pytest.approx(wall, abs=1e-9)
    # Heights unchanged; the control net bent, not stretched: neighbours along the width
    # keep their spacing to within the chord of the quarter turn, up the panel exactly.
    for p in patches:
        w, w0 = p.world, before[p.name]
        np.testing.assert_array_equal(w[..., 2], w0[..., 2])
        across = np.linalg.norm(np.diff(w, axis=0), axis=-1) / np.linalg.norm(np.diff(w0, axis=0), axis=-1)
        assert across.max() <= 1.0 + 1e-9 and across.min() > 0.98
        np.testing.assert_allclose(np.linalg.norm(np.diff(w, axis=1), axis=-1),
                                   np.linalg.norm(np.diff(w0, axis=1), axis=-1), rtol=1e-9)


def test_panels_reaching_across_the_trunk_are_not_bent():
    """The same cuffs at the height of a trunk (a cylinder through the middle): there is no
    half to bend into, and nothing moves."""
    body = torso()
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    patches, seams = cuffs()
    for p in patches:
        p.world[..., 2] += 1.0
    before = [p.world.copy() for p in patches]
    assert into_own_half(patches, seams, V, F) == {}
    for p, w in zip(patches, before):
        np.testing.assert_array_equal(p.world, w)
