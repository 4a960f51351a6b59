"""Off-screen PyVista renders of simulated frames: PNG folders, MP4 and GIF videos.

No display needed: VTK draws through OSMesa (`libosmesa6`), selected by the environment
variable below before VTK is first imported. Cloth is smooth-shaded from area-weighted
vertex normals, its two sides in different colours; bodies are grey. The camera looks at
the bounding box of the whole run (so nothing leaves the picture), either fixed or
orbiting once around the vertical axis over the video.

    frames = FrameBuffer(); sim.run(..., sinks=[frames])      # or viz.recording.Recording
    render(frames.meshes, frames.frames(), "out.mp4", RenderOptions(size=(800, 600)))
"""

from __future__ import annotations

import os

# Must be set before vtk is imported anywhere; setdefault keeps a user's choice.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")

import contextlib  # noqa: E402
import math  # noqa: E402
from collections.abc import Callable, Iterable, Iterator  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from sim.files import atomic_write  # noqa: E402
from sim.sinks import Frame, MeshTopology  # noqa: E402

from .rerun_sink import normals_operator, vertex_normals  # noqa: E402

VIDEO_SUFFIXES = (".mp4", ".gif")
CLOTH_FRONT = (0.42, 0.62, 0.90)  # RGB in [0, 1]
CLOTH_BACK = (0.95, 0.62, 0.38)
BODY = (0.78, 0.78, 0.76)
BACKGROUND = (1.0, 1.0, 1.0)
# Phong interpolation of our vertex normals = smooth shading; some ambient light keeps
# faces turned away from the key light readable.
SHADING = {"interpolation": "phong", "ambient": 0.25, "diffuse": 0.8, "specular": 0.15, "specular_power": 20.0}

# (frame index, time in s, mesh name -> (V, 3) positions in m)
FrameData = tuple[int, float, dict[str, np.ndarray]]


@dataclass
class RenderOptions:
    """size: (width, height) in pixels (rounded up to even numbers for H.264).
    fps: frames per second of a video. orbit: turn the camera once around the vertical
    axis over the video instead of keeping it fixed. azimuth / elevation: view direction
    in degrees (azimuth from +x towards +y when z is up; the camera goes to the side the
    cloth's front faces). zoom: > 1 moves closer. up: the scene's vertical (None: +z;
    `garment simulate` passes the direction against gravity, so Y-up scenes stand).
    follow: aim at each frame's own centre (smoothed over FOLLOW_SMOOTH seconds) at the
    distance that fits the largest single frame, instead of framing the whole path (a
    dancer who travels stays large in the picture)."""

    size: tuple[int, int] = (640, 480)
    fps: float = 30.0
    orbit: bool = False
    azimuth: float = -60.0
    elevation: float = 20.0
    zoom: float = 1.0
    up: tuple[float, float, float] | None = None
    follow: bool = False


FOLLOW_SMOOTH = 0.5  # s: the follow camera's moving-average window (no jitter from steps)


