"""The memory a bake needs, estimated from its frames, creatures and worker processes, and
checked before it starts: a bake that would run out of memory part way (a crowd of 1000 for a
minute needs about 60 GB) is refused at once with the largest crowd and the longest bake that
fit, instead of dying after half an hour.

The estimate is linear, with coefficients fitted to measured peaks (the machine's used memory,
every process of the bake included; see the README's Benchmarks):

- BASE_BYTES: the process with the bundled level loaded;
- SOLVE_BYTES_PER_FRAME: a creature's solve (trail, body, legs over all its frames at once),
  what a lone creature's bake grows by per exported frame; a crowd solves one creature per
  worker process at a time;
- a crowd's creatures are kept by the bake until the files are written: CREATURE_BYTES each,
  and CREATURE_BYTES_PER_FRAME per creature and frame (the trajectory, the clip, its keys, and
  their share of the files being written).

The limit is --max-memory when given, else USABLE_SHARE of the memory this process may use
(the RAM, or less under `ulimit -v` or a container's limit: navmesh.budget).
"""

from __future__ import annotations

from baker.config import frame_count
from baker.errors import BudgetError

#: [bytes] the process with the bundled level and its navigation surface loaded (379 MB
#: measured for a 1 s bake)
BASE_BYTES = 400e6
#: [bytes] per exported frame of the creature being solved (a lone creature's bake, peak
#: resident: 575 MB at 1,801 frames, 1,461 MB at 9,001, 3,646 MB at 27,001; the machine's
#: memory rose by 3.92 GB in the last)
SOLVE_BYTES_PER_FRAME = 130e3
#: [bytes] per creature of a crowd, and per creature and exported frame (fitted to 100
#: creatures x 601 frames, 2.22 GB, and 1000 creatures x 61 frames, 4.15 GB, of the machine's
#: memory above what it used before the bake)
CREATURE_BYTES = 2.2e6
CREATURE_BYTES_PER_FRAME = 34e3
#: share of the memory the process may use that a bake may be estimated to need by default
USABLE_SHARE = 0.8


def estimate(creatures: int, frames: int, workers: int = 1) -> float:
    """[bytes] the estimated peak memory of a bake of `creatures` creatures and `frames`
    exported frames, its per-creature work on `workers` processes."""
    n, f = int(creatures), int(frames)
    solving = max(1, min(int(workers), n))
    est = BASE_BYTES + SOLVE_BYTES_PER_FRAME * f * solving
    if n > 1:
        est += n * (CREATURE_BYTES + CREATURE_BYTES_PER_FRAME * f)
    return est


def limit(max_memory_mb: float | None) -> float:
    """[bytes] the largest estimate a bake may have: `max_memory_mb` (--max-memory), else
    USABLE_SHARE of the memory this process may use."""
    if max_memory_mb is not None:
        return float(max_memory_mb) * 1e6
    from baker.navmesh.budget import usable_memory

    return USABLE_SHARE * usable_memory()


def check(creatures: int, seconds: float, fps: int, workers: int,
          max_memory_mb: float | None) -> float:
    """Raise BudgetError when the bake is estimated over the limit, naming the largest crowd
    and the longest bake that fit. Returns the estimate [bytes]."""
    n, frames = int(creatures), frame_count(seconds, fps)
    est, cap = estimate(n, frames, workers), limit(max_memory_mb)
    if est <= cap:
        return est
    what = f"{n} creatures for {seconds:g} s" if n > 1 else f"{seconds:g} s"
    fits = []
    most = _most_creatures(frames, workers, cap)
    if n > 1 and most:
        fits.append(f"at most {most} creatures for {seconds:g} s")
    longest = _longest(n, fps, workers, cap)
    if longest > 0:
        fits.append(f"{f'{n} creatures for ' if n > 1 else ''}at most {longest:g} s")
    fit = f"bake {' or '.join(fits)}, or " if fits else ""
    raise BudgetError(
        f"a bake of {what} at {fps} fps needs about {est / 1e9:.3g} GB of memory, over the "
        f"{cap / 1e9:.3g} GB limit; {fit}raise --max-memory",
        where="--creatures" if n > 1 else "--seconds")


def _most_creatures(frames: int, workers: int, cap: float) -> int:
    """The largest crowd (at least 2) whose bake of `frames` frames fits `cap`, or 0."""
    return _largest(lambda n: estimate(n, frames, workers) <= cap, 2, 1000)


def _longest(creatures: int, fps: int, workers: int, cap: float) -> float:
    """[s] the longest bake of `creatures` creatures (in tenths of a second) that fits `cap`,
    or 0 when none does."""
    tenths = _largest(lambda k: estimate(creatures, frame_count(k / 10, fps), workers) <= cap,
                      1, 36000)
    return tenths / 10.0


def _largest(fits, lo: int, hi: int) -> int:
    """The largest k in [lo, hi] with fits(k) (fits is true up to some k, then false), or 0."""
    if not fits(lo):
        return 0
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid - 1)
    return lo
