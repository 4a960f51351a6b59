"""Small scenes the tests share: scene-file texts, and seamed panels built in code."""

from __future__ import annotations

import numpy as np

from sim.model import ContactOptions, bspline_model
from sim.materials import PRESETS
from sim.patches import Patch
from sim.seams.spec import SeamSpec
from sim.simulator import Simulator

# A 7x6 sheet hanging from two corners: 4 frames of 2 steps.
HANGING_SHEET = """
[[cloth]]
name = "sheet"
size = [0.4, 0.3]
control_points = [7, 6]
origin = [0, 0, 1]
axis_u = [1, 0, 0]
axis_v = [0, 0, -1]

[[pin]]
corners = ["u0v0", "u1v0"]

[time]
dt = 0.01
frames = 4
steps_per_frame = 2
"""

# A 10x10 sheet dropped onto a ball on the ground; `.format(height=...)` places it.
DROP = """
[material]
E_bd = 8e3
[[cloth]]
name = "sheet"
size = [0.4, 0.4]
control_points = [10, 10]
origin = [-0.2, -0.2, {height}]
[[obstacle]]
name = "ball"
sphere = {{radius = 0.08, center = [0.0, 0.0, 0.08], subdivisions = 2}}
[[obstacle]]
name = "ground"
plane = {{point = [0, 0, 0], normal = [0, 0, 1], size = 2.0}}
[contact]
dhat = 1e-3
kappa = 1e5
[time]
dt = 0.01
"""

N = 8  # control points along each side of the seam tests' panels


def panel(name: str, origin, size=(0.2, 0.2)) -> Patch:
    """An N x N control point panel in the plane z = origin[2], u along x and v along y."""
    return Patch.rectangle(name, size, (N, N), origin, (1, 0, 0), (0, 1, 0))


def edge_seam(u_b: float = 0.0, v_scale: float = 1.0) -> SeamSpec:
    """30 samples along panel a's side u1 sewn to panel b's line u = u_b (its side u0 by
    default), b's v scaled by v_scale (< 1: b's side is shorter, the seam eased)."""
    t = np.linspace(0.0, N - 2.0, 30)
    return SeamSpec("a", np.c_[np.full(30, N - 2.0), t], "b", np.c_[np.full(30, u_b), v_scale * t])


def two_panels(gap: float, stiffness: float = 1e6, contact=None) -> Simulator:
    """Two 0.2 m cotton panels side by side, `gap` m apart, sewn along their facing sides,
    with contact (adaptive kappa) and gravity."""
    a = panel("a", (-0.2 - gap / 2, -0.1, 0.0))
    b = panel("b", (gap / 2, -0.1, 0.0))
    return Simulator(bspline_model([a, b], [PRESETS["cotton"]] * 2, gravity=(0.0, 0.0, -9.81), dt=0.01,
                     contact=contact or ContactOptions(adaptive_kappa=True), seams=[edge_seam()],
                     seam_stiffness=stiffness))
