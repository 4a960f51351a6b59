"""The starting layout made valid by garment/dress/layout.py: overlapping panels and a
panel inside the body are moved apart (checked by the independent test), and what cannot
be fixed is named."""

import numpy as np
import pytest
import trimesh

from garment.dress.layout import CLEARANCE, PlacementError, _Body, crossings, separate
from garment.verify import intersecting_triangles
from tests.support.paths import SHARED_ASSETS
from sim.embedding import default_resolution, grid_faces, interpolation_matrix, sample_grid
from sim.patches import Patch


def mesh(p: Patch, density: float = 3.0):
    n, m = p.shape
    res = default_resolution(n, m, density)
    W = interpolation_matrix(*sample_grid(n, m, res), n, m, 0, n * m)
    return W @ p.world.reshape(-1, 3), grid_faces(*res)


def independent_pairs(patches, body=None) -> int:
    meshes = [mesh(p) for p in patches]
    count = sum(len(intersecting_triangles(*meshes[i], *meshes[j]))
                for i in range(len(meshes)) for j in range(i + 1, len(meshes)))
    if body is not None:
        count += sum(len(intersecting_triangles(*m, body.vertices, body.faces)) for m in meshes)
    return count


def torso(radius=0.15, height=1.7):
    """A standing cylinder as the body, axis along Z through the origin."""
    body = trimesh.creation.cylinder(radius=radius, height=height, sections=48).subdivide_to_size(0.05)
    body.apply_translation([0.0, 0.0, height / 2])
    return body


