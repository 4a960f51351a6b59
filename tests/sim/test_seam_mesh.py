"""Seamed piece meshes (sim/seams/mesh.py): the uv rectangle tiled exactly, matched seam
vertices on both sides, and the contact mesh sewn shut once the seams close."""

from __future__ import annotations

import numpy as np
import pytest

import sim.seams.contact as seams_mod
from sim.model import ContactOptions
from sim.checkpoint import read_checkpoint, write_checkpoint
from sim.seams.mesh import (SNAP, THIN, Perimeter, matched_points, matched_uv_points, merged_labels,
                            seam_meshes, seamed_mesh)
from sim.embedding import points_at
from sim.seams.spec import SeamSpec

from tests.support.intersections import intersecting_triangles, shared_vertices, stacked_cloth
from tests.support.scenes import two_panels

U, V, RES = 6.0, 4.0, (11, 8)


def _areas(uv, F):
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _check_tiling(uv, F):
    area = _areas(uv, F)
    assert area.min() > 0.0  # counter-clockwise, like grid_faces
    assert abs(area.sum() - U * V) < 1e-12  # the rectangle, no gap, no overlap
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, count = np.unique(e, axis=0, return_counts=True)
    assert count.max() == 2  # edge-manifold
    B = edges[count == 1]
    on = Perimeter(U, V, *RES).on_boundary
    assert on(uv[B[:, 0]]) and on(uv[B[:, 1]])  # boundary edges lie on the rectangle's sides


@pytest.mark.parametrize("seam", [
    (12.0, 17.0),  # along u = U
    (30.0, 27.5),  # along v = V, reversed
    (28.5, 34.0),  # round the corner (0, V)
])
def test_seamed_mesh_tiles_the_rectangle_with_the_seam_vertices_on_its_boundary(seam):
    per = Perimeter(U, V, *RES)
    g = np.linspace(*seam, 7)
    ga, _ = matched_points(g, g[::-1] + 1.0, per, per)
    uv, F, (verts,) = seamed_mesh(U, V, RES, [ga])
    _check_tiling(uv, F)
    np.testing.assert_allclose(uv[verts], per.uv(ga), atol=1e-12)
    steps = np.abs(np.diff(ga))
    assert steps.max() <= 1.0 + 1e-12 and steps.min() >= THIN * 0.5 - 1e-12


