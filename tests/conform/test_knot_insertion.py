"""Exact refinement of garments (conform/knot_insertion.py): the same surfaces and seams
with more control points, and a sewn simulation continued at the finer span."""

from __future__ import annotations

import numpy as np
import pytest

from conform.knot_insertion import refine_net, refine_patchset
from garment.bench.garment import _refined
from sim.model import ContactOptions, bspline_model
from sim.errors import InputError
from sim.materials import PRESETS
from sim.patches import Patch, PatchSet
from sim.seams.spec import BoundaryInterval, PatchSeam
from garment.scene import parse_scene
from sim.contact.mesh import crossing_pairs
from sim.embedding import interpolation_matrix
from garment.build import build_simulator
from sim.simulator import Simulator

from tests.support.panels import bib


def _surface(X, u, v):
    n, m = X.shape[:2]
    return interpolation_matrix(u, v, n, m, 0, n * m) @ X.reshape(n * m, -1)


def test_refined_nets_and_seams_describe_the_same_garment():
    rng = np.random.default_rng(1)
    a = Patch("a", rng.normal(size=(6, 5, 2)), rng.normal(size=(6, 5, 3)))
    b = Patch("b", rng.normal(size=(4, 7, 2)), rng.normal(size=(4, 7, 3)))
    uv_a, uv_b = np.c_[np.full(5, 4.0), np.linspace(0, 3, 5)], np.c_[np.linspace(0, 2, 5), np.zeros(5)]
    seam = PatchSeam("s", "a", "b", uv_a, uv_b, [BoundaryInterval("u1", 0.0, 3.0)], [BoundaryInterval("v0", 0.0, 2.0)])
    ps = PatchSet([a, b], [seam], {}, {}, {})
    for levels in (1, 2):
        fine = refine_patchset(ps, levels)
        k = 2.0 ** levels
        assert fine.patches[0].shape == (4 * 2 ** levels + 2, 3 * 2 ** levels + 2)
        for p, q in zip(ps.patches, fine.patches):
            n, m = p.shape
            u, v = rng.uniform(0, n - 2, 40), rng.uniform(0, m - 2, 40)
            for coarse, refined in ((p.rest, q.rest), (p.world, q.world)):
                assert np.abs(_surface(coarse, u, v) - _surface(refined, k * u, k * v)).max() < 1e-13
        s = fine.seams[0]
        for X, Y, uv, fuv in ((a.world, fine.patches[0].world, uv_a, s.uv_a), (b.world, fine.patches[1].world, uv_b, s.uv_b)):
            assert np.abs(_surface(X, *uv.T) - _surface(Y, *fuv.T)).max() < 1e-13
        assert s.intervals_a[0].t1 == 3.0 * k and s.intervals_b[0].side == "v0"
    world = {"a": np.zeros((6, 5, 3))}
    assert np.all(refine_patchset(ps, 1, world).patches[0].world == 0.0)
    assert refine_net(a.rest, 0) is a.rest


def test_a_sewn_garment_continues_exactly_at_half_the_span(tmp_path):
    source = bib(tmp_path / "bib.obj", 0.24, 0.16, 0.12, 0.13)
    doc = {"garment": [{"name": "bib", "source": str(source), "knot_span_mm": 40}],
           "obstacle": [{"name": "ball", "sphere": {"radius": 0.1, "subdivisions": 3}}],
           "contact": {"dhat": 1e-3, "kappa": "adaptive"}, "time": {"dt": 0.01, "frames": 10, "preroll": 0.05}}
    scene = parse_scene(doc, tmp_path / "bib.toml")
    coarse = build_simulator(scene)
    for _ in range(6):
        coarse.step()
    fine = _refined(coarse, scene, 1, tmp_path)
    assert fine.t == coarse.t and fine.n_dofs > 2.5 * coarse.n_dofs
    for p in coarse.model.pieces:
        n, m = p.patch.shape
        u, v = np.meshgrid(np.linspace(0, n - 2, 7), np.linspace(0, m - 2, 7))
        for X, Y in ((coarse.control_points(p.name), fine.control_points(p.name)),
                     (coarse.velocities(p.name), fine.velocities(p.name))):
            assert np.abs(_surface(X, u.ravel(), v.ravel()) - _surface(Y, 2 * u.ravel(), 2 * v.ravel())).max() < 1e-12
    np.testing.assert_allclose(fine.model.seam.samples.gaps(fine.C), coarse.model.seam.samples.gaps(coarse.C), atol=1e-12)
    assert fine.step().converged


def test_only_a_handed_over_state_may_start_with_crossings():
    def crossed(keep_crossings):
        a = Patch.rectangle("a", (0.2, 0.2), (6, 6), (-0.1, -0.1, 0.0), (1, 0, 0), (0, 1, 0))
        b = Patch.rectangle("b", (0.2, 0.2), (6, 6), (-0.1, 0.0, -0.1), (1, 0, 0), (0, 0, 1))  # through a
        return Simulator(bspline_model([a, b], [PRESETS["cotton"]] * 2, contact=ContactOptions(adaptive_kappa=True),
                                       keep_crossings=keep_crossings))

    with pytest.raises(InputError, match=r"intersects itself or an obstacle: a and b \(\d+ edges\)\. Move"):
        crossed(False)

    sim = crossed(True)
    mesh = sim.model.barrier.contact
    x = mesh.vertices(sim.C)
    n_a = sim.model.pieces[0].W.shape[0]
    pairs = crossing_pairs(mesh.mesh, x, mesh.n_cloth)
    assert pairs and all(i < n_a <= j for i, j in pairs)  # only a-b pairs, where the sheets cross
    separate = np.array(x)
    separate[n_a:, 2] += 1.0  # lift b clear of a: nothing crosses
    assert crossing_pairs(mesh.mesh, separate, mesh.n_cloth) == set()
