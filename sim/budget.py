"""Memory a request needs, estimated before the work and refused when it will not fit.

`memory_limit()` is what this process may use: the machine's memory (/proc/meminfo
MemTotal, or os.sysconf), lowered by a cgroup limit or RLIMIT_AS when set; the environment
variable GARMENT_MEMORY_LIMIT (bytes, or with a unit: 512M, 2G) overrides it (tests).
`require_memory` raises InputError (exit status 2) with the estimate, the limit and the
setting to change.

The simulation estimate is fitted to the peak resident memory of `garment simulate` on
flat sheets (1 frame, no outputs; docs/inputs.md): 0.57 GB at 100^2 control points,
1.5 GB at 200^2, 3.4 GB at 300^2 without contact; 1.1 GB at 100^2 and 4.0 GB at 200^2
with an obstacle (contact mesh 2 vertices per control point). Per control point that is
21-34 kB without contact, growing like the fill of the sparse Cholesky factor (log N),
plus about 25 kB per contact-mesh vertex.
"""

from __future__ import annotations

import math
import os
import re
import resource
from pathlib import Path

from .errors import InputError

ENV = "GARMENT_MEMORY_LIMIT"
BASE_BYTES = 0.4e9  # Python, numpy, numba, ipctk and rerun loaded
FACTOR_BYTES_PER_LOG2 = 2.2e3  # per control point and doubling of N (Hessian, factor, rows)
CONTACT_BYTES_PER_VERTEX = 25e3  # per contact-mesh vertex (mesh, BVH, collision sets, merged system)

_UNITS = {"": 1, "k": 1e3, "m": 2**20, "g": 2**30, "t": 2**40}


def parse_bytes(text: str) -> float:
    """'2G' -> 2 GiB, '512M', '1.5e9' -> bytes; ValueError otherwise."""
    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([kKmMgGtT]?)i?[bB]?\s*", text)
    if not m:
        raise ValueError(f"not an amount of memory: {text!r} (e.g. 2G, 512M or bytes)")
    value = float(m[1]) * _UNITS[m[2].lower()]
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"not an amount of memory: {text!r}")
    return value


def memory_limit() -> tuple[float, str]:
    """(bytes this process may use, where the number comes from)."""
    override = os.environ.get(ENV)
    if override:
        try:
            return parse_bytes(override), ENV
        except ValueError as e:
            raise InputError(f"{ENV}: {e}") from None
    limits = [(_machine_memory(), "the machine's memory")]
    cgroup = _cgroup_limit()
    if cgroup is not None:
        limits.append((cgroup, "the cgroup's memory limit"))
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    if soft != resource.RLIM_INFINITY:
        limits.append((float(soft), "the address-space limit (ulimit -v)"))
    return min(limits)


def _machine_memory() -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError):
        return math.inf


def _cgroup_limit() -> float | None:
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 2**60:
            return float(text)
    return None


def format_bytes(n: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n / 2**10:.0f} KiB"


def require_memory(need: float, what: str, fix: str) -> None:
    """InputError when `need` bytes exceed memory_limit(): "{what} needs about ...; {fix}"."""
    limit, source = memory_limit()
    if need > limit:
        raise InputError(f"{what} needs about {format_bytes(need)} of memory, more than {source} "
                         f"({format_bytes(limit)}): {fix}")


def simulation_bytes(control_points: int, contact_vertices: int = 0) -> float:
    """Peak memory (bytes) of a B-spline simulation with `control_points` in all, and a
    contact mesh of `contact_vertices` (cloth and obstacles; 0 without contact)."""
    n = max(int(control_points), 1)
    per_point = FACTOR_BYTES_PER_LOG2 * max(math.log2(n), 10.0)
    return BASE_BYTES + n * per_point + CONTACT_BYTES_PER_VERTEX * contact_vertices