def test_a_dart_running_into_the_patch_gets_its_legs_as_vertices():
    # Like dress_knife's panel6 darts: two legs from the v = 0 side a short way in.
    per = Perimeter(U, V, *RES)
    step = np.array([U / (RES[0] - 1), V / (RES[1] - 1)])
    leg_a = np.array([[1.5, 0.0], [1.7, 0.2], [1.9, 0.45], [2.0, 1.3]])
    leg_b = np.array([[3.6, 0.0], [3.3, 0.25], [3.1, 0.5], [2.6, 1.4]])
    pa, pb = matched_uv_points(leg_a, leg_b, step, step)
    assert len(pa) == len(pb) and np.allclose(pa[[0, -1]], leg_a[[0, -1]]) and np.allclose(pb[-1], leg_b[-1])
    gaps = np.linalg.norm(np.diff(pa, axis=0) / step, axis=1)
    assert gaps.max() <= 1.0 + 1e-12 and gaps.min() >= THIN * 0.5  # thinned and subdivided
    boundary = matched_points(np.array([12.0, 15.0]), np.array([34.0, 31.0]), per, per)
    uv, F, (va, vb, v1, v2) = seamed_mesh(U, V, RES, [pa, pb, *boundary])
    _check_tiling(uv, F)
    np.testing.assert_allclose(uv[va], pa, atol=1e-12)
    np.testing.assert_allclose(uv[vb], pb, atol=1e-12)
    np.testing.assert_allclose(uv[v1], per.uv(boundary[0]), atol=1e-12)
    assert len(set(va) | set(vb)) == len(va) + len(vb)  # every leg point its own vertex
    # Each leg is a line of mesh edges, so a closed dart folds along it.
    E = {tuple(sorted(e)) for f in F.tolist() for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert all(tuple(sorted(e)) in E for leg in (va, vb) for e in zip(leg[:-1], leg[1:]))


def test_seams_meeting_at_a_junction_share_its_vertex():
    # One seam ends where the next begins, to within a fraction of a grid step (as
    # conformed panels' seams do): one vertex, no edge shorter than the contact distance.
    per = Perimeter(U, V, *RES)
    first, _ = matched_points(np.array([2.0, 5.0]), np.array([20.0, 17.0]), per, per)
    second, _ = matched_points(np.array([5.0 + 0.5 * SNAP, 8.0]), np.array([30.0, 27.0]), per, per)
    uv, F, (va, vb) = seamed_mesh(U, V, RES, [first, second])
    _check_tiling(uv, F)
    assert va[-1] == vb[0]
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    steps = np.array([U / (RES[0] - 1), V / (RES[1] - 1)])
    assert np.linalg.norm((uv[e[:, 0]] - uv[e[:, 1]]) / steps, axis=1).min() > SNAP


def test_matched_points_keep_corners_and_pair_both_sides():
    per = Perimeter(U, V, *RES)
    c = per.corners[3]  # (0, V)
    ga, gb = matched_points(np.array([c - 2.3, c + 2.1]), np.array([1.0, 4.0]), per, per)
    assert len(ga) == len(gb)
    assert np.any(np.abs(ga - c) < 1e-12)  # the corner is a vertex
    # Both sides advance together: the same fraction of the seam at every matched pair.
    np.testing.assert_allclose((ga - ga[0]) / (ga[-1] - ga[0]), (gb - gb[0]) / (gb[-1] - gb[0]), atol=1e-12)
    assert np.diff(ga).max() <= 1.0 + 1e-12 and np.diff(gb).max() <= 1.0 + 1e-12


def _merged_shut(meshes: dict, pairs: list) -> int:
    """Mesh edges whose two ends the matched pairs merge into one vertex."""
    off = dict(zip(meshes, np.cumsum([0] + [len(uv) for uv, _ in meshes.values()])))
    n = sum(len(uv) for uv, _ in meshes.values())
    labels = merged_labels(n, np.concatenate([np.c_[va + off[a], vb + off[b]] for a, va, b, vb in pairs]))
    F = np.concatenate([f + off[name] for name, (_, f) in meshes.items()])
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return int((labels[E[:, 0]] == labels[E[:, 1]]).sum())


def test_a_point_sewn_to_a_stretch_merges_one_vertex_pair():
    # dress_00's shoulder: a seam 0.15 grid steps long on the front and 0.45 on the back.
    # The front's two points are one vertex (SNAP); matched to both back vertices, the
    # merge would pull the back edge between them to zero length and hold the seam open.
    step = U / (RES[0] - 1)
    seam = SeamSpec("front", np.array([[0.0, 0.0], [0.15 * step, 0.0]]),
                    "back", np.array([[0.0, 0.0], [0.45 * step, 0.0]]), "shoulder")
    shape = (int(U) + 2, int(V) + 2)
    meshes, pairs = seam_meshes({"front": shape, "back": shape}, {"front": RES, "back": RES}, [seam])
    assert len(pairs[0][1]) == 1 and _merged_shut(meshes, pairs) == 0
    assert np.allclose(meshes["back"][0][pairs[0][3][0]], [0.0, 0.0])


def test_a_cut_keeps_every_pair_so_its_pieces_start_sewn():
    # The shoulder seam above as a cut through one panel: its sides lie together at rest
    # (the front's net 3 x the back's, so 0.15 front steps are 0.45 back steps). The
    # pieces abut from the start, and an unmerged back vertex would sit on the front's
    # edge, crossing it (jumpsuit_777_02's 6 mm cut: 3 pairs dropped, 7 edges crossing):
    # both pairs merge, the back edge between them shut. Laid apart, one pair, as above.
    step = U / (RES[0] - 1)
    seam = SeamSpec("front", np.array([[0.0, 0.0], [0.15 * step, 0.0]]),
                    "back", np.array([[0.0, 0.0], [0.45 * step, 0.0]]), "cut")
    shape = (int(U) + 2, int(V) + 2)
    net = np.stack(np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij"), axis=-1) * 0.01
    net -= points_at(net, np.zeros((1, 2)))[0]  # uv (0, 0) at the origin on both
    for apart, kept, shut in ((0.0, 2, 1), (1.0, 1, 0)):
        rests = {"front": 3.0 * net, "back": net + apart}
        meshes, pairs = seam_meshes({"front": shape, "back": shape}, {"front": RES, "back": RES}, [seam], rests)
        assert (len(pairs[0][1]), _merged_shut(meshes, pairs)) == (kept, shut)


def test_a_gathered_seam_merges_no_edge_shut():
    # jumpsuit_777_02's back waist: 8.2 grid steps of torso gathered onto 2.4 of trouser.
    # Cut to a grid step on the torso, the trouser's points come 0.18 steps apart, below
    # SNAP, and two of them share a vertex: two torso neighbours matched to it.
    step = U / (RES[0] - 1)
    k = np.arange(9)  # samples 0.51 and 0.148 grid steps apart (3.4 to 1, as there)
    torso = np.c_[(0.2 + 0.51 * k) * step, np.zeros(9)]
    trouser = np.c_[(0.2 + 0.148 * k) * step, np.zeros(9)]
    shape = (int(U) + 2, int(V) + 2)
    meshes, pairs = seam_meshes({"torso": shape, "trouser": shape}, {"torso": RES, "trouser": RES},
                                [SeamSpec("torso", torso, "trouser", trouser, "waist")])
    _, va, _, vb = pairs[0]
    assert len(set(va.tolist())) == len(va) >= 4  # each torso vertex matched once,
    assert _merged_shut(meshes, pairs) == 0  # and no merge pulls a torso edge shut


def test_closed_seam_is_sewn_shut_in_the_contact_mesh():
    sim = two_panels(0.03)
    merged = [sim.step().extra["seam_pairs_sewn"] for _ in range(6)]
    n = len(sim.model.seam_contact.pairs)
    assert merged == [0, n, 0, 0, 0, 0] and (sim.model.seam_contact.state == 1).all()  # shut once all are within d_hat
    # Matched vertices now are one contact vertex and export the same position bit for bit.
    W, F, _ = stacked_cloth(sim.model.pieces)
    x = W @ sim.C
    a, b = sim.model.seam_contact.pairs.T
    assert np.array_equal(x[a], x[b])
    assert sim.model.barrier.contact.n_cloth == len(x) - len(a)
    # No barrier between stitched neighbours, none needed anywhere else, nothing crosses.
    st = sim.step()
    assert st.extra["contact_count"] == 0
    assert len(intersecting_triangles(*shared_vertices(x, F))) == 0
    assert sim.model.seam.samples.gaps(sim.C).max() < 1e-5


def test_resume_after_the_seams_merged(tmp_path):
    sim = two_panels(0.03)
    for _ in range(3):
        sim.step()
    ck = read_checkpoint(write_checkpoint(tmp_path / "c.npz", sim.state, 3, "sewn"))
    resumed = two_panels(0.03)
    resumed.state = ck.state
    assert (resumed.model.seam_contact.state == 1).all()
    sim.step()
    resumed.step()
    assert np.array_equal(resumed.C, sim.C)


def test_band_seams_keep_grids_and_exclude_pairs_near_the_seam():
    merged = two_panels(0.03)
    band = two_panels(0.03, contact=ContactOptions(adaptive_kappa=True, seams="band"))
    assert len(band.model.seam_contact.pairs) == 0 and band.model.seam_contact.excluded
    assert [len(p.topology.faces) for p in band.model.pieces] == [2 * 10 * 10] * 2  # the plain 11 x 11 grids
    assert len(merged.model.seam_contact.pairs) > 0 and not merged.model.seam_contact.excluded


@pytest.mark.parametrize("keep", [False, True])
def test_crossings_away_from_the_merged_pairs_stop_only_a_fresh_state_sewing(monkeypatch, keep):
    # A state handed over from a coarser run (keep_crossings) may carry crossings that no
    # merge made; they must not stop its seams from sewing, as they must for a fresh run.
    sim = two_panels(0.03)
    sim.model.seam_contact.keep_crossings = keep
    monkeypatch.setattr(seams_mod.ipctk, "has_intersections", lambda mesh, x: True)
    monkeypatch.setattr(seams_mod, "crossings_at", lambda *args: np.zeros(0, np.int64))
    merged = [sim.step().extra["seam_pairs_sewn"] for _ in range(3)]
    n = len(sim.model.seam_contact.pairs)
    assert merged == ([0, n, 0] if keep else [0, 0, 0])
    assert (sim.model.seam_contact.state == 1).all() == keep


def test_a_pair_blocked_then_sewn_counts_once(monkeypatch):
    # The first merge crosses at one pair: it is BLOCKED, the rest are sewn, and it sews
    # on a later step. seam_pairs_sewn counts each pair once, when it is sewn.
    sim = two_panels(0.03)
    calls = []
    real = seams_mod.ipctk.has_intersections

    def first_crosses(mesh, x):
        calls.append(1)
        return len(calls) == 1 or real(mesh, x)

    monkeypatch.setattr(seams_mod.ipctk, "has_intersections", first_crosses)
    monkeypatch.setattr(seams_mod, "crossings_at", lambda mesh, x, n, labels: labels[:1])
    merged = [sim.step().extra["seam_pairs_sewn"] for _ in range(2)]
    n = len(sim.model.seam_contact.pairs)
    assert merged == [0, n - 1] and (sim.model.seam_contact.state != seams_mod.SEWN).sum() == 1
    for _ in range(4):
        merged.append(sim.step().extra["seam_pairs_sewn"])
        if (sim.model.seam_contact.state == seams_mod.SEWN).all():
            break
    assert (sim.model.seam_contact.state == seams_mod.SEWN).all() and sum(merged) == n


def test_the_ring_does_not_turn_over_in_the_rest_shape():
    # A rest shape whose v = 0 side bulges in by 0.8 grid steps over a short stretch (as a
    # boundary wrapping round a dart tip comes close to the grid's next row): zipped in
    # perimeter order, ring triangles turn over there; the zip advances the other loop.
    per = Perimeter(U, V, *RES)
    du, dv = U / (RES[0] - 1), V / (RES[1] - 1)

    def place(uv):
        bulge = np.where(np.abs(uv[:, 1]) < 1e-12, 0.8 * dv * np.exp(-((uv[:, 0] - 1.5) / (0.6 * du)) ** 2), 0.0)
        return uv + bulge[:, None] * [0.0, 1.0]

    ga, _ = matched_points(np.linspace(0.5, 8.5, 17), np.linspace(8.5, 0.5, 17), per, per)
    uv, F, _ = seamed_mesh(U, V, RES, [ga])
    assert _areas(place(uv), F).min() < 0.0  # the order of the perimeter alone
    uv, F, (verts,) = seamed_mesh(U, V, RES, [ga], place)
    _check_tiling(uv, F)
    assert _areas(place(uv), F).min() > 0.0
    np.testing.assert_allclose(uv[verts], per.uv(ga), atol=1e-12)
