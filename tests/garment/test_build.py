"""Building a simulation from a scene (garment/build.py): the scene's settings reach the
model they describe."""

from __future__ import annotations

from dataclasses import fields

from garment.build import build_simulator, contact_options, sewing_options
from garment.scene import loads_scene
from sim.drag import Drag
from sim.model import ContactOptions
from sim.seams.sewing import SewingOptions

CLOTH = "[[cloth]]\nsize = [0.5, 0.5]\ncontrol_points = [6, 6]\n"


def test_sewing_table_and_sewing_mode_fill_the_sewing_policy():
    scene = loads_scene(CLOTH + "[time]\nsewing = 'quasistatic'\nsettle_drag = 5.0\npreroll = 0.4\n[sewing]\nramp_start = 25.0\n"
                        "multiplier_step = 3.0\nblock_reach = 7.0\nheld_fraction = 0.05\npleat_wait_gap_mm = 2.0\n"
                        "pleat_wait_end = 0.9\n")
    o = sewing_options(scene, 0.4)
    assert (o.ramp, o.quasistatic, o.multipliers) == (0.4, True, True)
    assert (o.ramp_start, o.multiplier_step, o.block_reach, o.held_fraction) == (25.0, 3.0, 7.0, 0.05)
    assert abs(o.pleat_wait_gap - 2e-3) < 1e-15 and o.pleat_wait_end == 0.9
    # Left out, the table gives the policy's own defaults.
    default = sewing_options(loads_scene(CLOTH), 0.0)
    assert default == SewingOptions(ramp=0.0)


def test_settle_drag_reaches_the_model_with_or_without_seams():
    # A scene without seams once dropped [time] settle_drag silently (it lived in the
    # sewing policy); it is the model's velocity policy, starting after the pre-roll.
    scene = loads_scene(CLOTH + "[time]\nsettle_drag = 5.0\npreroll = 0.4\n")
    model = build_simulator(scene).model
    assert model.sewing is None and model.drag == Drag(5.0, 0.4)
    assert build_simulator(loads_scene(CLOTH)).model.drag == Drag()


def test_contact_table_fills_every_contact_option():
    scene = loads_scene(CLOTH + "[contact]\nenabled = true\ndhat = 2e-3\nkappa = 'adaptive'\nmu = 0.2\n"
                        "self_contact = false\nseams = 'band'\nmesh_density = 1.5\n")
    o = contact_options(scene.contact)
    assert o == ContactOptions(enabled=True, dhat=2e-3, kappa=o.kappa, adaptive_kappa=True, mu=0.2,
                               self_contact=False, seams="band", mesh_density=1.5)
    assert {f.name for f in fields(ContactOptions)} <= {f.name for f in fields(type(scene.contact))}
