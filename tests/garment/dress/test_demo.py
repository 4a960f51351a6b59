"""The demo's scene: a 9-panel GarmentCode skirt placed around the CC0 MakeHuman body's
bind pose (garment/commands/demo.py). Its first frames sew the skirt weightless, checked
with the independent crossing test; the whole clip is `make demo`."""

import numpy as np

from garment.build import build_simulator
from garment.commands.demo import demo_scene
from garment.verify import frame_crossings


def test_demo_scene_starts_clean_and_sews(tmp_path):
    scene = demo_scene(tmp_path / "demo.rrd", frames=3)
    assert scene.obstacles[0].kind == "skin" and scene.time.preroll == 1.0
    sim = build_simulator(scene)
    assert len(sim.model.pieces) == 9
    gaps = []
    for _ in range(3 * scene.time.steps_per_frame):
        st = sim.step()
        gaps.append(st.extra["seam_gap_max"])
    pos = sim.positions() | sim.obstacle_positions()
    cloth = [(pos[m.name], m.faces) for m in sim.topologies() if m.kind == "cloth"]
    bodies = [(pos[m.name], m.faces) for m in sim.topologies() if m.kind != "cloth"]
    assert frame_crossings(cloth, bodies) == (0, 0)
    assert np.isfinite(gaps).all() and gaps[-1] < 0.5 * gaps[0]  # the seams are closing
