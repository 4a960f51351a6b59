"""Several garments in one scene: two bibs, one over the other, sewn over a ball with their
own seam stiffnesses, checked every step with the independent intersection test
(tests/support/intersections.py) between the garments, within each, and against the ball."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from garment.scene import parse_scene
from sim.simulator import Simulator
from tests.support.intersections import garment_intersections

SPACING = 0.02


def _bib(path: Path, width: float, height: float, plane: float, top: float) -> Path:
    """A panel OBJ (garment/io/panels.py): two width x height panels at y = +-plane whose
    top edges (z = top) are sewn together outside a central neck opening."""
    nx, nz = round(width / SPACING) + 1, round(height / SPACING) + 1
    s, t = np.meshgrid(np.linspace(0, width, nx), np.linspace(0, height, nz), indexing="ij")
    flat = np.c_[s.ravel(), t.ravel()]
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    v = (i * nz + j).ravel()
    tris = np.r_[np.c_[v, v + nz, v + nz + 1], np.c_[v, v + nz + 1, v + 1]]
    n, lines = len(flat), []
    for y in (plane, -plane):
        lines += [f"v {x - width / 2:.6f} {y:.6f} {top - height + z:.6f}" for x, z in flat]
    lines += [f"vt {x:.6f} {z:.6f}" for _ in range(2) for x, z in flat]
    for k, name in enumerate(("front", "back")):
        lines.append(f"g {name}")
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in tris + 1 + k * n]
    top_ids = np.arange(nx) * nz + nz - 1
    x = flat[top_ids, 0] - width / 2
    for side in (x <= -0.05, x >= 0.05):
        lines.append(f"seam {side.sum()}")
        lines += [f"stitch {a} {a + n} {a + n} 0" for a in top_ids[side]]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_two_garments_sew_and_layer_over_a_ball_without_intersections(tmp_path):
    inner = _bib(tmp_path / "inner.obj", 0.24, 0.16, 0.12, 0.13)
    outer = _bib(tmp_path / "outer.obj", 0.30, 0.18, 0.15, 0.16)
    doc = {
        "garment": [{"name": "inner", "source": str(inner), "knot_span_mm": 40, "seam_stiffness": 1e6},
                    {"name": "outer", "source": str(outer), "knot_span_mm": 40, "seam_stiffness": 2e5}],
        "obstacle": [{"name": "ball", "sphere": {"radius": 0.1, "subdivisions": 3}}],
        "contact": {"dhat": 1e-3, "kappa": "adaptive", "mu": 0.2},
        "time": {"dt": 0.01, "frames": 30, "preroll": 0.2},
    }
    sim = Simulator.from_scene(parse_scene(doc, tmp_path / "bibs.toml"))
    names = [p.name for p in sim.pieces]
    assert names == ["inner.front", "inner.back", "outer.front", "outer.back"]

    # Each garment's seams carry its own stiffness: k = 2 E / sum w gap^2 per garment.
    seam = sim.seam
    inner_rows = np.repeat([s.piece_a.startswith("inner") for s in sim.seams], [len(s.uv_a) for s in sim.seams])
    D, w = seam.D.toarray(), seam.samples.weights
    C = np.random.default_rng(0).normal(size=sim.C.shape)
    for rows, k in ((inner_rows, 1e6), (~inner_rows, 2e5)):
        gap2 = ((D[rows] @ C) ** 2).sum(axis=1)
        K_part = sp.csr_matrix(D[rows]).T @ sp.diags(k * w[rows]) @ sp.csr_matrix(D[rows])
        assert abs(np.einsum("ij,ij", C, K_part @ C) - k * (w[rows] * gap2).sum()) < 1e-6 * k
    np.testing.assert_allclose((seam.K0 @ C), (sp.csr_matrix(D).T @ sp.diags(
        np.where(inner_rows, 1e6, 2e5) * w) @ sp.csr_matrix(D)) @ C, rtol=1e-12, atol=1e-9)

    ball = sim.obstacles[0]
    merged = []
    for step in range(30):
        merged.append(sim.step().extra["seam_pairs_sewn"])
        x, ball_pairs, cloth_pairs = garment_intersections(sim.pieces, sim.C, ball.at(sim.t), ball.faces)
        assert np.all(np.isfinite(x)), step
        assert ball_pairs == 0, f"garment-ball, step {step}"
        # Sewn panels share their seam vertices exactly; no other triangle pair may cross.
        assert cloth_pairs == 0, f"cloth-cloth intersection, step {step}: {cloth_pairs} pairs"
    assert (sim.seam_contact.state == 1).all() and sum(merged) == len(sim.seam_contact.state)  # sewn shut in the pre-roll
    gaps = sim.seam.samples.gaps(sim.C)
    assert gaps[inner_rows].max() < 1e-3 and gaps[~inner_rows].max() < 1e-3
    # Both rest on the ball, the outer one on the inner one: both hang below its top.
    assert x[:, 2].max() < 0.16