def follow_path(frames: list[FrameData], fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The follow camera: (K, 3) smoothed centre of each frame's box and the (2, 3) box,
    centred on the origin, that holds every frame around its centre."""
    boxes = np.array([scene_bounds([f]) for f in frames])  # (K, 2, 3)
    centres = boxes.mean(axis=1)
    half = max(1, int(round(0.5 * FOLLOW_SMOOTH * fps)))
    padded = np.concatenate([np.repeat(centres[:1], half, 0), centres, np.repeat(centres[-1:], half, 0)])
    kernel = np.ones(2 * half + 1) / (2 * half + 1)
    smooth = np.stack([np.convolve(padded[:, d], kernel, mode="valid") for d in range(3)], axis=1)
    extent = np.maximum(np.abs(boxes[:, 0] - smooth), np.abs(boxes[:, 1] - smooth)).max(axis=0)
    return smooth, np.array([-extent, extent])


def parse_size(text: str) -> tuple[int, int]:
    """'640x480' -> (640, 480); raises ValueError on anything else."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"size must look like 640x480, got {text!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise ValueError(f"size must be between 16x16 and 8192x8192, got {text!r}")
    return w, h


def output_kind(out: str | os.PathLike) -> str:
    """'mp4', 'gif' or 'png' (a folder of PNG frames: any path without a video suffix)."""
    suffix = Path(out).suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return suffix[1:]
    if suffix and not Path(out).is_dir():
        raise ValueError(f"{out}: render output must be .mp4, .gif or a folder for PNG frames")
    return "png"


class FrameBuffer:
    """Sink that keeps every frame in memory as float32 (V, 3) positions, for rendering
    after the run (when the camera can frame the whole motion). About 12 bytes per
    vertex and frame: 48 MB for 200 frames of a 20K-vertex mesh."""

    def __init__(self):
        self.meshes: list[MeshTopology] = []
        self._frames: list[FrameData] = []

    @staticmethod
    def bytes_for(frames: int, vertices: int) -> float:
        """Memory the buffer takes for `frames` frames of `vertices` vertices in all."""
        return 12.0 * frames * vertices

    def open(self, meshes: list[MeshTopology]) -> None:
        self.meshes = list(meshes)
        self._frames = []

    def write(self, frame: Frame) -> None:
        self._frames.append((frame.index, frame.time,
                             {k: np.asarray(v, dtype=np.float32) for k, v in frame.positions.items()}))

    def close(self) -> None:
        pass

    def __len__(self) -> int:
        return len(self._frames)

    def frames(self) -> list[FrameData]:
        return list(self._frames)


def scene_bounds(frames: Iterable[FrameData]) -> np.ndarray:
    """(2, 3) min and max corner in m over every vertex of every frame."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for _, _, positions in frames:
        for x in positions.values():
            if len(x):
                lo, hi = np.minimum(lo, x.min(axis=0)), np.maximum(hi, x.max(axis=0))
    if not np.all(np.isfinite(lo)):
        return np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
    return np.array([lo, hi])


def _direction(azimuth: float, elevation: float, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Unit view direction; azimuth turns about `up` from the horizontal axis nearest +x
    (towards +y when up is +z)."""
    a, e = math.radians(azimuth), math.radians(elevation)
    e1, e2, u = _horizontal_basis(up)
    return math.cos(e) * (math.cos(a) * e1 + math.sin(a) * e2) + math.sin(e) * u


def _horizontal_basis(up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed orthonormal (e1, e2, up): e1 the horizontal direction nearest +x."""
    u = np.asarray(up, float) / np.linalg.norm(up)
    ref = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - (ref @ u) * u
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1), u


class SceneRenderer:
    """An off-screen PyVista plotter holding one actor per mesh; `image(positions)` moves
    the vertices and returns the picture as (H, W, 3) uint8."""

    VIEW_ANGLE = 30.0  # degrees, VTK's default vertical field of view

    def __init__(self, meshes: list[MeshTopology], bounds: np.ndarray, options: RenderOptions,
                 first: dict[str, np.ndarray] | None = None):
        import pyvista as pv

        self.options = options
        self.up = _horizontal_basis(options.up if options.up is not None else (0.0, 0.0, 1.0))[2]
        w, h = options.size
        self.size = (w + w % 2, h + h % 2)  # libx264/yuv420p needs even sides
        self.plotter = pv.Plotter(off_screen=True, window_size=self.size)
        self.plotter.set_background(BACKGROUND)
        self.polys: dict[str, pv.PolyData] = {}
        self._faces: dict[str, np.ndarray] = {}
        self._incidence = {}
        for m in meshes:
            faces = np.asarray(m.faces, dtype=np.int64)
            x0 = first.get(m.name) if first else None
            n = len(x0) if x0 is not None else int(faces.max(initial=-1)) + 1
            poly = pv.PolyData(np.zeros((n, 3)) if x0 is None else np.asarray(x0, float),
                               np.column_stack([np.full(len(faces), 3), faces]).ravel())
            self.polys[m.name], self._faces[m.name] = poly, faces
            self._incidence[m.name] = normals_operator(faces, n)
            if m.kind == "cloth":
                self.plotter.add_mesh(poly, color=CLOTH_FRONT, backface_params={"color": CLOTH_BACK}, **SHADING)
            else:
                self.plotter.add_mesh(poly, color=BODY, **SHADING)
        self.center = bounds.mean(axis=0)
        self.corners = np.array([[bounds[i, 0], bounds[j, 1], bounds[k, 2]]
                                 for i in (0, 1) for j in (0, 1) for k in (0, 1)]) - self.center
        self.azimuth = options.azimuth
        if first:
            self.azimuth = self._facing_azimuth(meshes, first)
        turns = np.linspace(0.0, 1.0, 36, endpoint=False) if options.orbit else [0.0]
        # One distance for the whole video, so an orbit does not zoom in and out.
        self.distance = max(self._fit_distance(t) for t in turns) / options.zoom

    def _facing_azimuth(self, meshes, first) -> float:
        """The requested azimuth, mirrored when the cloth's front faces away from it."""
        total = np.zeros(3)
        for m in meshes:
            if m.kind == "cloth" and m.name in first:
                tri = np.asarray(first[m.name], float)[np.asarray(m.faces)]
                total += np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(axis=0)
        d = _direction(self.options.azimuth, 0.0, self.up)
        horizontal = total - (total @ self.up) * self.up
        return self.options.azimuth + 180.0 if horizontal @ d < 0 else self.options.azimuth

    def _fit_distance(self, turn: float, margin: float = 1.08) -> float:
        """Camera distance (m) from the box centre at which all 8 corners of the scene's
        bounding box are inside the field of view, looking from `turn` of an orbit."""
        d, right, up = self._frame(turn)
        w, h = self.size
        tan_v = math.tan(math.radians(self.VIEW_ANGLE / 2))
        tan_h = tan_v * w / h
        q = self.corners
        # A corner at depth (D - q.d) in front of the camera must satisfy |q.up| <= depth tan_v.
        need = q @ d + np.maximum(np.abs(q @ up) / tan_v, np.abs(q @ right) / tan_h)
        return margin * max(float(need.max()), 1e-3)

    def _frame(self, turn: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors: towards the camera, screen right, screen up."""
        # Clamped: looking straight down leaves "screen right" undefined.
        d = _direction(self.azimuth + 360.0 * turn, float(np.clip(self.options.elevation, -89.0, 89.0)), self.up)
        right = np.cross(self.up, d)
        right /= np.linalg.norm(right)
        return d, right, np.cross(d, right)

    def set_camera(self, turn: float = 0.0) -> None:
        """Camera at the fitting distance, `up` up; `turn` in [0, 1) of a full orbit."""
        d = self._frame(turn)[0]
        cam = self.plotter.camera
        cam.focal_point = tuple(self.center)
        cam.position = tuple(self.center + self.distance * d)
        cam.up = tuple(self.up)
        cam.view_angle = self.VIEW_ANGLE
        self.plotter.reset_camera_clipping_range()

    def image(self, positions: dict[str, np.ndarray], turn: float = 0.0) -> np.ndarray:
        """Render one frame: positions (V, 3) in m per mesh name -> (H, W, 3) uint8."""
        for name, x in positions.items():
            poly = self.polys.get(name)
            if poly is None:
                continue
            x = np.asarray(x, dtype=np.float64)
            poly.points = x
            poly.point_data["Normals"] = vertex_normals(x, self._faces[name], self._incidence[name])
            poly.point_data.active_normals_name = "Normals"
        self.set_camera(turn)
        self.plotter.render()
        return np.asarray(self.plotter.screenshot(None, return_img=True))[..., :3]

    def close(self) -> None:
        self.plotter.close()


class _PngWriter:
    """One PNG per frame, each written whole (sim.files.atomic_write)."""

    def __init__(self, directory: Path):
        self.directory = directory
        directory.mkdir(parents=True, exist_ok=True)

    def write(self, index: int, image: np.ndarray) -> None:
        import imageio.v2 as iio

        with atomic_write(self.directory / f"frame_{index:05d}.png", keep_suffix=True) as tmp:
            iio.imwrite(tmp, image)


class _VideoWriter:
    """MP4 (H.264 through imageio-ffmpeg) or GIF (Pillow) at `path` (render() hands it a
    temporary name, renamed when the video is complete)."""

    def __init__(self, path: Path, fps: float):
        import imageio.v2 as iio

        if path.suffix.lower() == ".mp4":
            # macro_block_size=2: keep the exact (even) size instead of padding to 16.
            self.writer = iio.get_writer(path, fps=fps, codec="libx264", quality=8,
                                         pixelformat="yuv420p", macro_block_size=2)
        else:
            self.writer = iio.get_writer(path, mode="I", duration=1000.0 / fps, loop=0)

    def write(self, index: int, image: np.ndarray) -> None:
        self.writer.append_data(image)

    def close(self) -> None:
        self.writer.close()


def render(
    meshes: list[MeshTopology],
    frames: Iterable[FrameData] | list[FrameData],
    out: str | os.PathLike,
    options: RenderOptions | None = None,
    on_frame: Callable[[int], None] | None = None,
    bounds: np.ndarray | None = None,
) -> Path:
    """Render `frames` to `out` (.mp4, .gif, or a folder of `frame_<index>.png`).

    frames: (index, time s, name -> (V, 3) positions m), a list (or a re-iterable) since
    the camera needs the bounds of all frames unless `bounds` (2, 3) is given.
    on_frame(k) is called after the k-th image is written (for progress bars).
    """
    options = options or RenderOptions()
    out = Path(out)
    kind = output_kind(out)
    frames = frames if isinstance(frames, list) else list(frames)
    if not frames:
        raise ValueError("no frames to render")
    centres = None
    if options.follow:
        centres, bounds = follow_path(frames, options.fps)
    elif bounds is None:
        bounds = scene_bounds(frames)
    with contextlib.ExitStack() as stack:  # unwinds in reverse: writer, file, renderer
        renderer = SceneRenderer(meshes, bounds, options, first=frames[0][2])
        stack.callback(renderer.close)
        if kind == "png":
            writer = _PngWriter(out)
        else:  # renamed into place when complete, removed when failed or interrupted half way
            writer = _VideoWriter(stack.enter_context(atomic_write(out, keep_suffix=True)), options.fps)
            stack.callback(writer.close)
        for k, (index, _, positions) in enumerate(frames):
            turn = k / len(frames) if options.orbit else 0.0
            if centres is not None:
                renderer.center = centres[k]
            writer.write(index, renderer.image(positions, turn))
            if on_frame is not None:
                on_frame(k)
    return out


def recording_frames(recording) -> Iterator[FrameData]:
    """(index, time, positions) of every intact frame of a `viz.recording.Recording`."""
    for k in recording.frames:
        yield k, recording.time_of(k), {name: recording.positions_at(name, k) for name in recording.meshes}


def recording_meshes(recording) -> list[MeshTopology]:
    """MeshTopology (faces and kind only) of every mesh of a `viz.recording.Recording`."""
    empty = np.zeros((0, 2))
    return [MeshTopology(name, recording.faces(name), empty, empty, m.kind) for name, m in recording.meshes.items()]
