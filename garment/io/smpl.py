"""SMPL-family bodies (SMPL, SMPL-H, SMPL-X) posed by AMASS-style motions, in numpy.

Model file (the user's own: no SMPL file ships with the toolkit), .npz or the official
.pkl, with `v_template` (V, 3), `shapedirs` (V, 3, B), `posedirs` (V, 3, 9 (J - 1)) or
(3 V, 9 (J - 1)), `J_regressor` (J, V) (dense, or scipy sparse in a .pkl), `weights`
(V, J), `kintree_table` (2, J) (row 0: parents) and `f` (F, 3). Metres, Y-up, rest pose a
T-pose; J = 24 (SMPL), 52 (SMPL-H), 55 (SMPL-X).

Motion (.npz): `poses` (T, >= 3 J) axis-angle per joint (root first; the first 3 J
columns are used), `trans` (T, 3) m, `betas` (B,), `mocap_framerate` (or
`mocap_frame_rate`) in 1/s. AMASS motions are Z-up: their root rotation stands the
Y-up model upright.

The body: shaped vertices v_s = v_template + shapedirs . betas, joints J_regressor v_s;
pose correctives posedirs . (R_j - I) over the non-root joints' local rotations; then
linear blend skinning (garment/io/skinning.py) with the root at joint 0 + trans.

A .pkl is unpickled with a restricted Unpickler: numpy arrays, scipy sparse matrices
(read from their stored arrays, no scipy code runs) and chumpy arrays (their stored
value `x`); anything else is refused, so a model file cannot run code.
"""

from __future__ import annotations

import copyreg
import io
import pickle
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.budget import require_memory
from sim.errors import InputError, printable
from sim.files import input_file

from .bodies import to_scene_frame
from .rotations import axis_angle_matrix, matrix_quaternion, quaternion_matrix, slerp
from .skinning import PoseTrack, Rig, padded_weights

MODEL_KEYS = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f")
MAX_JOINTS = 200
MAX_FPS = 1000.0
# Scene axes of the model's (and a Y-up motion's) axes: the obstacle convention's +90 deg about X.
UP = {"y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]), "z": np.eye(3)}


@dataclass
class SmplModel:
    """A checked model: arrays as in the module docstring, parents (J,) from kintree_table,
    posedirs (3 V, P), J_regressor dense (J, V)."""

    path: Path
    v_template: np.ndarray
    shapedirs: np.ndarray
    posedirs: np.ndarray
    J_regressor: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    faces: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.parents)

    def shaped(self, betas: np.ndarray) -> np.ndarray:
        """(V, 3) vertices of the rest pose with shape coefficients `betas` (the first
        len(betas) shape directions)."""
        b = np.asarray(betas, float)[: self.shapedirs.shape[2]]
        return self.v_template + self.shapedirs[:, :, : len(b)] @ b

    def joints(self, shaped: np.ndarray) -> np.ndarray:
        """(J, 3) rest joints regressed from shaped vertices."""
        return self.J_regressor @ shaped

    def correctives(self, local: np.ndarray) -> np.ndarray:
        """(V, 3) pose blend shapes of local joint rotations (J, 3, 3) (model frame)."""
        feature = (local[1:] - np.eye(3)).reshape(-1)
        return (self.posedirs @ feature).reshape(-1, 3)

    def rig(self, betas: np.ndarray, scale: float = 1.0, translate=(0.0, 0.0, 0.0)) -> Rig:
        """The shaped model as a Rig in the scene frame (Y-up model turned Z-up)."""
        shaped = self.shaped(betas)
        joints = self.joints(shaped)
        V, J = self.weights.shape
        vertex, joint = np.nonzero(self.weights > 0.0)
        index, w, unweighted = padded_weights(vertex, joint, self.weights[vertex, joint], V)
        if len(unweighted):
            raise InputError(f"{self.path}: weights: vertex {int(unweighted[0])} has no weight "
                             f"({len(unweighted)} such vertices)")
        U = UP["y"]

        def correctives(world: np.ndarray) -> np.ndarray:
            # Local rotations of the model frame from the scene-frame world rotations.
            local = np.empty_like(world)
            local[0] = world[0]
            local[1:] = np.swapaxes(world[self.parents[1:]], 1, 2) @ world[1:]
            return scale * self.correctives(U.T @ local @ U) @ U.T

        return Rig([f"joint{j}" for j in range(J)], self.parents.copy(),
                   to_scene_frame(joints, scale, "y", translate), to_scene_frame(shaped, scale, "y", translate),
                   self.faces, index, w, None, correctives)


