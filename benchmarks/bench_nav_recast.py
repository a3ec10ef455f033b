"""Navigation build against Recast C++ on the ~1M-triangle level (issue 15): time and memory of
baker.navmesh's build and of benchmarks/recast_reference.cpp (Recast 1.5.1, up to its regions),
both ratios printed by one run.

    python benchmarks/bench_nav_recast.py [--repeat 3] [--recast-bin PATH] [--before TREE]

--before TREE also runs the build of another checkout of baker (e.g. a worktree of the commit
before a change) in the same run, alternated with the others, for before/after figures.

The level is bench_navmesh.generated_scene() (terrain, hollow half logs, rocks, 200 x 200 m),
agent radius 0.3 m, height 1.0 m, climb 0.3 m, slope 60 deg, cell 0.1 m (Recast's cell height
0.05 m). Each build runs in a fresh process, with the mesh loaded (and, for baker, the
environment's ray caster built: the input the simulation shares) before it starts:
- time: the build's wall time, and its CPU time (the fairer figure on a shared machine);
- memory: the peak resident memory during the build (Linux VmHWM, reset through
  /proc/self/clear_refs just before it) above the resident memory before it.
Medians over --repeat processes. Without --recast-bin the reference is compiled with g++
(Debian: apt-get install librecast-dev).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

AGENT = dict(radius=0.3, height=1.0, step_height=0.3, cell_size=0.1, max_slope_deg=60.0)
CELL_HEIGHT = 0.05
TARGET_TIME, TARGET_MEMORY = 1.5, 10.0


def _status_kb(key: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key):
                return int(line.split()[1])
    return 0


def child() -> None:
    """One baker build in this process; prints a JSON line {time_s, memory_mb, samples}."""
    import numpy as np

    from baker.config import NavAgentConfig
    from baker.navmesh import build
    from bench_navmesh import generated_scene

    env = generated_scene()
    _ = env.mesh
    env.rays.cast(np.zeros((1, 3)), np.array([[0.0, -1.0, 0.0]]))  # the ray caster is built
    agent = NavAgentConfig(radius=AGENT["radius"], height=AGENT["height"],
                           step_height=AGENT["step_height"], cell_size=AGENT["cell_size"],
                           max_slope=math.radians(AGENT["max_slope_deg"]))
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    before = _status_kb("VmRSS:")
    t, c = time.perf_counter(), time.process_time()
    s = build(env, agent)
    dt, dc = time.perf_counter() - t, time.process_time() - c
    peak = _status_kb("VmHWM:")
    print(json.dumps({"time_s": dt, "cpu_s": dc, "memory_mb": (peak - before) / 1024.0,
                      "samples": s.n_samples, "walkable_m2": s.walkable_area}))


def write_obj(path: Path) -> int:
    import numpy as np

    from bench_navmesh import generated_scene

    m = generated_scene().mesh
    v = np.asarray(m.vertices, dtype=np.float64)
    f = np.asarray(m.faces, dtype=np.int64) + 1
    with open(path, "w") as fh:
        fh.write("".join(f"v {a:.6f} {b:.6f} {c:.6f}\n" for a, b, c in v.tolist()))
        fh.write("".join(f"f {a} {b} {c}\n" for a, b, c in f.tolist()))
    return len(f)


def recast_binary(tmp: Path, given: str | None) -> Path:
    if given:
        return Path(given)
    out = tmp / "recast_reference"
    subprocess.run(["g++", "-O2", "-o", str(out), str(ROOT / "benchmarks" / "recast_reference.cpp"),
                    "-I/usr/include/recastnavigation", "-lRecast"], check=True)
    return out


def run_recast(binary: Path, obj: Path) -> dict:
    a = AGENT
    out = subprocess.run([str(binary), str(obj), str(a["cell_size"]), str(CELL_HEIGHT),
                          str(a["radius"]), str(a["height"]), str(a["step_height"]),
                          str(a["max_slope_deg"])], check=True, capture_output=True,
                         text=True).stdout
    t = float(re.search(r"build ([\d.]+) s", out).group(1))
    cpu = float(re.search(r"cpu ([\d.]+) s", out).group(1))
    mem = float(re.search(r"build memory ([\d.]+) MB", out).group(1))
    area = float(re.search(r"walkable area ([\d.]+) m", out).group(1))
    return {"time_s": t, "cpu_s": cpu, "memory_mb": mem, "walkable_m2": area}


def run_baker(tree: Path | None = None) -> dict:
    """One build in a fresh process, by this checkout's baker or by `tree`'s (its own copy of
    this script, which puts its tree first on the path)."""
    root = ROOT if tree is None else Path(tree).resolve()
    out = subprocess.run([sys.executable, str(root / "benchmarks" / Path(__file__).name),
                          "--child"], check=True, capture_output=True, text=True,
                         cwd=root).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--recast-bin")
    ap.add_argument("--before", type=Path, help="another checkout of baker, run alongside")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child()
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        obj = tmp / "generated.obj"
        n = write_obj(obj)
        binary = recast_binary(tmp, a.recast_bin)
        rec, ours, old = [], [], []
        for _ in range(a.repeat):   # alternated, so all see the same machine load
            rec.append(run_recast(binary, obj))
            ours.append(run_baker())
            if a.before:
                old.append(run_baker(a.before))
    med = statistics.median
    r = {k: med(x[k] for x in rec) for k in ("time_s", "cpu_s", "memory_mb")}
    print(f"generated level: {n:,} triangles, cell {AGENT['cell_size']} m, {a.repeat} runs each, "
          f"medians")
    print(f"  Recast C++ : build {r['time_s']:.2f} s (CPU {r['cpu_s']:.2f} s), memory "
          f"{r['memory_mb']:.0f} MB, walkable {rec[0]['walkable_m2']:.0f} m^2")
    for label, runs in (("baker", ours), (f"baker ({a.before})", old)):
        if not runs:
            continue
        b = {k: med(x[k] for x in runs) for k in ("time_s", "cpu_s", "memory_mb")}
        tr, cr, mr = (b[k] / r[k] for k in ("time_s", "cpu_s", "memory_mb"))
        print(f"  {label}: build {b['time_s']:.2f} s (CPU {b['cpu_s']:.2f} s), memory "
              f"{b['memory_mb']:.0f} MB, walkable {runs[0]['walkable_m2']:.0f} m^2, "
              f"{runs[0]['samples']:,} samples")
        print(f"    ratio to Recast: time {tr:.2f}x, CPU {cr:.2f}x (target <= {TARGET_TIME}x: "
              f"{'met' if tr <= TARGET_TIME else 'NOT met'}), memory {mr:.1f}x "
              f"(target <= {TARGET_MEMORY:g}x: {'met' if mr <= TARGET_MEMORY else 'NOT met'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
