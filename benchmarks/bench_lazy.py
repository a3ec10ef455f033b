"""Lazy navigation windows on a level far too big to build whole for the creature (printed,
not a timed test).

    python benchmarks/bench_lazy.py [--seconds S] [--repeat N]

The generated ~1M-triangle, 200 x 200 m scene of bench_navmesh.py (terrain, hollow logs, rocks)
walked by the default 0.25 m rig: at its 1.5 cm cells the whole level would be 178 million
columns (MAX_COLUMNS is 40 million), so `baker bake` builds it lazily (navmesh/lazy.py). Each
run is a fresh process with a cold navigation cache; it prints the median bake time, the time
spent building windows, the windows' area against the level's, and peak memory.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

RUN = r"""
import json, resource, sys, time
from pathlib import Path
from baker.config import BakeConfig
from baker.pipeline import bake
t = time.perf_counter()
r = bake(BakeConfig(environment=Path(sys.argv[1]), seconds=float(sys.argv[2]), seed=int(sys.argv[3]),
                    out=Path(sys.argv[4]), formats=("glb",), nav_cache_dir=Path(sys.argv[5])))
print(json.dumps({"total": time.perf_counter() - t, "timings": r.report["timings_s"],
                  "windows": r.report["navmesh"]["lazy_windows"],
                  "walked": r.report["metrics"]["distance_walked_m"],
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}))
"""


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)
    from bench_navmesh import generated_scene
    from baker.config import DEFAULT_RIG, load_rig_config
    from baker.export.gltf import build_glb
    from baker.navmesh.lazy import full_columns

    env = generated_scene()
    agent = load_rig_config(DEFAULT_RIG).navigation
    with tempfile.TemporaryDirectory() as tmp:
        level = Path(tmp) / "generated.glb"
        level.write_bytes(build_glb(env, None, None, extras={}))
        lo, hi = env.bounds
        area = float((hi[0] - lo[0]) * (hi[2] - lo[2]))
        print(f"level: {len(env.mesh.faces):,} triangles, {hi[0] - lo[0]:.0f} x {hi[2] - lo[2]:.0f} m; "
              f"whole grid at cell {agent.cell_size} m: {full_columns(env, agent.cell_size):,} columns")
        rows = []
        for i in range(a.repeat):
            out = subprocess.run([sys.executable, "-c", RUN, str(level), str(a.seconds), str(i),
                                  str(Path(tmp) / f"o{i}"), str(Path(tmp) / f"cache{i}")],
                                 check=True, capture_output=True, text=True, cwd=ROOT)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            x0, z0, x1, z1 = r["windows"][-1]
            r["area"] = (x1 - x0) * (z1 - z0)
            rows.append(r)
            print(f"seed {i}: bake {r['total']:.2f} s, first window {r['timings']['navmesh']:.2f} s, "
                  f"simulate (with any growth) {r['timings']['simulate']:.2f} s, "
                  f"{len(r['windows'])} window(s), last {x1 - x0:.1f} x {z1 - z0:.1f} m "
                  f"({100 * r['area'] / area:.2f} % of the level), walked {r['walked']:.1f} m, "
                  f"peak {r['peak_mb']:.0f} MB")
        med = lambda k: float(np.median([r[k] for r in rows]))  # noqa: E731
        print(f"median of {a.repeat}: {a.seconds:g} s bake in {med('total'):.2f} s, "
              f"peak {med('peak_mb'):.0f} MB, window {100 * med('area') / area:.2f} % of the level")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
