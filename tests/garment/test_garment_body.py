"""A garment sewn onto a moving character, checked frame by frame with the independent
brute-force intersection test (tests/support/intersections.py): the bundled poncho
(assets/scenes/poncho_rumba.toml), placed and sewn as `garment dress` does it, closes its
shoulder seams during the pre-roll and rides the first frames of the Rumba dance."""

from __future__ import annotations

import dataclasses

import pytest

from garment.dress.scene_file import scene_for_run
from garment.build import build_simulator

from tests.support.intersections import assert_garment_clean
from tests.support.paths import SCENES

SCENE = SCENES / "poncho_rumba.toml"


@pytest.mark.slow
def test_poncho_sews_onto_the_dancing_body_without_intersections(tmp_path):
    scene = scene_for_run(SCENE, tmp_path)
    frames = 20  # the 0.6 s pre-roll + 0.2 s of the dance
    assert scene.time.preroll == pytest.approx(0.6)
    sim = build_simulator(dataclasses.replace(scene, time=dataclasses.replace(scene.time, frames=frames)))
    body = sim.model.obstacles[0]
    gaps = []
    for frame in range(frames):
        for _ in range(scene.time.steps_per_frame):
            sim.step()
        # No garment-body pair, and within the garment none at all (sewn panels share their
        # seam vertices exactly).
        assert_garment_clean(sim.model.pieces, sim.C, f"frame {frame}", body.at(sim.t), body.faces)
        gaps.append(float(sim.model.seam.samples.gaps(sim.C).max()))
    assert gaps[0] > 0.05  # the seams start open...
    assert max(gaps[-5:]) < 1e-3  # ...and are closed below 1 mm once sewn, while the body dances
