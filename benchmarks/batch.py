"""Throughput of `baker batch` on the local pool: 24 short bakes of the bundled rainforest floor
(2 s at 30 fps, seeds 0-23, GLB + USD + report each) with 1 and 2 worker processes, with the
navigation cache warm. Prints the wall time of each whole batch (worker start-up included),
bakes per minute and the speed-up of 2 workers over 1.

    python benchmarks/batch.py [--jobs 24] [--seconds 2] [--repeat 1]

With --repeat N the two pool sizes alternate N times and the medians are printed (the machine
is shared: figures move between runs).
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import tempfile
import time
from pathlib import Path

from baker import batch
from baker.config import DEFAULT_ENVIRONMENT


def jobs_file(folder: Path, jobs: int, seconds: float) -> Path:
    path = folder / "bench.toml"
    path.write_text(f"""[[job]]
name = "bench"
environment = "{DEFAULT_ENVIRONMENT.as_posix()}"
seconds = {seconds}
[job.matrix]
seed = [{", ".join(str(s) for s in range(jobs))}]
""")
    return path


def one_batch(path: Path, out: Path, workers: int, cache: Path) -> tuple[float, float]:
    """(wall time of the whole batch, mean wall time of one bake inside it), seconds."""
    t0 = time.perf_counter()
    s = batch.run(path, out=out, workers=workers, force=True, cache=cache, stream=io.StringIO())
    wall = time.perf_counter() - t0
    if s.failed or s.baked != s.jobs:
        raise SystemExit(f"batch failed: {s.line}")
    doc = json.loads((out / "manifest.json").read_text())
    return wall, statistics.mean(e["wall_s"] for e in doc["jobs"].values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=24)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="baker-bench-batch-") as tmp:
        tmp = Path(tmp)
        cache = tmp / "cache"
        print(f"{a.jobs} bakes of {a.seconds:g} s on {DEFAULT_ENVIRONMENT.name}; warming the "
              "navigation cache ...", flush=True)
        warm = tmp / "warm"
        warm.mkdir()
        batch.run(jobs_file(warm, 1, a.seconds), out=warm / "out", workers=1, cache=cache,
                  stream=io.StringIO())
        path = jobs_file(tmp, a.jobs, a.seconds)
        walls: dict[int, list[float]] = {1: [], 2: []}
        bakes: dict[int, list[float]] = {1: [], 2: []}
        for r in range(a.repeat):
            for n in (1, 2):
                wall, per = one_batch(path, tmp / f"out{n}", n, cache)
                walls[n].append(wall)
                bakes[n].append(per)
                print(f"  run {r + 1}, {n} worker{'s' * (n > 1)}: {wall:.1f} s "
                      f"({per:.2f} s per bake inside the workers)", flush=True)
    print()
    print("| workers | batch wall time | bakes per minute | mean bake (in its worker) | speed-up |")
    print("|---|---|---|---|---|")
    w1 = statistics.median(walls[1])
    for n in (1, 2):
        w = statistics.median(walls[n])
        print(f"| {n} | {w:.1f} s | {60.0 * a.jobs / w:.1f} | {statistics.median(bakes[n]):.2f} s "
              f"| {w1 / w:.2f}x |")


if __name__ == "__main__":
    main()