def test_two_overlapping_panels_are_moved_apart():
    body = torso()
    # Two front panels crossing each other at 20 degrees in front of the body.
    a = Patch.rectangle("left", (0.3, 0.4), (8, 10), origin=(-0.2, 0.2, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    tilt = np.deg2rad(20)
    b = Patch.rectangle("right", (0.3, 0.4), (8, 10), origin=(-0.05, 0.2 - 0.15 * np.sin(tilt), 1.0),
                        axis_u=(np.cos(tilt), np.sin(tilt), 0), axis_v=(0, 0, 1))
    patches = [a, b]
    assert independent_pairs(patches, body) > 0
    layout = separate(patches, np.asarray(body.vertices), np.asarray(body.faces, np.int32))
    assert independent_pairs(patches, body) == 0
    assert not crossings(patches, np.asarray(body.vertices), np.asarray(body.faces, np.int32))
    # Only one layer moved, outwards (away from the body), by a few centimetres at most.
    assert len(layout.moved) == 1
    assert 0 < max(layout.moved.values()) < 0.1


def test_a_panel_inside_the_body_is_pushed_out():
    body = torso()
    # A back panel whose middle sits 3 cm inside the body's surface.
    p = Patch.rectangle("back", (0.25, 0.3), (8, 9), origin=(-0.125, -0.12, 1.0), axis_u=(1, 0, 0),
                        axis_v=(0, 0, 1))
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    assert independent_pairs([p], body) > 0
    layout = separate([p], V, F)
    assert independent_pairs([p], body) == 0
    # It moved backwards (-y, away from the body) and stays within a step of touching.
    assert p.world[..., 1].max() < -0.12
    inside = 0.15 - np.abs(p.world[..., 1]).min()
    assert layout.moved["back"] == pytest.approx(abs(p.world[..., 1].max() + 0.12), abs=1e-9)
    assert inside < 0.15 and layout.moved["back"] > CLEARANCE


def test_impossible_layout_names_the_panels_and_where():
    body = torso()
    # Two panels crossing at right angles through each other's middle: moving either along
    # its normal never clears the other.
    a = Patch.rectangle("yoke", (0.6, 0.6), (8, 8), origin=(-0.3, 0.3, 0.9), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    b = Patch.rectangle("fin", (0.6, 0.6), (8, 8), origin=(0.0, 0.0, 0.9), axis_u=(0, 1, 0), axis_v=(0, 0, 1))
    b.world[..., 1] += 0.0  # fin spans y 0..0.6, crossing the yoke at y = 0.3
    with pytest.raises(PlacementError) as e:
        separate([a, b], np.asarray(body.vertices), np.asarray(body.faces, np.int32))
    text = str(e.value)
    assert "panel yoke" in text and "panel fin" in text and " cm" in text and "placement" in text


def test_panels_laid_corner_to_corner_are_moved_apart_but_pieces_of_one_panel_are_not():
    """GarmentCode lays a godet skirt's inserts corner to corner: they cross nothing, yet
    contact would start at zero distance and hold them still. Pieces of one split panel
    meet along their cut by design and stay where they are."""
    from garment.dress.layout import TOUCH, touching

    body = torso()
    a = Patch.rectangle("ins_0", (0.2, 0.3), (6, 8), origin=(-0.2, 0.3, 0.8), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    b = Patch.rectangle("ins_1", (0.2, 0.3), (6, 8), origin=(0.0005, 0.3, 1.1), axis_u=(0.8, 0.6, 0),
                        axis_v=(0, 0, 1))  # a corner 0.5 mm from ins_0's
    cut = [Patch.rectangle(f"back.{k}", (0.2, 0.3), (6, 8), origin=(-0.2 + 0.2 * k, -0.3, 0.8),
                           axis_u=(1, 0, 0), axis_v=(0, 0, 1)) for k in (0, 1)]
    patches = [a, b, *cut]
    panels = ["ins_0", "ins_1", "back", "back"]  # the pieces' panel (PatchSet.panel_of)
    assert (0, 1) not in crossings(patches, np.asarray(body.vertices), np.asarray(body.faces, np.int32))
    assert set(touching(patches, panels)) == {(0, 1)}  # the corners meet
    assert set(touching(patches, [p.name for p in patches])) == {(0, 1), (2, 3)}  # as if two panels
    layout = separate(patches, np.asarray(body.vertices), np.asarray(body.faces, np.int32), panels=panels)
    assert len({"ins_0", "ins_1"} & set(layout.moved)) == 1
    x = [mesh(p)[0] for p in patches]
    gap = np.linalg.norm(x[0][:, None] - x[1][None], axis=-1).min()
    assert gap > TOUCH


def test_the_panels_of_a_seam_through_the_shoulder_are_lifted_over_it():
    """Straps laid in front of and behind a shoulder (a box 1.40-1.45 m high): their
    seam would close through it. Both are lifted by the least 2 cm steps that take every
    closing path over the shoulder; a seam beside the body and one through the trunk
    (no lift within 10 cm clears it) stay where they are."""
    from garment.dress.layout import LIFT_STEP, lift_over_body, seams_through_body
    from sim.seams.spec import PatchSeam

    shoulder = trimesh.creation.box(extents=(0.3, 0.2, 0.5))
    shoulder.apply_translation([0.0, 0.0, 1.2])  # top at 1.45 m
    V, F = np.asarray(shoulder.vertices), np.asarray(shoulder.faces, np.int32)

    def strap(name, y, top):
        return Patch.rectangle(name, (0.06, 0.2), (5, 6), origin=(-0.03, y, top - 0.2), axis_u=(1, 0, 0),
                               axis_v=(0, 0, 1))

    def top_seam(name, a, b):
        n, m = a.shape
        uv = np.c_[np.linspace(0, n - 2, 7), np.full(7, m - 2.0)]
        return PatchSeam(name, a.name, b.name, uv, uv.copy(), [], [])

    front, back = strap("front", -0.15, 1.42), strap("back", 0.15, 1.42)
    side_a, side_b = strap("side_a", -0.15, 1.42), strap("side_b", -0.15, 1.42)
    side_a.world += [0.5, 0.0, 0.0]
    side_b.world += [0.5, 0.05, 0.0]  # beside the body, 5 cm apart
    trunk_a, trunk_b = strap("trunk_a", -0.15, 1.1), strap("trunk_b", 0.15, 1.1)  # 35 cm below the top
    seams = [top_seam("shoulder", front, back), top_seam("side", side_a, side_b), top_seam("trunk", trunk_a, trunk_b)]
    patches = [front, back, side_a, side_b, trunk_a, trunk_b]
    before = {p.name: p.world.copy() for p in patches}
    assert set(seams_through_body(patches, seams, V, F)) == {"shoulder", "trunk"}
    lifted = lift_over_body(patches, seams, V, F)
    # The tops at 1.42 m: 2 cm leaves the paths at 1.44 m, inside; 4 cm takes them over.
    assert lifted == pytest.approx({"front": 2 * LIFT_STEP, "back": 2 * LIFT_STEP})
    np.testing.assert_allclose(front.world - before["front"], np.broadcast_to([0, 0, 0.04], front.world.shape))
    assert all(np.array_equal(p.world, before[p.name]) for p in patches[2:])
    assert set(seams_through_body(patches, seams, V, F)) == {"trunk"}
    # A strap cut from a torso panel takes the torso along (sliding up its own plane,
    # it would overlap it).
    for p in patches:
        p.world = before[p.name].copy()
    torso = strap("front_torso", -0.15, 1.22)
    lifted = lift_over_body(patches + [torso], seams, V, F, panels=[
        "front", "back", "side_a", "side_b", "trunk_a", "trunk_b", "front"])
    assert lifted == pytest.approx({"front": 0.04, "back": 0.04, "front_torso": 0.04})


@pytest.mark.skipif(not (SHARED_ASSETS / "patterns_garmentcode" / "mean_all.obj").exists(), reason="shared assets missing")
def test_a_point_in_front_of_the_shrunk_knee_is_outside():
    # dress_06's front skirt piece has its middle 17 cm in front of the knee. On the body
    # as shrunk at the start of sewing (legs a few centimetres thick) all 8 nearest
    # triangles faced away from it, so it was judged inside, pushed "out" by 15 cm into
    # the body and the layout refused.
    from garment.dress.job import DressOptions, _body
    from garment.io.obstacles import ObstacleGeometry

    _, V, F = _body(SHARED_ASSETS / "patterns_garmentcode" / "mean_all.obj")
    o = DressOptions()
    shrunk = ObstacleGeometry("body", V, F, inset=o.inset, grow=(0.5 * o.sew_time, o.sew_time)).at(0.0)
    body = _Body(shrunk, F)
    points = np.array([[0.262, -0.171, 0.461], [0.0, 0.0, 1.0], [0.0, -0.3, 1.0]])  # the piece, the torso, the front
    assert body.inside(points).tolist() == [False, True, False]


def test_inside_holds_far_from_the_surface_and_on_an_open_mesh():
    # The body as a tube without caps (a body mesh with holes), its faces wound inwards:
    # the winding number still tells the axis (inside) from points 2 cm and 30 cm out.
    tube = trimesh.creation.cylinder(radius=0.1, height=1.0, sections=32)
    keep = np.abs(tube.face_normals[:, 2]) < 0.5
    V, F = np.asarray(tube.vertices), np.asarray(tube.faces[keep][:, ::-1], np.int32)
    body = _Body(V, F)
    points = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.3], [0.12, 0.0, 0.0], [0.0, -0.4, 0.1], [0.0, 0.0, 0.8]])
    assert body.inside(points).tolist() == [True, True, False, False, False]
    assert body.winding(points[:1])[0] == pytest.approx(1.0, abs=0.1)