@dataclass
class SmplMotion:
    """poses (T, 3 J) axis-angle (already cut to the model's joints), trans (T, 3) m,
    betas (B,), fps in 1/s."""

    path: Path
    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    fps: float

    @property
    def duration(self) -> float:
        return (len(self.poses) - 1) / self.fps

    def local_rotations(self, times: np.ndarray) -> np.ndarray:
        """(n, J, 3, 3) local rotations at `times` (s), slerped between frames."""
        i0, i1, w = _brackets(times, self.fps, len(self.poses))
        J = self.poses.shape[1] // 3
        q0 = matrix_quaternion(axis_angle_matrix(self.poses[i0].reshape(-1, J, 3)))
        q1 = matrix_quaternion(axis_angle_matrix(self.poses[i1].reshape(-1, J, 3)))
        return quaternion_matrix(slerp(q0, q1, np.broadcast_to(w[:, None], (len(w), J))))

    def translation(self, times: np.ndarray) -> np.ndarray:
        i0, i1, w = _brackets(times, self.fps, len(self.poses))
        return (1.0 - w)[:, None] * self.trans[i0] + w[:, None] * self.trans[i1]


def _brackets(times, fps: float, n: int):
    s = np.clip(np.asarray(times, float) * fps, 0.0, n - 1)
    i0 = np.minimum(np.floor(s).astype(int), n - 1)
    return i0, np.minimum(i0 + 1, n - 1), s - i0


def up_axis(motion: SmplMotion, time: float) -> str:
    """The motion's up axis ("y" or "z") from the root rotation at `time`: where it turns
    the model's up (+Y); InputError when the body is not upright along either."""
    body_up = motion.local_rotations(np.array([time]))[0, 0] @ [0.0, 1.0, 0.0]
    for axis, k in (("y", 1), ("z", 2)):
        if body_up[k] > np.cos(np.radians(35.0)):
            return axis
    raise InputError(f"{motion.path}: cannot tell the motion's up axis: at its first frame the body's up "
                     f"points along ({body_up[0]:.2f}, {body_up[1]:.2f}, {body_up[2]:.2f}); set up = \"z\" "
                     f"(AMASS) or \"y\" on the obstacle")


def smpl_track(model: SmplModel, betas: np.ndarray, motion: SmplMotion, times: np.ndarray, frame_dt: float,
               up: str, scale: float = 1.0) -> PoseTrack:
    """The motion at `times` as world rotations and root positions in the scene frame (the
    model's axes are Y-up, the motion's `up`)."""
    local = motion.local_rotations(times)
    world = np.empty_like(local)
    for j, p in enumerate(model.parents):
        world[:, j] = local[:, j] if p < 0 else world[:, p] @ local[:, j]
    world = UP[up] @ world @ UP["y"].T
    root = model.joints(model.shaped(betas))[0] + motion.translation(times)  # joint 0 in the motion's frame
    return PoseTrack(world, to_scene_frame(root, scale, up), frame_dt)


# ------------------------------------------------------------------------------ reading


def read_model(path) -> SmplModel:
    """A checked SMPL-family model from .npz or .pkl."""
    path = input_file(path, "SMPL model")
    arrays = _read_pkl(path) if path.suffix.lower() == ".pkl" else _read_npz(path, MODEL_KEYS, "SMPL model")
    missing = [k for k in MODEL_KEYS if k not in arrays]
    if missing:
        raise InputError(f"{path}: an SMPL model needs {', '.join(missing)} (has {', '.join(sorted(arrays)) or 'none'})")
    return _check_model(path, {k: arrays[k] for k in MODEL_KEYS})


def _array(path, name: str, a, ndim: int, kind: str = "fiu") -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != ndim or a.dtype.kind not in kind or a.size == 0:
        raise InputError(f"{path}: {name} has shape {a.shape} ({a.dtype}); expected {ndim} dimensions of numbers")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise InputError(f"{path}: {name} has non-finite values (NaN or inf)")
    return a


