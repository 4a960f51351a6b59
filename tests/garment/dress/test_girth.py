"""Openings and trunk girths (garment/dress/girth.py): why a garment slid off, against
polygons whose perimeters are known exactly."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from garment.dress.girth import boundary_loops, loop_length, loose_opening, trunk_girth, widest_trunk

N = 48  # sides of every polygon below


def polygon(r: float) -> float:
    """Perimeter of the regular N-gon of circumradius r."""
    return 2 * N * r * np.sin(np.pi / N)


def tube(r: float, z0: float, z1: float, rings: int = 5):
    """An open cylinder (no caps) round the z axis: two boundary loops of N vertices."""
    a = 2 * np.pi * np.arange(N) / N
    X = np.concatenate([np.c_[r * np.cos(a), r * np.sin(a), np.full(N, z)] for z in np.linspace(z0, z1, rings)])
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(N), indexing="ij")
    p, q = (i * N + j).ravel(), (i * N + (j + 1) % N).ravel()
    T = np.concatenate([np.c_[p, q, p + N], np.c_[q, q + N, p + N]])
    return X, T


def body():
    """A solid of revolution 1.72 m tall, widest (r = 0.17 m) at 0.85 m, with an arm (a
    thin cylinder) hanging beside it."""
    profile = [[0.0, 0.0], [0.10, 0.0], [0.17, 0.85], [0.12, 1.05], [0.15, 1.30], [0.05, 1.72], [0.0, 1.72]]
    trunk = trimesh.creation.revolve(profile, sections=N)
    arm = trimesh.creation.cylinder(radius=0.04, height=0.7, sections=N)
    arm.apply_translation([0.25, 0.0, 1.0])
    both = trimesh.util.concatenate([trunk, arm])
    return np.asarray(both.vertices), np.asarray(both.faces)


def test_an_open_tube_has_two_loops_of_its_perimeter():
    X, T = tube(0.25, 0.7, 1.0)
    loops = boundary_loops(X, T)
    assert len(loops) == 2 and sorted(len(loop) for loop in loops) == [N, N]
    for loop in loops:
        assert loop_length(X, loop) == pytest.approx(polygon(0.25), rel=1e-12)


def test_the_trunk_girth_is_the_loop_round_the_centre_not_the_arm():
    V, F = body()
    # At 1.05 m the profile's radius is 0.12 m exactly; the arm's loop beside it is left out.
    assert trunk_girth(V, F, 1.05, np.zeros(2)) == pytest.approx(polygon(0.12), rel=1e-9)
    assert trunk_girth(V, F, 1.05, np.array([0.5, 0.0])) is None  # nothing encloses a point outside
    girth, height = widest_trunk(V, F)
    assert girth == pytest.approx(polygon(0.17), rel=0.02) and abs(height - 0.85) < 0.03


def test_an_opening_wider_than_the_trunk_anywhere_is_found():
    V, F = body()
    X, T = tube(0.25, 0.7, 1.0)  # 157 cm round, the trunk at most 107 cm
    found = loose_opening(X, T, V, F)
    assert found is not None
    loop, length, girth, _ = found
    assert X[loop, 2].mean() == pytest.approx(1.0) and length == pytest.approx(polygon(0.25))
    assert girth < length
    assert loose_opening(*tube(0.15, 0.7, 1.0), V, F) is None  # 94 cm: the hips hold it


def test_an_opening_above_the_trunk_rests_on_the_shoulders_however_wide():
    V, F = body()
    # 1.30 m is 76 % of the 1.72 m body: a neckline there hangs on shoulders and arms.
    assert loose_opening(*tube(0.30, 1.0, 1.30), V, F) is None


def test_only_the_trunk_below_an_opening_can_hold_it():
    V, F = body()
    # At 0.80 m the trunk below (from 0.77 m, 45 % of the height) is at most r = 0.165 m
    # round, narrower than the widest (0.17 m at 0.85 m) above it.
    found = loose_opening(*tube(0.167, 0.5, 0.80), V, F)
    assert found is not None and found[2] < polygon(0.167) < polygon(0.17)
