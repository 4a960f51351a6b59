"""Starting shapes of garments: the least-squares lift of a curved placement, placement
files (a sewn drape in the source mesh's vertex order) and bodies that grow out of an
inset during the pre-roll."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import trimesh

from conform.lift import lift
from conform.pipeline import ConformOptions, conform_panel
from sim.errors import InputError
from garment.io.garments import load_garment
from garment.io.obstacles import ObstacleGeometry
from sim.patches import Panel
from garment.scene import GarmentSpec, PlacementSpec, parse_scene
from sim.embedding import interpolation_matrix

from tests.support.panels import grid
from tests.support.paths import ASSETS


def _grid_panel(a: float, b: float, k: int, world) -> Panel:
    """An a x b rectangle meshed with (k+1)^2 vertices, placed by world(rest) -> (V, 3)."""
    rest, faces = grid(k + 1, k + 1, (a, b))
    return Panel(name="p", source="test", rest=rest, faces=faces, world=world(rest), vertex_ids=np.arange(len(rest)))


def _cylinder(radius):
    return lambda r: np.c_[radius * np.sin(r[:, 0] / radius), r[:, 1], radius * np.cos(r[:, 0] / radius)]


def _surface_radius_error(panel, X, C, radius):
    n, m = X.shape[:2]
    u, v = np.meshgrid(np.linspace(0, n - 2, 41), np.linspace(0, m - 2, 41), indexing="ij")
    N = interpolation_matrix(u.ravel(), v.ravel(), n, m, 0, n * m)
    P = N @ C.reshape(-1, 3)
    return np.abs(np.hypot(P[:, 0], P[:, 2]) - radius).max()


def test_lift_fits_the_surface_of_a_curved_placement_not_the_control_net():
    radius = 0.06  # an arm: 40 mm spans around it
    panel = _grid_panel(0.3, 0.2, 60, _cylinder(radius))
    X = conform_panel(panel, ConformOptions(knot_span=0.04))[0].rest
    C = lift(panel, X)
    err = _surface_radius_error(panel, X, C, radius)
    # Interpolating the control net instead sinks the surface by about h^2 / (8 R).
    control_net_error = _surface_radius_error(panel, X, _cylinder(radius)(X.reshape(-1, 2)), radius)
    assert control_net_error > 1e-3
    assert err < 0.2 * control_net_error and err < 5e-4  # 0.37 mm vs 2.9 mm


def test_lift_of_a_flat_placement_is_exact():
    angle = 0.3
    R = np.array([[np.cos(angle), 0.0, np.sin(angle)], [0.0, 1.0, 0.0]])
    panel = _grid_panel(0.3, 0.2, 12, lambda r: r @ R + np.array([0.1, -0.2, 0.5]))
    X = conform_panel(panel, ConformOptions(knot_span=0.05))[0].rest
    C = lift(panel, X)
    np.testing.assert_allclose(C.reshape(-1, 3), X.reshape(-1, 2) @ R + np.array([0.1, -0.2, 0.5]), atol=1e-12)


def _obj(path: Path, V: np.ndarray) -> Path:
    path.write_text("".join(f"v {x:.9f} {y:.9f} {z:.9f}\n" for x, y, z in V))
    return path


PANELS = ASSETS / "garments" / "dress_knife.obj"


def _source_vertices() -> np.ndarray:
    with open(PANELS) as f:
        return np.asarray([line.split()[1:4] for line in f if line.startswith("v ")], float)


def test_placement_file_replaces_the_layout(tmp_path):
    V = _source_vertices()
    shift = np.array([0.01, -0.02, 0.03])
    # Y-up file: z -> y, -y -> z, so that the simulator's Z-up frame gets V + shift back.
    Vy = np.c_[V[:, 0], V[:, 2], -V[:, 1]]
    spec = GarmentSpec("dress", PANELS, knot_span=0.06,
                       placement=PlacementSpec(_obj(tmp_path / "drape.obj", Vy), up="y", translate=tuple(shift)))
    moved = load_garment(spec)
    plain = load_garment(dataclasses.replace(spec, placement=None))
    for a, b in zip(moved.patches, plain.patches):
        np.testing.assert_allclose(a.world, b.world + shift, atol=1e-6)  # file precision 1e-9 m


def test_placement_errors_name_the_file(tmp_path):
    V = _source_vertices()
    short = _obj(tmp_path / "short.obj", V[:100])
    with pytest.raises(InputError, match="short.obj.*100 vertices"):
        load_garment(GarmentSpec("dress", PANELS, knot_span=0.06, placement=PlacementSpec(short)))
    scaled = _obj(tmp_path / "cm.obj", 100.0 * V)
    with pytest.raises(InputError, match="cm.obj.*rest length"):
        load_garment(GarmentSpec("dress", PANELS, knot_span=0.06, placement=PlacementSpec(scaled)))
    doc = {"garment": [{"source": str(PANELS), "placement": {"file": str(tmp_path / "missing.obj")}}]}
    with pytest.raises(InputError, match="garment.*placement.*missing.obj"):
        parse_scene(doc, "dress.toml")
    doc = {"garment": [{"source": str(PANELS)}], "obstacle": [{"sphere": {"radius": 0.1}, "inset": 0.002}]}
    with pytest.raises(InputError, match="inset.*preroll"):
        parse_scene(doc, "dress.toml")


def test_inset_body_grows_to_its_pose_over_the_second_half_of_the_preroll():
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    body = ObstacleGeometry("ball", np.asarray(m.vertices), np.asarray(m.faces, np.int32),
                            delay=0.2, inset=0.004, grow=(0.1, 0.2))
    r = lambda t: np.linalg.norm(body.at(t), axis=1)  # noqa: E731
    np.testing.assert_allclose(r(0.0), 0.1 - 0.004, rtol=1e-3)  # vertex normals of an icosphere are radial
    np.testing.assert_allclose(r(0.1), 0.1 - 0.004, rtol=1e-3)
    np.testing.assert_allclose(r(0.15), 0.1 - 0.002, rtol=1e-3)
    np.testing.assert_allclose(r(0.2), 0.1, rtol=1e-12)
    assert body.animated


def test_inset_stops_short_of_turning_thin_parts_inside_out():
    m = trimesh.creation.box(extents=(0.3, 0.3, 0.01)).subdivide().subdivide()  # a 1 cm slab
    body = ObstacleGeometry("slab", np.asarray(m.vertices), np.asarray(m.faces, np.int32), inset=0.03, grow=(0.1, 0.2))
    z = np.abs(body.at(0.0)[:, 2])
    top = np.abs(m.vertices[:, 2]) > 0.004
    inner = top & (np.abs(m.vertices[:, :2]).max(axis=1) < 0.1)  # away from the rims
    assert z[inner].min() > 0.005 - 0.4 * 0.01 - 1e-9  # at most 0.4 x the 1 cm thickness
    assert z[inner].max() < 0.005  # ...but moved in
