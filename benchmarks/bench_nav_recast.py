"""Navigation build against Recast C++ on the ~1M-triangle level (issue 15): time and memory of
baker.navmesh's build and of benchmarks/recast_reference.cpp (Recast 1.5.1, up to its regions),
both ratios printed by one run.

    python benchmarks/bench_nav_recast.py [--repeat 3] [--recast-bin PATH]

The level is bench_navmesh.generated_scene() (terrain, hollow half logs, rocks, 200 x 200 m),
agent radius 0.3 m, height 1.0 m, climb 0.3 m, slope 60 deg, cell 0.1 m (Recast's cell height
0.05 m). Each build runs in a fresh process, with the mesh loaded (and, for baker, the
environment's ray caster built: the input the simulation shares) before it starts:
- time: the build's wall time;
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
    t = time.perf_counter()
    s = build(env, agent)
    dt = time.perf_counter() - t
    peak = _status_kb("VmHWM:")
    print(json.dumps({"time_s": dt, "memory_mb": (peak - before) / 1024.0,
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
    mem = float(re.search(r"build memory ([\d.]+) MB", out).group(1))
    area = float(re.search(r"walkable area ([\d.]+) m", out).group(1))
    return {"time_s": t, "memory_mb": mem, "walkable_m2": area}


def run_baker() -> dict:
    out = subprocess.run([sys.executable, __file__, "--child"], check=True, capture_output=True,
                         text=True, cwd=ROOT).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--recast-bin")
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
        rec, ours = [], []
        for _ in range(a.repeat):   # alternated, so both see the same machine load
            rec.append(run_recast(binary, obj))
            ours.append(run_baker())
    med = statistics.median
    rt, rm = med(r["time_s"] for r in rec), med(r["memory_mb"] for r in rec)
    bt, bm = med(r["time_s"] for r in ours), med(r["memory_mb"] for r in ours)
    print(f"generated level: {n:,} triangles, cell {AGENT['cell_size']} m, {a.repeat} runs each, "
          f"medians")
    print(f"  Recast C++ : build {rt:.2f} s, memory {rm:.0f} MB, walkable "
          f"{rec[0]['walkable_m2']:.0f} m^2")
    print(f"  baker      : build {bt:.2f} s, memory {bm:.0f} MB, walkable "
          f"{ours[0]['walkable_m2']:.0f} m^2, {ours[0]['samples']:,} samples")
    print(f"  ratio      : time {bt / rt:.2f}x (target <= {TARGET_TIME}x: "
          f"{'met' if bt / rt <= TARGET_TIME else 'NOT met'}), memory {bm / rm:.1f}x "
          f"(target <= {TARGET_MEMORY:g}x: {'met' if bm / rm <= TARGET_MEMORY else 'NOT met'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
