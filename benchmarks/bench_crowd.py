"""Crowd benchmark (issue 15): the run stage (run.crowd.run_crowd: brains, agents, heads,
avoidance, all creatures in lockstep at 240 Hz) for N = 1, 10, 100 creatures on the default
scene, warm navigation cache. Prints medians, the time per creature and its growth from 10 to
100 creatures, and the smallest distance between different creatures' spine joints over all
frames (solved spine-only: the legs do not move the spine) against twice the body radius.

--bake times whole bakes instead (pipeline.bake: run, solve, pose, metrics, reduce and the
GLB, USD and report written; warm navigation cache) for each N and each --workers count, with
their stages, the wall time against the issue's 60 s for 100 creatures, and the judgement of
the crowd's own checks (the report's `crowd`).

Run from the repo root:  python benchmarks/bench_crowd.py [--seconds 60] [--runs 3]
[--big-runs 1] [--sizes 1,10,100] [--workers 1,2]   (--runs for N <= 10, --big-runs for
larger crowds; --workers: run each crowd on each count in turns, with their ratio)
                         python benchmarks/bench_crowd.py --bake [--workers 1,2] ...
"""

from __future__ import annotations

import argparse
import hashlib
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from baker.config import BakeConfig, DEFAULT_RIG, load_rig_config
from baker.context import Context
from baker.environment import load_environment
from baker.pipeline import in_local_frame, navigation_surface, validate_bake
from baker.run.crowd import run_crowd
from baker.solve.solve import solve


def min_spine_gap(spines: np.ndarray, bound: float) -> float:
    """Smallest distance between spine joints of different creatures over all frames (inf when
    none come within `bound`). spines : (n, F, S, 3)."""
    n, F, S, _ = spines.shape
    owner = np.repeat(np.arange(n), S)
    best = np.inf
    for f in range(F):
        pts = spines[:, f].reshape(-1, 3)
        pairs = cKDTree(pts).query_pairs(bound, output_type="ndarray")
        pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
        if len(pairs):
            best = min(best, float(np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]],
                                                  axis=1).min()))
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--big-runs", type=int, default=1)
    ap.add_argument("--sizes", default="1,10,100")
    ap.add_argument("--cache-dir", type=Path, default=None)
    ap.add_argument("--bake", action="store_true", help="time whole bakes (see the module)")
    ap.add_argument("--workers", default=None, help="worker counts to time (comma separated) "
                    "[default: 1 for the run stage, the CPUs available with --bake]")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.bake:
        return bench_bakes(args, sizes)
    with tempfile.TemporaryDirectory() as tmp:
        cfg = validate_bake(BakeConfig(seconds=args.seconds, fps=30, seed=0,
                                       rig=load_rig_config(DEFAULT_RIG),
                                       nav_cache_dir=args.cache_dir or Path(tmp)))
        env = load_environment(cfg.environment)
        run_cfg = in_local_frame(cfg, env.origin)
        nav, _ = navigation_surface(run_cfg, env)
        spine_rig = replace(run_cfg.rig, legs=replace(run_cfg.rig.legs, enabled=False))
        two_r = 2.0 * max(run_cfg.rig.body.width_profile)
        med = {}
        workers = [int(w) for w in (args.workers or "1").split(",")]
        print(f"crowd run stage, default scene, {args.seconds:.0f} s at 240 Hz (medians; "
              f"workers {', '.join(map(str, workers))}, taken in turns)")
        for n in sizes:
            times = {w: [] for w in workers}
            digests = {}
            for _ in range(args.runs if n <= 10 else args.big_runs):
                for w in workers:
                    t = time.perf_counter()
                    recs, _ = run_crowd(run_cfg, env, nav, 0, n, Context(), workers=w)
                    times[w].append(time.perf_counter() - t)
                    digests[w] = hashlib.sha256(b"".join(
                        r.heads.tobytes() + r.slither.tobytes() + r.cobra.tobytes()
                        for r in recs)).hexdigest()
            gap = ""
            if n > 1:
                spines = np.stack([solve(r, env.rays, spine_rig).spine_positions for r in recs])
                g = min_spine_gap(spines, 0.5)
                gap = (f"   min spine gap {g * 1000:6.1f} mm" if np.isfinite(g)
                       else "   min spine gap > 500 mm")
                gap += f" (2 x body radius {two_r * 1000:.1f} mm)"
            for w in workers:
                m = statistics.median(times[w])
                med.setdefault(n, m)
                print(f"  N = {n:4d}, {w} worker{'s' * (w > 1)}: {m:8.2f} s   {m / n:6.3f} s per "
                      f"creature   ({n * args.seconds / m:6.1f} creature-seconds per second)"
                      f"{gap}")
            if len(workers) > 1:
                first = statistics.median(times[workers[0]])
                print(f"  N = {n:4d}: " + ", ".join(
                    f"{w} workers {statistics.median(times[w]) / first:.2f}x of {workers[0]}"
                    for w in workers[1:]) + ", the same heads, slither and cobra: "
                    + ("yes" if len(set(digests.values())) == 1 else "NO"))
        if 10 in med and 100 in med:
            print(f"  growth per creature 10 -> 100: {(med[100] / 100) / (med[10] / 10):.2f}x "
                  f"(1.00 = linear; {workers[0]} worker{'s' * (workers[0] > 1)})")
        if 1 in med and 10 in med:
            print(f"  growth per creature 1 -> 10:   {(med[10] / 10) / med[1]:.2f}x")


