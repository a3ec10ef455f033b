"""Budget of a navigation build: its memory and time estimated from the column count, checked
before any ray is cast.

The estimate is linear in the grid's columns and the level's triangles, with coefficients
fitted to measured peak RSS of whole builds (benchmarks/bench_nav_budget.py; the README gives
the figures). A build estimated over the limit (`--max-memory`, default half of the machine's
RAM) is refused with a BudgetError naming a cell size whose estimate fits.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import os
from dataclasses import dataclass

from baker.errors import BudgetError

#: [bytes] process baseline (Python, numpy, trimesh, embree, the loaded level) before a build,
#: and numba's compiled rasterizer (about 125 MB: the import and LLVM, once loaded; about 50 MB
#: more on a machine's first build, which compiles it)
BASE_BYTES = 350e6
#: [bytes] peak memory per grid column (ray hits, samples, links, components); measured about
#: 230 on the default scene at cells 0.03-0.0075 m above the baseline (peak 415, 779, 1376,
#: 2441 MB for 0.56, 2.25, 5.06, 9 M columns; benchmarks/bench_nav_budget.py) since the build
#: keeps its temporaries in tiles and slims its samples (issue 15)
BYTES_PER_COLUMN = 250.0
#: [bytes] per level triangle (embree scene, solid labels)
BYTES_PER_TRIANGLE = 200.0
#: [s] build time per column and per triangle (2-core machine)
SECONDS_PER_COLUMN = 3.5e-6
SECONDS_PER_TRIANGLE = 4e-6

_limit: contextvars.ContextVar[float | None] = contextvars.ContextVar("nav_memory_limit",
                                                                      default=None)


@dataclass(frozen=True)
class Estimate:
    bytes: float      # [bytes] peak resident memory of the process during the build
    seconds: float    # [s] build wall time


def estimate(columns: float, triangles: int) -> Estimate:
    """The estimated peak memory and time of a build of `columns` columns over a level of
    `triangles` triangles."""
    return Estimate(bytes=BASE_BYTES + BYTES_PER_COLUMN * columns + BYTES_PER_TRIANGLE * triangles,
                    seconds=SECONDS_PER_COLUMN * columns + SECONDS_PER_TRIANGLE * triangles)


def default_limit() -> float:
    """[bytes] half of the memory this process may use (usable_memory); 4 GB when none can be
    read. (A build refused at once names a cell size that fits; one that runs out of memory
    half way is only an error line.)"""
    return 0.5 * usable_memory()


def usable_memory() -> float:
    """[bytes] the memory this process may use: the machine's physical RAM, or less where the
    process's address space is limited (`ulimit -v`, RLIMIT_AS) or its control group has a
    memory limit (cgroup v2 memory.max, v1 memory.limit_in_bytes); 8 GB when none can be
    read."""
    sizes = []
    try:
        sizes.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        pass
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY and soft > 0:
            sizes.append(soft)
    except (ImportError, ValueError, OSError):  # pragma: no cover - not Unix
        pass
    sizes += _cgroup_limits()
    return float(min(sizes)) if sizes else 8e9


#: the files holding this process's control-group memory limit (v2, then v1)
CGROUP_FILES = ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes")


def _cgroup_limits() -> list[float]:
    """The control-group memory limits in force ([bytes]; none when unlimited or unreadable)."""
    out = []
    for name in CGROUP_FILES:
        try:
            with open(name) as fh:
                text = fh.read().strip()
        except OSError:
            continue
        if text.isdigit() and 0 < int(text) < 1 << 60:   # v1 writes "unlimited" as ~2^63
            out.append(float(text))
    return out


def limit() -> float:
    """[bytes] the limit in force (memory_limit's, else default_limit())."""
    v = _limit.get()
    return default_limit() if v is None else v


@contextlib.contextmanager
def memory_limit(megabytes: float | None):
    """Builds inside this block are refused above `megabytes` MB (None: the default)."""
    token = _limit.set(None if megabytes is None else float(megabytes) * 1e6)
    try:
        yield
    finally:
        _limit.reset(token)


def _count(n: int) -> str:
    return f"{n:,}" if n < 10**12 else f"{float(n):.3g}"


def check(nx: int, nz: int, cell: float, triangles: int, where: str | None = None,
          area: float | None = None, hint: str = "") -> Estimate:
    """Raise BudgetError when a build of nx x nz columns at `cell` metres is estimated over
    the limit; the message names a cell size that fits (from `area`, m^2, the build's
    horizontal area; default nx * nz * cell^2); `hint` is appended to the message.
    Returns the estimate."""
    nx, nz = int(nx), int(nz)
    area = (nx * cell) * (nz * cell) if area is None else float(area)
    est = estimate(float(nx) * float(nz), triangles)   # (floats: a grid may be absurd)
    cap = limit()
    if est.bytes <= cap:
        return est
    room = cap - BASE_BYTES - BYTES_PER_TRIANGLE * triangles
    if room <= BYTES_PER_COLUMN:
        raise BudgetError(
            f"navigation build needs about {est.bytes / 1e9:.3g} GB, over the "
            f"{cap / 1e9:.3g} GB limit, and the level alone ({triangles:,} triangles) leaves no "
            f"room for any grid; raise --max-memory{hint}", where=where or "--max-memory")
    fit_cols = room / BYTES_PER_COLUMN
    # the cell whose grid fits (columns scale with 1 / cell^2), rounded up to 2 digits
    need = math.sqrt(area / fit_cols) * 1.02
    e = math.floor(math.log10(need)) - 1
    fit = math.ceil(need / 10 ** e) * 10 ** e
    raise BudgetError(
        f"navigation build of {_count(nx)} x {_count(nz)} columns at cell size {cell:g} m "
        f"needs about "
        f"{est.bytes / 1e9:.3g} GB and {est.seconds:.3g} s, over the {cap / 1e9:.3g} GB memory "
        f"limit; use --cell-size {fit:.2g} or larger, or raise --max-memory{hint}",
        where=where or "--cell-size")
