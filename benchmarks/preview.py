"""Preview benchmark: `baker preview` (map + 9-frame contact sheet at 640x360 per frame) on a
60 s bake of the default scene, and the animated GIF (`--gif`) on its own.

Each run is a `baker preview` process, Python start-up and imports included, as a user runs it.
Prints the median wall time and CPU time of several runs, and the pictures' sizes. Run from the
repo root:  python benchmarks/preview.py [--runs 5] [--seconds 60] [--glb FILE.glb]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(cmd: list[str]) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the child) of one command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--glb", type=Path, default=None,
                    help="preview this GLB instead of baking the default scene")
    args = ap.parse_args()
    baker = [sys.executable, "-m", "baker"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        glb = args.glb
        if glb is None:
            glb = tmp / "bake.glb"
            subprocess.run(baker + ["bake", "--seconds", str(args.seconds), "--format", "glb",
                                    "--out", str(glb.with_suffix(""))], check=True,
                           capture_output=True)
        pics = [timed(baker + ["preview", str(glb), "--out", str(tmp / "p")])
                for _ in range(args.runs)]
        gifs = [timed(baker + ["preview", str(glb), "--gif", "--out", str(tmp / "g")])
                for _ in range(max(1, args.runs // 2))]
        sizes = {p.name: p.stat().st_size for p in sorted(tmp.glob("[pg]*.*"))}
    med = statistics.median
    wall, cpu = med(p[0] for p in pics), med(p[1] for p in pics)
    gwall, gcpu = med(g[0] for g in gifs), med(g[1] for g in gifs)
    print(f"baker preview, {glb.name if args.glb else f'{args.seconds:.0f} s default bake'}, "
          f"medians of {args.runs} runs (imports included)")
    print(f"  map + 9-frame sheet (640x360) : {wall:6.2f} s wall, {cpu:6.2f} s CPU")
    print(f"  with --gif (320x180)          : {gwall:6.2f} s wall, {gcpu:6.2f} s CPU "
          f"(the GIF alone: {gwall - wall:.2f} s)")
    print("  files: " + ", ".join(f"{k} {v / 1024:.0f} kB" for k, v in sizes.items()))


if __name__ == "__main__":
    main()
