"""The starting layout made valid by garment/dress/layout.py: overlapping panels and a
panel inside the body are moved apart (checked by the independent test), and what cannot
be fixed is named."""

import numpy as np
import pytest
import trimesh

from garment.dress.layout import CLEARANCE, PlacementError, _Body, crossings, outward_normals, separate
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


def test_a_sleeve_caught_in_the_side_seam_moves_out_with_its_cuff():
    """A sleeve laid across the torso's side seam (between the front and back panels)
    would be sewn into it. It moves out sideways by the least 2 cm steps that free every
    path of the seam, and its cuff, sewn to it, comes along; the torso stays."""
    from garment.dress.layout import OUT_STEP, out_of_seam_paths, seams_through_cloth
    from sim.seams.spec import PatchSeam

    body = torso()
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    front = Patch.rectangle("front", (0.5, 0.4), (8, 7), origin=(-0.25, -0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    back = Patch.rectangle("back", (0.5, 0.4), (8, 7), origin=(-0.25, 0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    # The sleeve in the plane y = 0 from x = 0.2 m: the side seam's paths at x = 0.25 m cross it.
    sleeve = Patch.rectangle("sleeve", (0.3, 0.2), (7, 5), origin=(0.2, 0.0, 1.1), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    cuff = Patch.rectangle("cuff", (0.05, 0.2), (4, 5), origin=(0.52, 0.0, 1.1), axis_u=(1, 0, 0), axis_v=(0, 0, 1))

    def edge(p, u, k=9):  # k parameter samples up the patch's side at parameter u
        return np.c_[np.full(k, u), np.linspace(0, p.shape[1] - 2, k)]

    seams = [PatchSeam("side", "front", "back", edge(front, 6.0), edge(back, 6.0), [], []),
             PatchSeam("cuff", "sleeve", "cuff", edge(sleeve, 5.0, 5), edge(cuff, 0.0, 5), [], [])]
    patches = [front, back, sleeve, cuff]
    before = {p.name: p.world.copy() for p in patches}
    caught = seams_through_cloth(patches, seams)
    assert set(caught) == {("side", "sleeve")} and caught[("side", "sleeve")] >= 3
    moved = out_of_seam_paths(patches, seams, V, F)
    # 4 cm leaves the sleeve's inner edge at 0.24 m, still caught; 6 cm frees it.
    assert moved == pytest.approx({"sleeve": 3 * OUT_STEP, "cuff": 3 * OUT_STEP})
    np.testing.assert_allclose(sleeve.world - before["sleeve"], np.broadcast_to([0.06, 0, 0], sleeve.world.shape))
    np.testing.assert_allclose(cuff.world - before["cuff"], np.broadcast_to([0.06, 0, 0], cuff.world.shape))
    assert all(np.array_equal(p.world, before[p.name]) for p in (front, back))
    assert seams_through_cloth(patches, seams) == {}
    assert independent_pairs(patches, body) == 0


def test_a_cuff_caught_in_the_other_cuffs_side_seam_moves_alone():
    """Two trouser cuffs laid on ankles close together overlap: one cuff's inner side seam
    closes through the other cuff (jumpsuit_777_03). What hangs from the caught cuff is
    the whole garment but the first cuff, round the body's axis, which no rigid move may
    take; the caught cuff moves alone, out of the paths, and the torso stays."""
    from garment.dress.layout import OUT_STEP, out_of_seam_paths, seams_through_cloth
    from sim.seams.spec import PatchSeam

    body = torso()
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    front = Patch.rectangle("front", (0.5, 0.4), (8, 7), origin=(-0.25, -0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    back = Patch.rectangle("back", (0.5, 0.4), (8, 7), origin=(-0.25, 0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))

    def cuff(name, x0, width, y):  # 9 cm deep, below the body (an ankle's height)
        return Patch.rectangle(name, (width, 0.09), (7, 4), origin=(x0, y, -0.3), axis_u=(1, 0, 0), axis_v=(0, 0, 1))

    # Cuff a from x = -0.3 to 0.02 m in the planes y = -+0.1; cuff b from x = -0.03 m in
    # the planes y = -+0.08, between a's two panels: a's inner seam, at x = 0.02 m, crosses it.
    a_front, a_back = cuff("a_front", -0.3, 0.32, -0.1), cuff("a_back", -0.3, 0.32, 0.1)
    b_front, b_back = cuff("b_front", -0.03, 0.33, -0.08), cuff("b_back", -0.03, 0.33, 0.08)

    def side(p, u, k=5):  # k samples up the patch's side at parameter u
        return np.c_[np.full(k, u), np.linspace(0, p.shape[1] - 2, k)]

    def top(name, c, torso_panel):  # a cuff's top to the torso's bottom
        return PatchSeam(name, c.name, torso_panel.name, np.c_[np.linspace(0, 5, 7), np.full(7, 2.0)],
                         np.c_[np.linspace(0, 6, 7), np.zeros(7)], [], [])

    seams = [PatchSeam("left", "front", "back", side(front, 6.0), side(back, 6.0), [], []),
             PatchSeam("right", "front", "back", side(front, 0.0), side(back, 0.0), [], []),
             PatchSeam("inner_a", "a_front", "a_back", side(a_front, 5.0), side(a_back, 5.0), [], []),
             PatchSeam("inner_b", "b_front", "b_back", side(b_front, 0.0), side(b_back, 0.0), [], []),
             top("top_af", a_front, front), top("top_ab", a_back, back),
             top("top_bf", b_front, front), top("top_bb", b_back, back)]
    patches = [front, back, a_front, a_back, b_front, b_back]
    before = {p.name: p.world.copy() for p in patches}
    caught = {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert caught == {("inner_a", "b_front"), ("inner_a", "b_back")}
    moved = out_of_seam_paths(patches, seams, V, F)
    # Out along +x, away from cuff a: 4 cm leaves b's inner edge at x = 0.01 m, still
    # caught; 6 cm frees it. Down, it would need 10 cm.
    assert moved == pytest.approx({"b_front": 3 * OUT_STEP, "b_back": 3 * OUT_STEP})
    for p in (b_front, b_back):
        np.testing.assert_allclose(p.world - before[p.name], np.broadcast_to([0.06, 0, 0], p.world.shape))
    assert all(np.array_equal(p.world, before[p.name]) for p in (front, back, a_front, a_back))
    assert not {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert independent_pairs(patches, body) == 0


def test_a_skirt_round_the_body_caught_in_the_side_seams_stays():
    """A flared skirt laid flat reaches into the bodice's side seams with both sides, but
    round the body's axis its own side seams wrap it out of their paths as they close; no
    rigid move frees it without taking it off its waist seam, so it is left where it is
    (dress_04's skirt, moved 22-24 cm, slid off or stayed 3.8 mm open)."""
    from garment.dress.layout import out_of_seam_paths, seams_through_cloth
    from sim.seams.spec import PatchSeam

    body = torso()
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    front = Patch.rectangle("front", (0.5, 0.4), (8, 7), origin=(-0.25, -0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    back = Patch.rectangle("back", (0.5, 0.4), (8, 7), origin=(-0.25, 0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    # A skirt's front and back, 0.8 m wide, in the planes y = -+0.2 (in front of and behind
    # the body), their tops 10 cm up into the bodice: both side seams' paths, at x = +-0.25
    # m, cross both.
    skirt = [Patch.rectangle(name, (0.8, 0.5), (9, 6), origin=(-0.4, y, 0.6), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
             for name, y in (("skirt_front", -0.2), ("skirt_back", 0.2))]

    def edge(p, u, k=9):
        return np.c_[np.full(k, u), np.linspace(0, p.shape[1] - 2, k)]

    def waist(name, bodice):  # the skirt's top middle to the bodice's bottom
        return PatchSeam(name, f"skirt_{bodice}", bodice, np.c_[np.linspace(2, 5, 5), np.full(5, 4.0)],
                         np.c_[np.linspace(0, 6, 5), np.zeros(5)], [], [])

    seams = [PatchSeam("left", "front", "back", edge(front, 6.0), edge(back, 6.0), [], []),
             PatchSeam("right", "front", "back", edge(front, 0.0), edge(back, 0.0), [], []),
             waist("waist_front", "front"), waist("waist_back", "back")]
    patches = [front, back, *skirt]
    before = [p.world.copy() for p in skirt]
    caught = {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert caught == {(side, p.name) for side in ("left", "right") for p in skirt}
    assert out_of_seam_paths(patches, seams, V, F) == {}
    for p, w in zip(skirt, before):
        np.testing.assert_array_equal(p.world, w)


def test_turned_onto_seams_undoes_a_turn_in_the_panels_plane():
    """A sleeve's front and back, turned 50 degrees about y and moved away from the armhole
    they are sewn to, are put back by the 2D least-squares fit: every seam sample lands on
    its partner."""
    from garment.dress.layout import _turned_onto_seams
    from sim.seams.spec import PatchSeam

    torso_f = Patch.rectangle("tf", (0.3, 0.3), (6, 6), origin=(0.0, -0.1, 1.1), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    torso_b = Patch.rectangle("tb", (0.3, 0.3), (6, 6), origin=(0.0, 0.1, 1.1), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    # The sleeve's panels start on the torso's armhole edge (x = 0.3 m), going out.
    sleeve = {n: Patch.rectangle(n, (0.25, 0.3), (5, 6), origin=(0.3, y, 1.1), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
              for n, y in (("sf", -0.1), ("sb", 0.1))}
    edge = np.c_[np.zeros(6), np.linspace(0, 4, 6)]  # the sleeve's inner side, u = 0
    armhole = np.c_[np.full(6, 4.0), np.linspace(0, 4, 6)]  # the torso's outer side, u = 4
    seams = [PatchSeam("arm_f", "sf", "tf", edge, armhole, [], []), PatchSeam("arm_b", "tb", "sb", armhole, edge, [], [])]
    angle = np.radians(50.0)
    turn = np.array([[np.cos(angle), 0, -np.sin(angle)], [0, 1, 0], [np.sin(angle), 0, np.cos(angle)]])
    pivot = np.array([0.3, 0.0, 1.1])
    start = {n: (p.world - pivot) @ turn.T + pivot + [0.08, 0.0, -0.12] for n, p in sleeve.items()}
    out = _turned_onto_seams(start, seams, {p.name: p for p in (torso_f, torso_b, *sleeve.values())})
    for n, p in sleeve.items():
        np.testing.assert_allclose(out[n], p.world, atol=1e-9)


def test_a_sleeve_only_a_far_move_frees_is_turned_onto_its_armhole():
    """A fan sleeve laid hanging down across the side seam (its underarm between the
    torso's front and back), its armhole meant for the torso's side above the side seam
    (upper_garment_777_03): moved, it is freed only 24 cm out, its armhole as far open;
    turned in its plane onto the armhole it is freed and its armhole seam nearly shut."""
    from garment.dress.layout import out_of_seam_paths, seams_through_cloth
    from sim.embedding import points_at
    from sim.seams.spec import PatchSeam

    body = torso(radius=0.08)
    V, F = np.asarray(body.vertices), np.asarray(body.faces, np.int32)
    front = Patch.rectangle("front", (0.5, 0.5), (8, 8), origin=(-0.25, -0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    back = Patch.rectangle("back", (0.5, 0.5), (8, 8), origin=(-0.25, 0.25, 1.0), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
    # The sleeve hangs from z = 1.3 m down to 0.95, x 0.03..0.47, between front and back:
    # the side seam's paths (x = 0.25 m, z 1.0..1.3) cross it, and it is freed 24 cm out
    # or in, or more up or down.
    sleeve = [Patch.rectangle(n, (0.44, 0.35), (6, 6), origin=(0.03, y, 0.95), axis_u=(1, 0, 0), axis_v=(0, 0, 1))
              for n, y in (("sleeve_f", -0.1), ("sleeve_b", 0.1))]

    def side(p, u, v0, v1, k=7):
        return np.c_[np.full(k, u), np.linspace(v0, v1, k)]

    top = np.c_[np.linspace(0, 4, 7), np.full(7, 4.0)]  # the sleeve's top edge
    seams = [PatchSeam("side", "front", "back", side(front, 6.0, 0.0, 3.5), side(back, 6.0, 0.0, 3.5), [], []),
             PatchSeam("arm_f", "sleeve_f", "front", top, side(front, 6.0, 3.6, 6.0), [], []),
             PatchSeam("arm_b", "sleeve_b", "back", top, side(back, 6.0, 3.6, 6.0), [], []),
             PatchSeam("under", "sleeve_f", "sleeve_b", side(None, 0.0, 0.0, 4.0), side(None, 0.0, 0.0, 4.0), [], [])]
    patches = [front, back, *sleeve]
    caught = {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert caught == {("side", "sleeve_f"), ("side", "sleeve_b")}
    moved = out_of_seam_paths(patches, seams, V, F)
    assert set(moved) == {"sleeve_f", "sleeve_b"}
    assert not {k for k, n in seams_through_cloth(patches, seams).items() if n >= 3}
    assert independent_pairs(patches, body) == 0
    index = {p.name: p for p in patches}
    gap = max(np.linalg.norm(points_at(index[s.patch_a].world, s.uv_a) - points_at(index[s.patch_b].world, s.uv_b),
                             axis=1).max() for s in seams if s.name.startswith("arm"))
    assert gap < 0.2  # moved 24 cm, the armhole would be 24 cm open or more
