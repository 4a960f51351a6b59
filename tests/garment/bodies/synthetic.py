"""Small stand-ins for the body files no one may ship: an SMPL-layout model of a
three-joint column and an AMASS-style motion for it, and a BVH writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

# The column: a 0.3 m x 1.0 m x 0.2 m box, Y-up like SMPL, joints at heights 0, 0.4, 0.8.
HEIGHT = 1.0
JOINT_Y = (0.0, 0.4, 0.8)
PARENTS = (-1, 0, 1)


def column_mesh(sections: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A closed box column (vertices (V, 3), faces (F, 3)) with `sections` rings along Y."""
    m = trimesh.creation.box(extents=(0.3, HEIGHT, 0.2))
    for _ in range(3):
        m = m.subdivide()
    V = np.asarray(m.vertices) + [0.0, HEIGHT / 2 - 0.1, 0.0]  # from y = -0.1 to 0.9
    return V, np.asarray(m.faces, np.int64)


def column_weights(V: np.ndarray) -> np.ndarray:
    """(V, 3) weights: each joint owns its segment, blended linearly over 10 cm at joints."""
    y = V[:, 1]
    w = np.zeros((len(V), 3))
    t1 = np.clip((y - 0.35) / 0.1, 0.0, 1.0)  # 0 below 0.35, 1 above 0.45
    t2 = np.clip((y - 0.75) / 0.1, 0.0, 1.0)
    w[:, 0] = 1.0 - t1
    w[:, 1] = t1 - t2
    w[:, 2] = t2
    return w


def column_model(seed: int = 0) -> dict[str, np.ndarray]:
    """The arrays of an SMPL model file for the column: 2 shape directions (height, width),
    pose correctives of small random size, joints regressed from the vertices nearest
    each joint height (rows sum to 1)."""
    rng = np.random.default_rng(seed)
    V, F = column_mesh()
    n = len(V)
    shapedirs = np.zeros((n, 3, 2))
    shapedirs[:, 1, 0] = 0.1 * V[:, 1]  # beta 0: 10 % taller per unit
    shapedirs[:, 0, 1] = 0.1 * V[:, 0]  # beta 1: 10 % wider per unit
    posedirs = 1e-3 * rng.standard_normal((n, 3, 9 * 2))
    J = np.zeros((3, n))
    for j, h in enumerate(JOINT_Y):
        near = np.argsort(np.abs(V[:, 1] - h))[:16]
        J[j, near] = 1.0 / len(near)
    kintree = np.array([[2**32 - 1, 0, 1], [0, 1, 2]], np.uint32)
    return {"v_template": V, "shapedirs": shapedirs, "posedirs": posedirs, "J_regressor": J,
            "weights": column_weights(V), "kintree_table": kintree, "f": F.astype(np.uint32)}


def bend_motion(frames: int = 31, fps: float = 30.0, angle: float = 0.6, z_up: bool = True) -> dict:
    """An AMASS-style motion of the column bending at joint 1 about the model's z by up to
    `angle` rad and back, with the root stood up Z-up (AMASS) when z_up; 3 extra pose
    columns and 16 betas, as AMASS files carry more than a model needs."""
    t = np.arange(frames) / fps
    poses = np.zeros((frames, 12))
    if z_up:
        poses[:, 0] = np.pi / 2  # +90 deg about X: the Y-up model stands along +Z
    poses[:, 5] = angle * np.sin(np.pi * t / t[-1])
    trans = np.zeros((frames, 3))
    trans[:, 0] = 0.05 * t
    return {"poses": poses, "trans": trans, "betas": np.r_[0.5, -0.5, np.zeros(14)],
            "mocap_framerate": np.float64(fps), "gender": np.array("neutral")}


def write_npz(path: Path, arrays: dict) -> Path:
    np.savez(path, **arrays)
    return path


