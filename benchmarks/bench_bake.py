"""Bake benchmark: a 60 s bake at 30 fps of the default scene, cold and warm navigation cache.

Prints medians of several runs, the per-stage split and the real-time ratio. Run from the repo
root:  python benchmarks/bench_bake.py [--runs 3] [--seconds 60]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from baker.config import BakeConfig, load_rig_config, DEFAULT_RIG
from baker.context import Context
from baker.pipeline import bake


def timed_bake(seconds: float, cache: Path, out: Path, rig=None, **kw):
    """One in-process bake of the default scene; returns (wall seconds, per-stage timings)."""
    cfg = BakeConfig(seconds=seconds, fps=30, seed=0, rig=rig or load_rig_config(DEFAULT_RIG),
                     out=out / "bench", nav_cache_dir=cache, **kw)
    ctx = Context()
    t = time.perf_counter()
    bake(cfg, ctx=ctx)
    return time.perf_counter() - t, dict(ctx.timings)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cold, warm, stages = [], [], []
        for i in range(args.runs):
            cache = tmp / f"cache{i}"
            t, _ = timed_bake(args.seconds, cache, tmp)          # cold: empty cache
            cold.append(t)
            t, st = timed_bake(args.seconds, cache, tmp)         # warm: same cache
            warm.append(t)
            stages.append(st)
        # the CLI with bytecode written as on any machine (an environment that sets
        # PYTHONDONTWRITEBYTECODE would have each run compile the package's sources again);
        # one run first writes it
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        cmd = [sys.executable, "-m", "baker", "bake", "--seconds", str(args.seconds),
               "--out", str(tmp / "cli"), "--cache-dir", str(tmp / "cache0")]
        subprocess.run(cmd, check=True, capture_output=True, env=env)
        cli = []
        for _ in range(args.runs):
            t = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=env)
            cli.append(time.perf_counter() - t)
    med = statistics.median
    print(f"bake {args.seconds:.0f} s @ 30 fps, default scene, {args.runs} runs (medians)")
    print(f"  cold navigation cache : {med(cold):6.2f} s   ({args.seconds / med(cold):5.1f}x real time)")
    print(f"  warm navigation cache : {med(warm):6.2f} s   ({args.seconds / med(warm):5.1f}x real time)")
    print(f"  CLI, warm, incl. imports: {med(cli):6.2f} s   ({args.seconds / med(cli):5.1f}x real time)")
    print("  warm stages: " + ", ".join(f"{k} {med([s.get(k, 0) for s in stages]):.3f} s"
                                       for k in stages[0]))


if __name__ == "__main__":
    main()
