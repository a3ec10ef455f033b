"""Legs benchmark: a 60 s bake at 30 fps of the default scene with legs and spine-only
(legs.enabled = false), both with a cold and with a warm navigation cache. Issue 5: legs may add
at most 2x to the spine-only bake time.

Prints medians of several runs, the per-stage split and the ratios. Run from the repo root:
    python benchmarks/bench_legs.py [--runs 3] [--seconds 60]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from dataclasses import replace
from pathlib import Path

from baker.config import DEFAULT_RIG, load_rig_config
from bench_bake import timed_bake


def one(seconds: float, legs: bool, cache: Path, out: Path):
    rig = load_rig_config(DEFAULT_RIG)
    return timed_bake(seconds, cache, out, rig=replace(rig, legs=replace(rig.legs, enabled=legs)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    med = statistics.median
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for legs in (False, True):
            cold, warm, stages = [], [], []
            for i in range(args.runs):
                cache = tmp / f"cache_{legs}_{i}"
                cold.append(one(args.seconds, legs, cache, tmp)[0])
                t, st = one(args.seconds, legs, cache, tmp)
                warm.append(t)
                stages.append(st)
            res[legs] = (med(cold), med(warm), {k: med([s.get(k, 0.0) for s in stages])
                                                for k in stages[0]})
    print(f"bake {args.seconds:.0f} s @ 30 fps, default scene, {args.runs} runs (medians)")
    for legs, name in ((False, "spine only"), (True, "with legs ")):
        cold, warm, st = res[legs]
        print(f"  {name}: cold nav cache {cold:6.2f} s, warm {warm:6.2f} s   warm stages: "
              + ", ".join(f"{k} {v:.3f}" for k, v in st.items()))
    print(f"  ratio legs / spine-only: cold {res[True][0] / res[False][0]:.2f}x, "
          f"warm {res[True][1] / res[False][1]:.2f}x   (issue 5: at most 2x)")


if __name__ == "__main__":
    main()
