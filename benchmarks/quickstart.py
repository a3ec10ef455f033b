"""Quick-start benchmark: the bake a fresh clone runs first, timed the way a user runs it.

`baker bake` (no options: the default bake, the showcase's minute with 2 prey) through the CLI, in a subprocess (imports included), with an
empty --cache-dir (cold: the navigation surface is built) and again with the same cache (warm),
median of --runs each. Prints the wall time of each, the per-stage timings from the bake's JSON
report (`timings_s`), the share of the wall time the stages do not account for (interpreter
start, imports, option checks, writing the outputs), and the targets: issue 14's 15 s on 2
cores for the quick start, issue 15's 0.2 s for `baker --help` (median of --help-runs).

Run from the repo root:
    python benchmarks/quickstart.py [--runs 3] [--help-runs 7] [-- EXTRA BAKE ARGS]

Whatever follows `--` is passed on to `baker bake` (e.g. `-- --seed 3`), so the script measures
whatever the default scene and options are.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

QUICK_START: tuple[str, ...] = ()    # the README's quick start gives no option
TARGET_BAKE_S = 15.0
TARGET_HELP_S = 0.2


def baker(*args: str) -> list[str]:
    """The `baker` command as a fresh clone's venv runs it (the console script's entry point)."""
    return [sys.executable, "-m", "baker", *args]


def timed_bake(out: Path, cache: Path, extra: list[str]) -> tuple[float, dict]:
    """One CLI bake; returns (wall seconds, the report's timings_s)."""
    cmd = baker("bake", *QUICK_START, "--out", str(out), "--cache-dir", str(cache), *extra)
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"bake failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr}")
    report = json.loads(out.with_suffix(".json").read_text())
    return wall, report["timings_s"]


def help_time(runs: int) -> float:
    """Median wall seconds of `baker --help`."""
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        subprocess.run(baker("--help"), check=True, capture_output=True)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def stage_line(label: str, wall: list[float], stages: list[dict]) -> str:
    med = statistics.median
    names = list(dict.fromkeys(k for s in stages for k in s))
    per = {k: med([s.get(k, 0.0) for s in stages]) for k in names}
    rest = med(wall) - sum(per.values())
    parts = ", ".join(f"{k} {v:.2f}" for k, v in per.items())
    return (f"  {label:5s} {med(wall):6.2f} s wall (runs: {', '.join(f'{w:.2f}' for w in wall)})"
            f"\n        stages: {parts}\n        outside the stages (start, imports, checks, "
            f"commit): {rest:.2f} s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--help-runs", type=int, default=7)
    ap.add_argument("extra", nargs="*", help="extra `baker bake` arguments (after --)")
    args = ap.parse_args(argv)
    cold, warm, cold_st, warm_st = [], [], [], []
    with tempfile.TemporaryDirectory(prefix="baker-quickstart-") as tmp:
        tmp = Path(tmp)
        for i in range(args.runs):
            cache = tmp / f"cache{i}"                  # empty: a fresh clone's first bake
            t, st = timed_bake(tmp / f"cold{i}", cache, args.extra)
            cold.append(t)
            cold_st.append(st)
            t, st = timed_bake(tmp / f"warm{i}", cache, args.extra)
            warm.append(t)
            warm_st.append(st)
    helps = help_time(args.help_runs)
    print(f"quick start: baker bake {' '.join(QUICK_START + tuple(args.extra))} "
          f"(CLI subprocess, medians of {args.runs})")
    print(stage_line("cold", cold, cold_st))
    print(stage_line("warm", warm, warm_st))
    print(f"  target (issue 14): cold <= {TARGET_BAKE_S:.0f} s: "
          f"{'met' if statistics.median(cold) <= TARGET_BAKE_S else 'NOT met'} "
          f"({statistics.median(cold) / TARGET_BAKE_S:.2f} of it)")
    print(f"baker --help: {helps:.3f} s (median of {args.help_runs}); target (issue 15) <= "
          f"{TARGET_HELP_S} s: {'met' if helps <= TARGET_HELP_S else 'NOT met'}")


if __name__ == "__main__":
    main()
