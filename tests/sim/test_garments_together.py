"""Several garments in one scene: two bibs, one over the other, sewn over a ball with their
own seam stiffnesses, checked every step with the independent intersection test
(tests/support/intersections.py) between the garments, within each, and against the ball."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from garment.scene import parse_scene
from garment.build import build_simulator

from tests.support.intersections import assert_garment_clean
from tests.support.panels import bib


def test_two_garments_sew_and_layer_over_a_ball_without_intersections(tmp_path):
    inner = bib(tmp_path / "inner.obj", 0.24, 0.16, 0.12, 0.13)
    outer = bib(tmp_path / "outer.obj", 0.30, 0.18, 0.15, 0.16)
    doc = {
        "garment": [{"name": "inner", "source": str(inner), "knot_span_mm": 40, "seam_stiffness": 1e6},
                    {"name": "outer", "source": str(outer), "knot_span_mm": 40, "seam_stiffness": 2e5}],
        "obstacle": [{"name": "ball", "sphere": {"radius": 0.1, "subdivisions": 3}}],
        "contact": {"dhat": 1e-3, "kappa": "adaptive", "mu": 0.2},
        "time": {"dt": 0.01, "frames": 30, "preroll": 0.2},
    }
    sim = build_simulator(parse_scene(doc, tmp_path / "bibs.toml"))
    names = [p.name for p in sim.model.pieces]
    assert names == ["inner.front", "inner.back", "outer.front", "outer.back"]

    # Each garment's seams carry its own stiffness: k = 2 E / sum w gap^2 per garment.
    seam = sim.model.seam
    inner_rows = np.repeat([s.piece_a.startswith("inner") for s in sim.model.seams], [len(s.uv_a) for s in sim.model.seams])
    D, w = seam.D.toarray(), seam.samples.weights
    C = np.random.default_rng(0).normal(size=sim.C.shape)
    for rows, k in ((inner_rows, 1e6), (~inner_rows, 2e5)):
        gap2 = ((D[rows] @ C) ** 2).sum(axis=1)
        K_part = sp.csr_matrix(D[rows]).T @ sp.diags(k * w[rows]) @ sp.csr_matrix(D[rows])
        assert abs(np.einsum("ij,ij", C, K_part @ C) - k * (w[rows] * gap2).sum()) < 1e-6 * k
    np.testing.assert_allclose((seam.K0 @ C), (sp.csr_matrix(D).T @ sp.diags(
        np.where(inner_rows, 1e6, 2e5) * w) @ sp.csr_matrix(D)) @ C, rtol=1e-12, atol=1e-9)

    ball = sim.model.obstacles[0]
    merged = []
    for step in range(30):
        merged.append(sim.step().extra["seam_pairs_sewn"])
        x = assert_garment_clean(sim.model.pieces, sim.C, f"step {step}", ball.at(sim.t), ball.faces)
    assert (sim.model.seam_contact.state == 1).all() and sum(merged) == len(sim.model.seam_contact.state)  # sewn shut in the pre-roll
    gaps = sim.model.seam.samples.gaps(sim.C)
    assert gaps[inner_rows].max() < 1e-3 and gaps[~inner_rows].max() < 1e-3
    # Both rest on the ball, the outer one on the inner one: both hang below its top.
    assert x[:, 2].max() < 0.16
