"""Off-screen PyVista renders: images are not empty, the camera frames the scene, and
PNG folders, MP4 and GIF come out with one image per frame."""

from __future__ import annotations

import imageio.v2 as iio
import numpy as np
import pytest

from garment.cli import main
from sim.embedding import grid_faces
from sim.sinks import MeshTopology
from viz.render import BACKGROUND, RenderOptions, output_kind, parse_size, render, scene_bounds

from tests.support.scenes import HANGING_SHEET

SIZE = (160, 120)
EMPTY = np.zeros((0, 2))


def wavy_scene(n_frames: int = 3):
    """A 20 x 20 vertex cloth with a travelling wave over a small box-shaped body."""
    a = 20
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, a), np.linspace(-0.5, 0.5, a), indexing="ij")
    cloth = MeshTopology("sheet", grid_faces(a, a), EMPTY, EMPTY)
    box_x = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (0.0, 0.2)])
    box_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    body = MeshTopology("box", box_f, EMPTY, EMPTY, kind="body")
    frames = []
    for k in range(n_frames):
        z = 0.3 + 0.1 * np.sin(6 * u + 0.8 * k) * np.cos(4 * v)
        frames.append((k, 0.1 * k, {"sheet": np.column_stack([u.ravel(), v.ravel(), z.ravel()]), "box": box_x}))
    return [cloth, body], frames


def foreground(img: np.ndarray) -> np.ndarray:
    """Pixels that differ from the background colour."""
    bg = np.round(np.array(BACKGROUND) * 255).astype(int)
    return np.abs(img.astype(int) - bg).sum(axis=-1) > 30


def test_png_frames_are_not_empty(tmp_path):
    meshes, frames = wavy_scene()
    out = render(meshes, frames, tmp_path / "png", RenderOptions(size=SIZE))
    files = sorted(out.iterdir())
    assert [f.name for f in files] == [f"frame_{k:05d}.png" for k in range(3)]
    for f in files:
        img = iio.imread(f)
        assert img.shape == (SIZE[1], SIZE[0], 3)
        fg = foreground(img)
        assert 0.05 < fg.mean() < 0.9, "the scene should fill a good part of the picture"
        assert img[fg].std() > 5, "smooth shading gives a range of tones, not one flat colour"
        # The camera frames the scene: nothing touches the image border.
        assert not (fg[0].any() or fg[-1].any() or fg[:, 0].any() or fg[:, -1].any())
    # Successive frames differ (the wave moves).
    assert np.abs(iio.imread(files[0]).astype(int) - iio.imread(files[2])).mean() > 0.5


def test_orbit_moves_the_camera(tmp_path):
    meshes, frames = wavy_scene(1)
    still = [(k, 0.1 * k, frames[0][2]) for k in range(4)]
    render(meshes, still, tmp_path / "png", RenderOptions(size=SIZE, orbit=True))
    a, b = (iio.imread(tmp_path / "png" / f"frame_{k:05d}.png").astype(int) for k in (0, 2))
    assert np.abs(a - b).mean() > 1.0


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_videos(tmp_path, suffix):
    meshes, frames = wavy_scene(4)
    out = render(meshes, frames, tmp_path / f"v{suffix}", RenderOptions(size=SIZE, fps=10))
    images = [im for im in iio.get_reader(out)]  # list() asks len(), infinite for ffmpeg
    assert len(images) == 4
    assert images[0].shape[:2] == (SIZE[1], SIZE[0])
    assert foreground(np.asarray(images[-1])[..., :3]).mean() > 0.05
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary files left


def test_output_kinds_and_sizes(tmp_path):
    assert output_kind("a.mp4") == "mp4" and output_kind("b.GIF") == "gif" and output_kind(tmp_path / "dir") == "png"
    with pytest.raises(ValueError):
        output_kind("a.avi")
    assert parse_size("640x480") == (640, 480)
    for bad in ("640", "0x480", "axb"):
        with pytest.raises(ValueError):
            parse_size(bad)
    bounds = scene_bounds(wavy_scene(2)[1])
    assert bounds.shape == (2, 3) and np.all(bounds[1] > bounds[0])


def test_simulate_render_cli(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(HANGING_SHEET)
    gif = tmp_path / "run.gif"
    assert main(["simulate", str(scene), "--render", str(gif), "--render-size", "96x72", "-q"]) == 0
    assert len([im for im in iio.get_reader(gif)]) == 5  # initial frame + 4
    assert main(["simulate", str(scene), "--render", str(tmp_path / "x.avi"), "-q"]) == 2
    assert "x.avi" in capsys.readouterr().err
    assert main(["simulate", str(scene), "--render", str(gif), "--render-size", "big", "-q"]) == 2


def test_inspect_render_cli(tmp_path):
    scene = tmp_path / "small.toml"
    scene.write_text(HANGING_SHEET)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "-q"]) == 0
    assert main(["inspect", str(rrd), "--render", str(tmp_path / "frames"), "--render-size", "96x72", "-q"]) == 0
    pngs = sorted((tmp_path / "frames").iterdir())
    assert len(pngs) == 5 and foreground(iio.imread(pngs[-1])).mean() > 0.05


def test_up_axis_stands_a_y_up_scene_upright(tmp_path):
    """A tall thin post along +y: upright (taller than wide) with up = y, lying with z up."""
    post_x = np.array([[x, y, z] for x in (-0.05, 0.05) for y in (0.0, 1.0) for z in (-0.05, 0.05)])
    post_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    meshes = [MeshTopology("post", post_f, EMPTY, EMPTY, kind="body")]
    frames = [(0, 0.0, {"post": post_x})]
    aspect = {}
    for up in ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        out = tmp_path / f"up{up[1]:.0f}"
        render(meshes, frames, out, RenderOptions(size=SIZE, up=up))
        rows, cols = np.nonzero(foreground(iio.imread(next(out.iterdir()))[..., :3]))
        aspect[up[1]] = (np.ptp(rows) + 1) / (np.ptp(cols) + 1)
    assert aspect[1.0] > 3.0 and aspect[0.0] < 1.0


def test_the_follow_camera_keeps_a_travelling_scene_large(tmp_path):
    """The scene moves 4 m sideways over the clip: framed whole it shrinks to a sliver,
    followed it keeps the size of a single frame (its centre tracked, smoothed)."""
    from viz.render import follow_path

    meshes, frames = wavy_scene(25)
    frames = [(k, t, {n: x + [0.16 * k, 0.0, 0.0] for n, x in pos.items()}) for k, t, pos in frames]
    centres, box = follow_path(frames, fps=25.0)
    own = scene_bounds(frames[:1])
    # Every frame fits the followed box around its own (smoothed) centre, and the box is
    # a frame's size plus the smoothing lag (0.5 s at 4 m/s: < 0.6 m), not the 4 m path.
    for (_, _, pos), c in zip(frames, centres):
        b = scene_bounds([(0, 0.0, pos)])
        assert np.all(b[0] >= c + box[0] - 1e-12) and np.all(b[1] <= c + box[1] + 1e-12)
    assert box[1, 0] - (own[1, 0] - own[0, 0]) / 2 < 0.6
    assert np.ptp(centres[:, 0]) > 3.0
    fixed = iio.imread(render(meshes, frames[-1:], tmp_path / "a",
                              RenderOptions(size=SIZE), bounds=scene_bounds(frames)) / "frame_00024.png")
    followed = iio.imread(render(meshes, frames, tmp_path / "b", RenderOptions(size=SIZE, follow=True))
                          / "frame_00024.png")
    assert foreground(followed).sum() > 3 * foreground(fixed).sum()