def _check_model(path: Path, a: dict) -> SmplModel:
    v = _array(path, "v_template", a["v_template"], 2).astype(float)
    if v.shape[1] != 3:
        raise InputError(f"{path}: v_template has shape {v.shape}, expected (vertices, 3)")
    V = len(v)
    kt = _array(path, "kintree_table", a["kintree_table"], 2, "iu")
    if kt.shape[0] != 2 or not 1 <= kt.shape[1] <= MAX_JOINTS:
        raise InputError(f"{path}: kintree_table has shape {kt.shape}, expected (2, joints)")
    J = kt.shape[1]
    if not np.array_equal(kt[1].astype(np.int64), np.arange(J)):
        raise InputError(f"{path}: kintree_table row 1 must list the joints 0 to {J - 1} in order")
    parents = kt[0].astype(np.int64)
    parents[0] = -1  # the root's entry is -1 or 2^32 - 1 in the official files
    bad = np.flatnonzero((parents[1:] < 0) | (parents[1:] >= np.arange(1, J)))
    if len(bad):
        raise InputError(f"{path}: kintree_table: joint {bad[0] + 1}'s parent {parents[bad[0] + 1]} is not an "
                         "earlier joint")
    sd = _array(path, "shapedirs", a["shapedirs"], 3).astype(float)
    if sd.shape[:2] != (V, 3):
        raise InputError(f"{path}: shapedirs has shape {sd.shape}, expected ({V}, 3, betas)")
    P = 9 * (J - 1)
    pd = np.asarray(a["posedirs"])
    pd = _array(path, "posedirs", pd, 2 if pd.ndim == 2 else 3)
    if pd.shape not in ((V, 3, P), (3 * V, P)):
        raise InputError(f"{path}: posedirs has shape {pd.shape}, expected ({V}, 3, {P}) for {J} joints")
    jr = _array(path, "J_regressor", a["J_regressor"], 2).astype(float)
    if jr.shape != (J, V):
        raise InputError(f"{path}: J_regressor has shape {jr.shape}, expected ({J}, {V})")
    w = _array(path, "weights", a["weights"], 2).astype(float)
    if w.shape != (V, J):
        raise InputError(f"{path}: weights has shape {w.shape}, expected ({V}, {J})")
    if (w < -1e-6).any():
        raise InputError(f"{path}: weights has negative entries")
    f = _array(path, "f", a["f"], 2, "iu")
    if f.shape[1] != 3 or f.max() >= V:
        raise InputError(f"{path}: f has shape {f.shape} and indices up to {f.max()}, expected (faces, 3) "
                         f"indices below {V}")
    return SmplModel(path, v, sd, pd.reshape(3 * V, P).astype(float), jr, np.maximum(w, 0.0), parents,
                     f.astype(np.int32))