def write_bvh(path: Path, names, parents, offsets, channels, values, frame_time: float,
              ends: dict | None = None) -> Path:
    """A BVH file of joints given in any order with parents before children: offsets
    (J, 3), channel names per joint, values (T, C) with each joint's channels in that
    order. The file lists joints depth first, as BVH requires, values reordered alike."""
    ends = ends or {}
    children = {j: [k for k, p in enumerate(parents) if p == j] for j in range(len(names))}
    start = np.cumsum([0] + [len(c) for c in channels])
    values = np.atleast_2d(values)
    lines, columns = ["HIERARCHY"], []

    def joint(j: int, depth: int) -> None:
        pad = "\t" * depth
        lines.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}\tOFFSET {' '.join(f'{x:.9f}' for x in offsets[j])}")
        lines.append(f"{pad}\tCHANNELS {len(channels[j])} {' '.join(channels[j])}")
        columns.extend(range(start[j], start[j + 1]))
        for c in children[j]:
            joint(c, depth + 1)
        if not children[j]:
            end = ends.get(j, (0.0, 1.0, 0.0))
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{",
                          f"{pad}\t\tOFFSET {' '.join(f'{x:.9f}' for x in end)}", f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    joint(0, 0)
    lines += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {frame_time:.9f}"]
    lines += [" ".join(f"{x:.9f}" for x in row[columns]) for row in values]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_column_rig(folder: Path, unit: float = 1.0) -> dict[str, Path]:
    """The column as MakeHuman-style files in `folder`, coordinates divided by `unit` (m
    per file unit): body.obj (group "body" plus joint cubes "joint-*", as MakeHuman's base
    mesh), rig.json (bones Root, Mid, Top: heads from cubes, a MEAN and a VERTEX) and
    weights.json. Returns their paths by name."""
    import json

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    V, F = column_mesh()
    cube = trimesh.creation.box(extents=(0.01, 0.01, 0.01))
    groups = [("body", F)]
    points = [V]
    offset = len(V)
    for name, y in (("joint-root", JOINT_Y[0]), ("joint-mid", JOINT_Y[1]), ("joint-top", JOINT_Y[2]),
                    ("joint-end", 0.9)):
        points.append(np.asarray(cube.vertices) + [0.0, y, 0.0])
        groups.append((name, np.asarray(cube.faces) + offset))
        offset += len(cube.vertices)
    P = np.concatenate(points) / unit
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in P]
    for name, faces in groups:
        lines.append(f"g {name}")
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (folder / "body.obj").write_text("\n".join(lines) + "\n")
    level = V[np.argmin(np.abs(V[:, 1] - JOINT_Y[2])), 1]  # the ring of vertices nearest the top joint
    top = [int(i) for i in np.flatnonzero((V[:, 1] == level) & (np.abs(V[:, 0]) == 0.15) & (np.abs(V[:, 2]) == 0.1))]
    tip = int(np.argmax(V[:, 1] - np.abs(V[:, 0]) - np.abs(V[:, 2])))

    def cube_ref(name):
        return {"cube_name": name, "default_position": [0.0, 0.0, 0.0], "strategy": "CUBE"}

    rig = {
        "Root": {"parent": "", "head": cube_ref("joint-root"), "tail": cube_ref("joint-mid"), "roll": 0.0},
        "Mid": {"parent": "Root", "head": cube_ref("joint-mid"), "tail": {"strategy": "MEAN", "vertex_indices": top},
                "roll": 0.0},
        "Top": {"parent": "Mid", "head": {"strategy": "MEAN", "vertex_indices": top},
                "tail": {"strategy": "VERTEX", "vertex_index": tip}, "roll": 0.0},
    }
    (folder / "rig.json").write_text(json.dumps(rig, indent=1))
    W = column_weights(V)
    weights = {"weights": {b: [[int(i), float(W[i, j])] for i in np.flatnonzero(W[:, j] > 0)]
                           for j, b in enumerate(("Root", "Mid", "Top"))}}
    (folder / "weights.json").write_text(json.dumps(weights))
    return {"mesh": folder / "body.obj", "rig": folder / "rig.json", "weights": folder / "weights.json"}


def write_column_bvh(path: Path, frames: int = 13, frame_time: float = 1 / 60, bend: float = 40.0,
                     unit: float = 0.01) -> Path:
    """A BVH for the column's three joints (Root, Mid, Top; Y-up, file units of `unit` m):
    the middle joint bends about Z up to `bend` degrees and back while the root moves
    5 cm along X."""
    t = np.linspace(0.0, 1.0, frames)
    values = np.zeros((frames, 12))
    values[:, 0] = 0.05 * t / unit
    values[:, 1] = 0.1 / unit
    values[:, 6] = bend * np.sin(np.pi * t)  # Mid's Zrotation
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 0.4, 0.0], [0.0, 0.4, 0.0]]) / unit
    return write_bvh(path, ["Root", "Mid", "Top"], [-1, 0, 1], offsets,
                     [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),
                      ("Zrotation", "Xrotation", "Yrotation"), ("Zrotation", "Xrotation", "Yrotation")],
                     values, frame_time, {2: (0.0, 0.1 / unit, 0.0)})
