"""Measured peak memory and time of navigation builds vs the budget estimate
(baker.navmesh.budget.estimate). Each build runs in its own process; peak RSS from
VmHWM from /proc/self/status of that process (ru_maxrss would carry the parent's peak
across fork and exec). Prints one row per cell size.

    python benchmarks/bench_nav_budget.py [cell sizes in metres...]
"""

import json
import subprocess
import sys

CHILD = r"""
import json, sys, time
from dataclasses import replace
from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, load_rig_config
from baker.environment import load_environment
from baker.navmesh import budget
from baker.navmesh.build import build, _grid
cell = float(sys.argv[1])
env = load_environment(FLOOR_ENVIRONMENT)
agent = replace(load_rig_config(DEFAULT_RIG).navigation, cell_size=cell)
x0, z0, nx, nz, _ = _grid(env, None, cell)
est = budget.estimate(nx * nz, len(env.mesh.faces))
def vmhwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
before = vmhwm()
t = time.perf_counter()
s = build(env, agent)
dt = time.perf_counter() - t
peak = vmhwm()
print(json.dumps({"cell": cell, "columns": nx * nz, "samples": int(len(s.positions)),
                  "before_mb": before / 1e6, "peak_mb": peak / 1e6, "seconds": dt,
                  "est_mb": est.bytes / 1e6, "est_s": est.seconds}))
"""


def main(cells):
    print("| cell (m) | columns | samples | peak RSS (MB) | estimate (MB) | build (s) | estimate (s) |")
    print("|---|---|---|---|---|---|---|")
    for c in cells:
        out = subprocess.run([sys.executable, "-c", CHILD, str(c)], capture_output=True,
                             text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"| {r['cell']:g} | {r['columns']:,} | {r['samples']:,} | {r['peak_mb']:.0f} | "
              f"{r['est_mb']:.0f} | {r['seconds']:.2f} | {r['est_s']:.1f} |", flush=True)


if __name__ == "__main__":
    main([float(x) for x in sys.argv[1:]] or [0.03, 0.015, 0.01, 0.0075])