def bench_bakes(args, sizes: list[int]) -> None:
    """Whole bakes of N creatures on W workers: medians of the wall time and of each stage."""
    from baker.parallel import available_cpus
    from baker.pipeline import bake

    workers = [int(w) for w in (args.workers or str(available_cpus())).split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        cache = args.cache_dir or Path(tmp) / "cache"
        cfg = BakeConfig(seconds=args.seconds, fps=30, seed=0, rig=load_rig_config(DEFAULT_RIG),
                         nav_cache_dir=cache, out=Path(tmp) / "crowd")
        bake(replace(cfg, seconds=1.0))                     # the navigation cache, warm
        print(f"whole bakes, default scene, {args.seconds:.0f} s (medians; target for 100 "
              "creatures: 60 s on 2 cores)")
        per = {}
        for n in sizes:
            for w in workers:
                walls, stages = [], []
                for _ in range(args.runs if n <= 10 else args.big_runs):
                    t = time.perf_counter()
                    res = bake(replace(cfg, creatures=n, workers=w))
                    walls.append(time.perf_counter() - t)
                    stages.append(res.report["timings_s"])
                wall = statistics.median(walls)
                per[n, w] = wall
                st = "  ".join(f"{k} {statistics.median(s[k] for s in stages):.1f}"
                               for k in ("simulate", "metrics", "reduce", "export"))
                crowd = res.report.get("crowd") or {}
                check = ("" if not crowd else
                         f"   spines apart {crowd['spines_apart']}, leg bones in other bodies "
                         f"{crowd['leg_bones_in_other_bodies']}")
                print(f"  N = {n:4d}, {w} worker{'s' * (w > 1)}: {wall:8.1f} s "
                      f"({wall / n:6.2f} s per creature; {st}){check}", flush=True)
        for w in workers:
            if (10, w) in per and (100, w) in per:
                print(f"  growth per creature 10 -> 100, {w} workers: "
                      f"{(per[100, w] / 100) / (per[10, w] / 10):.2f}x (1.00 = linear)")
        for n in sizes:
            if (n, 1) in per and len(workers) > 1:
                print(f"  N = {n}: " + ", ".join(f"{w} workers {per[n, 1] / per[n, w]:.2f}x"
                                                  for w in workers if w != 1))


if __name__ == "__main__":
    main()