def read_motion(path, n_joints: int, n_betas: int, fps: float | None = None) -> tuple[SmplMotion, list[str]]:
    """A checked AMASS-style motion cut to the model's joints and shape space, and notes
    on what was cut."""
    path = input_file(path, "SMPL motion")
    a = _read_npz(path, ("poses", "trans", "betas", "mocap_framerate", "mocap_frame_rate"), "SMPL motion")
    missing = [k for k in ("poses", "trans") if k not in a]
    if missing:
        raise InputError(f"{path}: an SMPL motion needs {', '.join(missing)} (AMASS: poses (T, 3 J), trans (T, 3), "
                         "betas, mocap_framerate)")
    notes = []
    poses = _array(path, "poses", a["poses"], 2).astype(float)
    if poses.shape[1] < 3 * n_joints:
        raise InputError(f"{path}: poses has {poses.shape[1]} values per frame, the model's {n_joints} joints need "
                         f"{3 * n_joints} (SMPL 72, SMPL-H 156, SMPL-X 165): is it a motion for this model?")
    if poses.shape[1] > 3 * n_joints:
        notes.append(f"{path.name}: poses has {poses.shape[1]} values per frame; the first {3 * n_joints} "
                     f"({n_joints} joints) are used")
    trans = _array(path, "trans", a["trans"], 2).astype(float)
    if trans.shape != (len(poses), 3):
        raise InputError(f"{path}: trans has shape {trans.shape}, expected ({len(poses)}, 3) to match poses")
    betas = np.zeros(0)
    if "betas" in a:
        betas = np.asarray(a["betas"])
        if betas.dtype.kind not in "fiu" or betas.ndim > 2 or (betas.ndim == 2 and betas.shape[0] != 1):
            raise InputError(f"{path}: betas has shape {betas.shape} ({betas.dtype}), expected (B,) numbers")
        betas = betas.reshape(-1).astype(float)
        if not np.isfinite(betas).all():
            raise InputError(f"{path}: betas has non-finite values")
    if len(betas) > n_betas:
        notes.append(f"{path.name}: {len(betas)} shape coefficients (betas), the model has {n_betas} shape "
                     f"directions: the first {n_betas} are used")
        betas = betas[:n_betas]
    if fps is None:
        key = next((k for k in ("mocap_framerate", "mocap_frame_rate") if k in a), None)
        if key is None:
            raise InputError(f"{path}: no mocap_framerate; give `fps` on the obstacle")
        rate = np.asarray(a[key])
        if rate.size != 1 or rate.dtype.kind not in "fiu":
            raise InputError(f"{path}: {key} must be one number (frames per second)")
        fps = float(rate.reshape(-1)[0])
    if not 0.0 < fps <= MAX_FPS:
        raise InputError(f"{path}: frame rate {fps:g} is not frames per second in (0, {MAX_FPS:g}]")
    return SmplMotion(path, poses[:, : 3 * n_joints], trans, betas, fps), notes


def _read_npz(path: Path, keys: tuple[str, ...], what: str) -> dict[str, np.ndarray]:
    """The arrays `keys` of an NPZ; the others (even Python objects, as in the official
    SMPL-X files) are skipped unread. Headers are checked before anything is allocated."""
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not an NPZ archive (expected {what})")
    try:
        with zipfile.ZipFile(path) as z:
            members = {i.filename[:-4]: i for i in z.infolist()
                       if i.filename.endswith(".npy") and i.filename[:-4] in keys}
            need = 0
            for name, info in members.items():
                with z.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version not in ((1, 0), (2, 0)):
                        raise ValueError(f"unsupported .npy format version {version}")
                    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                        np.lib.format.read_array_header_2_0
                    shape, _, dtype = read(f)
                if dtype.hasobject:
                    raise InputError(f"{path}: array {name!r} holds Python objects; only numbers are read")
                nbytes = float(np.prod(shape, dtype=float)) * dtype.itemsize
                if nbytes > info.file_size:
                    raise InputError(f"{path}: array {name!r} claims shape {tuple(shape)} but the archive stores "
                                     f"{info.file_size} bytes of it (damaged)")
                need += nbytes
            require_memory(3 * need, f"reading {path}", "is it the right file?")
            return {n: np.lib.format.read_array(z.open(i), allow_pickle=False) for n, i in members.items()}
    except InputError:
        raise
    except Exception as e:  # zipfile, zlib and numpy's format errors on a damaged archive
        raise InputError(f"{path}: not a readable {what} ({printable(e, 200)})") from None


# ----------------------------------------------------------------------------- pickles


class _Stored:
    """An object of a class we do not import: its pickled state, kept for reading."""

    def __init__(self, *args, **kwargs):
        self.args = args
        self.state = None

    def __setstate__(self, state):
        self.state = state


class _Sparse(_Stored):
    cls = ""


class _Chumpy(_Stored):
    cls = ""


def _stub(base: type, name: str) -> type:
    return type(name, (base,), {"cls": name})


def _numpy(name: str):
    try:
        from numpy._core import multiarray, numeric
    except ImportError:  # numpy 1
        from numpy.core import multiarray, numeric
    return {"_reconstruct": multiarray._reconstruct, "scalar": multiarray.scalar,
            "_frombuffer": numeric._frombuffer}[name]


