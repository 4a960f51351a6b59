"""Files a command reads and writes, checked before any work and written atomically.

Inputs: `input_file` says "no such file" or "is a folder" (not a bare OSError later).
Outputs: `output_file` / `output_folder` refuse, before a run starts, a file name that is
an existing folder (and the reverse), an extension that does not match the format, and a
place that cannot be written (probed by creating and removing a file in the nearest
existing folder: permissions, read-only or virtual file systems like /proc).
NPZ archives: `read_npz` checks each array's header (numeric dtype, a shape the stored
bytes can hold, memory the machine has) before allocating it.
Writes: `atomic_write` writes to `.NAME.PID.tmp` beside the final name and renames it
when complete; the temporary file is removed on every exit path that runs Python
(exceptions, KeyboardInterrupt, SIGTERM turned into one by the command line), and
`remove_partial_files` removes what is still open when the process must exit at once.
"""

from __future__ import annotations

import math
import os
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .budget import format_bytes, require_memory
from .errors import InputError, printable

# Temporary files being written: path -> final name to move it to on a hard exit (None:
# delete it). Only a stream that is valid when cut short (a Rerun recording) is kept.
_PARTIAL: dict[Path, Path | None] = {}


def input_file(path: str | os.PathLike, what: str = "file") -> Path:
    """`path` if it is an existing, readable file; InputError naming it otherwise."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a {what}")
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: cannot be read (permission denied)")
    return path


def read_npz(path: str | os.PathLike, what: str = "NPZ archive") -> dict[str, np.ndarray]:
    """Every array of an NPZ archive by name; InputError naming the file when it is not
    one, is damaged, holds Python objects or claims arrays larger than it stores."""
    path = input_file(path)
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not an NPZ archive (expected {what})")
    try:
        with zipfile.ZipFile(path) as z:
            members = [i for i in z.infolist() if i.filename.endswith(".npy")]
            need = 0
            for info in members:
                with z.open(info) as f:
                    shape, dtype = _npy_header(f)
                name = info.filename[:-4]
                if dtype.hasobject:
                    raise InputError(f"{path}: array {name!r} holds Python objects; only numbers are read")
                nbytes = math.prod(shape) * dtype.itemsize
                if nbytes > info.file_size:
                    raise InputError(f"{path}: array {name!r} claims shape {shape} ({format_bytes(nbytes)}) "
                                     f"but the archive stores {info.file_size} bytes of it (damaged)")
                need += nbytes
            require_memory(2 * need, f"reading {path}", "is it the right file?")
            return {i.filename[:-4]: np.lib.format.read_array(z.open(i), allow_pickle=False) for i in members}
    except InputError:
        raise
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile, zlib.error, NotImplementedError) as e:
        raise InputError(f"{path}: not a readable {what} ({printable(e, 200)})") from None


def _npy_header(f) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(f)
    readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in readers:
        raise ValueError(f"unsupported .npy format version {version}")
    shape, _, dtype = readers[version](f)
    return tuple(int(n) for n in shape), dtype


def output_file(path: str | os.PathLike, suffixes: tuple[str, ...], what: str) -> Path:
    """Check that `what` (e.g. "the recording (-o)") can be written to `path`: not a
    folder, one of `suffixes` (lower case, with the dot; empty: any), a writable place."""
    path = Path(path)
    if path.is_dir():
        example = path / f"run{suffixes[0]}" if suffixes else path / "NAME"
        raise InputError(f"{path}: is a folder; {what} is a file (e.g. {example})")
    if suffixes and path.suffix.lower() not in suffixes:
        got = f"'{path.suffix}'" if path.suffix else "no extension"
        raise InputError(f"{path}: {what} must end in {' or '.join(suffixes)}, got {got}")
    _check_writable(path)
    return path


def output_folder(path: str | os.PathLike, what: str) -> Path:
    """Check that `what` (a folder of outputs) can be created or written at `path`."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: is a file, but {what} must be a folder")
    _check_writable(path / "_")
    return path


def _check_writable(path: Path) -> None:
    """The nearest existing folder above `path` accepts a new file (nothing is left)."""
    folder = path.absolute().parent
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{path}: {folder} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".garment-probe-")
    except OSError as e:
        raise InputError(f"{path}: cannot write in {folder} ({e.strerror or e})") from None
    os.close(fd)
    os.unlink(probe)


def temporary_name(path: Path, keep_suffix: bool = False) -> Path:
    """`.NAME.PID.tmp` beside `path` (`.STEM.PID.tmp.suffix` with keep_suffix, lower case,
    for writers that choose the format by extension: imageio, USD)."""
    if keep_suffix:
        return path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix.lower()}")
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextmanager
def atomic_write(path: str | os.PathLike, keep_suffix: bool = False, fsync: bool = False) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is renamed to `path` (fsync: its
    data is on disk first), on any exception it is removed. Creates `path`'s folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_name(path, keep_suffix)
    _PARTIAL[tmp] = None
    try:
        yield tmp
        if fsync:
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        _PARTIAL.pop(tmp, None)
        tmp.unlink(missing_ok=True)


def track_partial(tmp: Path, final: Path | None = None) -> None:
    """Register a temporary file written outside `atomic_write` (a stream open for a whole
    run); `final`: move it there on a hard exit instead of deleting it."""
    _PARTIAL[Path(tmp)] = final


def untrack_partial(tmp: Path) -> None:
    _PARTIAL.pop(Path(tmp), None)


def remove_partial_files() -> None:
    """Before an immediate exit (os._exit): delete temporary files still being written, or
    move them to their final names where registered so. Never raises."""
    for tmp, final in list(_PARTIAL.items()):
        try:
            if final is not None and tmp.exists():
                os.replace(tmp, final)
            else:
                tmp.unlink(missing_ok=True)
        except OSError:
            pass
    _PARTIAL.clear()
