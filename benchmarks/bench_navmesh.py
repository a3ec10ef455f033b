"""Navigation surface benchmarks (printed, not timed tests).

    python benchmarks/bench_navmesh.py [--scene generated|default|nav_test|all] [--repeat N]

Scenes:
- generated: ~1M triangles on 200 x 200 m (terrain, hollow half logs, rocks), agent radius
  0.3 m, cell 0.1 m (issue 3's scale target: build <= 10 s, <= 2 GB peak);
- default:   environments/rainforest_floor.glb with the default rig's agent (as `baker bake`)
  (target: ready in <= 5 s);
- nav_test:  ../shared/fixtures/nav_test.obj (Recast's demo level) with Recast's demo agent
  (radius 0.6, height 2.0, climb 0.9, slope 45 deg, cell 0.3 as in the demo and 0.1).

For every scene it prints the median build time and the median / p90 times of
random_point_near and find_path for targets within a given distance.

Reference (benchmarks/recast_reference.cpp, Recast 1.5.1, cell height 0.05 m) on the generated
scene exported as OBJ: walkable area 37962 m^2 (baker.navmesh: 36967 m^2, -2.6 %), Recast build
2.3 s single-threaded on the same machine.
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from baker.config import DEFAULT_RIG, NavAgentConfig, load_rig_config  # noqa: E402
from baker.environment.model import EnvMesh, Environment, Sun  # noqa: E402
from baker.navmesh import build  # noqa: E402


# --------------------------------------------------------------------------- generated scene
def _half_log(r_in, r_out, length, sections):
    th = np.linspace(0.0, np.pi, sections + 1)
    v = np.zeros((sections + 1, 4, 3))
    for j, (r, z) in enumerate(((r_out, -length / 2), (r_out, length / 2),
                                (r_in, -length / 2), (r_in, length / 2))):
        v[:, j, 0] = r * np.cos(th)
        v[:, j, 1] = r * np.sin(th)
        v[:, j, 2] = z
    f = []
    for i in range(sections):
        a, b = 4 * i, 4 * (i + 1)
        for o0, o1 in ((0, 1), (2, 3), (0, 2), (1, 3)):
            f += [(a + o0, b + o0, b + o1), (a + o0, b + o1, a + o1)]
    for a in (0, 4 * sections):
        f += [(a, a + 2, a + 3), (a, a + 3, a + 1)]
    return v.reshape(-1, 3), np.array(f)


def _sphere(subdiv):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdiv)
    return np.asarray(m.vertices), np.asarray(m.faces)


def generated_scene(seed: int = 0, size: float = 200.0, n_grid: int = 560,
                    n_logs: int = 300, n_rocks: int = 200) -> Environment:
    """Terrain (2 n_grid^2 triangles) + hollow half logs + rocks, about 1M triangles."""
    rng = np.random.default_rng(seed)
    xs = np.linspace(-size / 2, size / 2, n_grid + 1)
    X, Z = np.meshgrid(xs, xs, indexing="ij")
    Y = np.zeros_like(X)
    for _ in range(12):
        k = rng.uniform(0.02, 0.15, 2)
        Y += rng.uniform(0.1, 0.6) * np.sin(k[0] * X + rng.uniform(0, 6)) * np.cos(
            k[1] * Z + rng.uniform(0, 6))
    v = np.stack([X, Y, Z], -1).reshape(-1, 3)
    i = np.arange(n_grid)[:, None] * (n_grid + 1) + np.arange(n_grid)[None, :]
    i = i.ravel()
    f = np.concatenate([np.stack([i, i + 1, i + n_grid + 2], 1),
                        np.stack([i, i + n_grid + 2, i + n_grid + 1], 1)])

    def ground(x, z):
        gi = np.clip(((np.asarray(x) + size / 2) / size * n_grid).astype(int), 0, n_grid)
        gj = np.clip(((np.asarray(z) + size / 2) / size * n_grid).astype(int), 0, n_grid)
        return Y[gi, gj]

    meshes = [EnvMesh("terrain", v.astype(np.float32), f.astype(np.uint32))]
    lv, lf = _half_log(0.45, 0.6, 1.0, 64)
    for k in range(n_logs):
        yaw = rng.uniform(0, np.pi)
        length = rng.uniform(3.0, 8.0)
        c = rng.uniform(-size / 2 + 5, size / 2 - 5, 2)
        vv = lv.copy()
        vv[:, 2] *= length
        R = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
        vv = vv @ R.T + [c[0], float(ground(c[0], c[1])) - 0.1, c[1]]
        meshes.append(EnvMesh(f"log{k}", vv.astype(np.float32), lf.astype(np.uint32)))
    sv, sf = _sphere(3)
    for k in range(n_rocks):
        c = rng.uniform(-size / 2 + 2, size / 2 - 2, 2)
        rad = rng.uniform(0.3, 2.0, 3) * [1.0, 0.6, 1.0]
        vv = sv * rad + [c[0], float(ground(c[0], c[1])) - 0.2 * rad[1], c[1]]
        meshes.append(EnvMesh(f"rock{k}", vv.astype(np.float32), sf.astype(np.uint32)))
    return Environment(tuple(meshes), Sun(np.array([0.0, 1.0, 0.0])), name="generated")


# --------------------------------------------------------------------------- measuring
def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench(name: str, env: Environment, agent: NavAgentConfig, target_dist: float,
          repeat: int, n_queries: int = 200) -> None:
    _ = env.mesh  # merged mesh (loading, not navigation)
    times = []
    s = None
    for _ in range(repeat):
        s = None  # free the previous surface before building again (peak memory)
        t = time.perf_counter()
        s = build(env, agent)
        times.append(time.perf_counter() - t)
    t = time.perf_counter()
    s.prepare()  # lazy query tables (otherwise built by the first queries)
    t_prep = time.perf_counter() - t
    rng = np.random.default_rng(0)
    starts = s.positions[rng.integers(s.n_samples, size=n_queries)].astype(np.float64)
    tr, tp, tn, complete = [], [], [], 0
    for p in starts:
        t = time.perf_counter()
        q = s.random_point_near(p, target_dist, rng)
        tr.append(time.perf_counter() - t)
        if q is None:
            continue
        t = time.perf_counter()
        r = s.find_path(p, q)
        tp.append(time.perf_counter() - t)
        complete += r.complete
        t = time.perf_counter()
        s.nearest(q + [0.0, 0.05, 0.0])
        tn.append(time.perf_counter() - t)
    tr, tp, tn = (np.array(x) * 1e3 for x in (tr, tp, tn))
    both = tr[: len(tp)] + tp
    print(f"{name}: {len(env.mesh.faces):,} triangles, {s.shape[0]} x {s.shape[1]} columns "
          f"(cell {agent.cell_size} m, radius {agent.radius} m)")
    print(f"  build median {np.median(times):.2f} s (n={repeat}), {s.n_samples:,} samples, "
          f"{s.n_components} components, walkable {s.walkable_area:.1f} m^2, "
          f"prepare() {t_prep:.2f} s, "
          f"peak RSS {_peak_mb():.0f} MB")
    print(f"  targets within {target_dist} m: random_point_near median {np.median(tr):.2f} ms, "
          f"find_path median {np.median(tp):.2f} ms (p90 {np.percentile(tp, 90):.2f}, "
          f"max {tp.max():.1f}), both median {np.median(both):.2f} ms, "
          f"nearest median {np.median(tn):.3f} ms; {complete}/{len(tp)} complete")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="all", choices=["generated", "default", "nav_test", "all"])
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    if a.scene in ("default", "all"):
        from baker.environment import load_environment

        p = ROOT / "environments" / "rainforest_floor.glb"
        if p.exists():
            env = load_environment(p)
            # the agent `baker bake` uses on it: the default rig's navigation section
            agent = load_rig_config(DEFAULT_RIG).navigation
            bench("default (rainforest_floor.glb)", env, agent, 2.5, a.repeat)
        else:
            print(f"default: {p} not found, skipped")
    if a.scene in ("nav_test", "all"):
        from baker.environment import load_environment

        p = ROOT.parent / "shared" / "fixtures" / "nav_test.obj"
        if p.exists():
            env = load_environment(p)
            for cell in (0.3, 0.1):
                agent = NavAgentConfig(radius=0.6, height=2.0, step_height=0.9,
                                       max_slope=math.radians(45.0), cell_size=cell)
                bench("nav_test.obj (Recast demo level)", env, agent, 20.0, a.repeat)
        else:
            print(f"nav_test: {p} not found, skipped")
    if a.scene in ("generated", "all"):
        env = generated_scene()
        agent = NavAgentConfig(radius=0.3, height=1.0, step_height=0.3, cell_size=0.1)
        bench("generated 200 x 200 m", env, agent, 10 * 1.0, a.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