def _encode(text: str, encoding: str = "utf-8") -> bytes:
    if encoding not in ("latin1", "latin-1", "utf-8", "utf8"):
        raise pickle.UnpicklingError(f"it encodes text as {encoding!r}")
    return text.encode(encoding)


class _Unpickler(pickle.Unpickler):
    """Only numpy arrays and dtypes, scipy sparse matrices and chumpy arrays (as stubs)."""

    def find_class(self, module: str, name: str):
        if module in ("numpy", "numpy.core.multiarray", "numpy._core.multiarray", "numpy.core.numeric",
                      "numpy._core.numeric"):
            if name == "ndarray":
                return np.ndarray
            if name == "dtype":
                return np.dtype
            if name in ("_reconstruct", "scalar", "_frombuffer"):
                return _numpy(name)
        if module == "_codecs" and name == "encode":  # how protocol 2 writes bytes
            return _encode
        if module in ("copy_reg", "copyreg") and name == "_reconstructor":
            return copyreg._reconstructor
        if module in ("__builtin__", "builtins") and name == "object":
            return object
        if module.startswith("scipy.sparse") and name in ("csc_matrix", "csr_matrix", "coo_matrix"):
            return _stub(_Sparse, name)
        if module.startswith("chumpy"):
            return _stub(_Chumpy, f"{module}.{name}")
        raise pickle.UnpicklingError(f"it refers to {module}.{name}, which a model file has no need of")


def _read_pkl(path: Path) -> dict[str, np.ndarray]:
    size = path.stat().st_size
    require_memory(4 * size, f"reading {path}", "is it the right file?")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            doc = _Unpickler(io.BytesIO(path.read_bytes()), encoding="latin1").load()
    except Exception as e:  # a damaged or foreign pickle raises anything
        raise InputError(f"{path}: not a readable SMPL model pickle ({printable(e, 200)}); convert it to .npz "
                         "(docs/bodies.md)") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: the pickle holds a {type(doc).__name__}, not an SMPL model (a dict of arrays)")
    return {k: _plain(path, k, v) for k, v in doc.items() if k in MODEL_KEYS}


def _plain(path: Path, key: str, value) -> np.ndarray:
    """A model entry as a numpy array: chumpy arrays by their value, sparse ones densified."""
    if isinstance(value, _Chumpy):
        x = value.state.get("x") if isinstance(value.state, dict) else None
        if not isinstance(x, np.ndarray):
            raise InputError(f"{path}: {key} is a chumpy expression ({value.cls}) that needs chumpy to evaluate; "
                             "convert the model to .npz (docs/bodies.md)")
        return x
    if isinstance(value, _Sparse):
        return _dense(path, key, value)
    if isinstance(value, np.ndarray):
        return value
    try:
        return np.asarray(value)
    except Exception:
        raise InputError(f"{path}: {key} is a {type(value).__name__}, not an array") from None


def _dense(path: Path, key: str, m: _Sparse) -> np.ndarray:
    s = m.state if isinstance(m.state, dict) else {}
    shape = s.get("_shape", s.get("shape"))
    try:
        rows, cols = (int(n) for n in shape)
        if not (0 < rows <= 10**6 and 0 < cols <= 10**8) or rows * cols > 2 * 10**8:
            raise ValueError
        out = np.zeros((rows, cols))
        data = np.asarray(s["data"], float)
        if m.cls == "coo_matrix":
            r, c = np.asarray(s["row"], np.int64), np.asarray(s["col"], np.int64)
        else:
            indices, indptr = np.asarray(s["indices"], np.int64), np.asarray(s["indptr"], np.int64)
            n = cols if m.cls == "csc_matrix" else rows
            if len(indptr) != n + 1 or np.any(np.diff(indptr) < 0) or indptr[-1] != len(indices) != len(data):
                raise ValueError
            major = np.repeat(np.arange(n), np.diff(indptr))
            r, c = (indices, major) if m.cls == "csc_matrix" else (major, indices)
        if len(r) != len(data) or len(c) != len(data) or (len(r) and (r.min() < 0 or r.max() >= rows
                                                                     or c.min() < 0 or c.max() >= cols)):
            raise ValueError
        np.add.at(out, (r, c), data)
        return out
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{path}: {key} is a damaged sparse matrix ({m.cls})") from None
