"""Quality sweep: bake many (scene, seed) pairs in parallel processes and judge every bake from
its files (baker.inspect: the GLB and USD read back, the Khronos glTF validator and
pxr.UsdValidation), then print per-limit pass rates per scene and the worst bakes with the joint
and frame of each worst value.

Scenes: the default bake (`default`: the bundled showcase, environments/showcase.glb, 60 s,
2 prey, its turning sun); ../shared/fixtures/nav_test.obj with the 2 m rig (--scale 8, 120 s;
skipped when ../shared is absent); the generated multi-storey level (environments/
multistorey.glb, 2 m rig, 120 s); the default bake moved 10 km from the origin (`far`); the
other bundled scene (`floor`: environments/rainforest_floor.glb, 60 s, no prey).

    python benchmarks/quality_sweep.py                      # 50 default seeds, 10 per other scene
    python benchmarks/quality_sweep.py --scenes default --default-seeds 8 --seed-base 5000
    python benchmarks/quality_sweep.py --scenes "" --level mylevel.glb@8 --other-seeds 4

--level PATH[@SCALE] sweeps a level of your own too (repeatable: --other-seeds seeds each,
--level-seconds long, --level-prey prey, the rig scaled by SCALE).

--creatures N bakes crowds: every creature of a bake is judged on every limit (the bake's row
holds each limit's worst creature), and the crowd's own checks count as two more limits:
`crowd_spines_apart` (no two creatures' spine joints closer than twice the body radius) and
`crowd_leg_bones_in_other_bodies` (no walking or ultimate leg bone through another body).
With fewer crowds than --workers, each crowd's bake runs on the cores left over (--workers of
the bake: the same bytes).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "fixtures"
VALIDATOR = ROOT / "tests" / "tools" / "gltf_validate.mjs"
#: 10 km from the origin, on both horizontal axes
FAR_OFFSET = (10000.0, 0.0, 10000.0)

#: numbers printed for diagnosis (not limits of their own)
DIAGNOSTICS = tuple(f"rotation_{kind}_{group}_deg" for group in
                    ("spine", "legs", "antennae", "ultimate") for kind in ("local", "world")) + (
    "antenna_bone_hits", "foot_near_ground_fraction", "head_unsupported_frames")

SCENES = {
    "default": dict(env="environments/showcase.glb", scale=None, seconds=60.0, prey=2),
    "nav_test": dict(env=str(SHARED / "nav_test.obj"), scale=8.0, seconds=120.0),
    "multistorey": dict(env="environments/multistorey.glb", scale=8.0, seconds=120.0),
    "far": dict(env="far", scale=None, seconds=60.0, prey=2),
    "floor": dict(env="environments/rainforest_floor.glb", scale=None, seconds=60.0),
}


def moved_glb(src: Path, dst: Path, offset) -> Path:
    """A copy of a GLB whose scene hangs under one extra root node translated by `offset`."""
    data = src.read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    rest = data[20 + jlen:]
    scene = doc["scenes"][doc.get("scene", 0)]
    doc["nodes"].append({"name": "far_offset", "translation": [float(x) for x in offset],
                         "children": scene["nodes"]})
    scene["nodes"] = [len(doc["nodes"]) - 1]
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    out = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + len(rest))
    out += struct.pack("<I4s", len(js), b"JSON") + js + rest
    dst.write_bytes(out)
    return dst


def level_scene(spec: str, seconds: float, prey: int) -> tuple[str, dict]:
    """(name, SCENES entry) of `--level PATH[@SCALE]`: any level file baker reads, with the rig
    scaled by SCALE (none: as it is); named by the file's stem (and @SCALE)."""
    path, at, scale = spec.rpartition("@")
    if not at:
        path, scale = spec, ""
    try:
        factor = float(scale) if scale else None
    except ValueError:
        raise SystemExit(f"--level {spec!r}: the scale after @ must be a number") from None
    p = Path(path).resolve()
    if not p.is_file():
        raise SystemExit(f"--level {spec!r}: no such file")
    name = p.stem + (f"@{scale}" if scale else "")
    return name, dict(env=str(p), scale=factor, seconds=seconds, prey=prey)


def register_scenes(extra: dict) -> None:
    """Add `--level` scenes to SCENES (in this process, and in each worker as it starts)."""
    SCENES.update(extra)


def scene_environment(scene: str, work: Path) -> Path | None:
    """The environment file of a sweep scene (None when it is not available here)."""
    if scene == "far":
        path = work / "showcase_far.glb"
        if not path.exists():
            moved_glb(ROOT / SCENES["default"]["env"], path, FAR_OFFSET)
        return path
    path = Path(SCENES[scene]["env"])
    path = path if path.is_absolute() else ROOT / path
    return path if path.exists() else None


def make_config(env: Path, scene: str, seed: int, seconds: float, out: Path, cache: Path,
                creatures: int = 1, workers: int = 1):
    from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config, override_rig

    rig = override_rig(load_rig_config(DEFAULT_RIG), scale=SCENES[scene]["scale"])
    return BakeConfig(environment=env, seconds=seconds, fps=30, seed=seed, rig=rig, out=out,
                      formats=("glb", "usd"), nav_cache_dir=cache,
                      prey=SCENES[scene].get("prey", 0), creatures=creatures, workers=workers)


def ensure_validator() -> bool:
    """Install the pinned Khronos glTF validator into tests/tools (npm ci) when node and npm
    are on PATH and it is not there yet; True when it can run."""
    node, npm = shutil.which("node"), shutil.which("npm")
    installed = (VALIDATOR.parent / "node_modules" / "gltf-validator").is_dir()
    if node and npm and not installed:
        subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"],
                       cwd=VALIDATOR.parent, capture_output=True, text=True, timeout=600)
        installed = (VALIDATOR.parent / "node_modules" / "gltf-validator").is_dir()
    return bool(node) and installed


def gltf_validator_errors(path: Path) -> int | None:
    """Errors the Khronos glTF validator reports (None when node or the validator is missing)."""
    node = shutil.which("node")
    if node is None or not (VALIDATOR.parent / "node_modules" / "gltf-validator").is_dir():
        return None
    r = subprocess.run([node, str(VALIDATOR), str(path)], cwd=VALIDATOR.parent,
                       capture_output=True, text=True, timeout=600)
    if r.returncode not in (0, 1):
        return None
    return int(json.loads(r.stdout)["issues"]["numErrors"])


def usd_validator_errors(path: Path) -> int:
    from pxr import Usd, UsdValidation

    stage = Usd.Stage.Open(str(path))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return sum(e.GetType() == UsdValidation.ValidationErrorType.Error for e in ctx.Validate(stage))


def sim_world_positions(result, creature: int = 0) -> dict[str, np.ndarray]:
    """{joint name: (F, 3) float64 world positions} of every driven joint of a creature, as the
    simulation placed them (its own float64 numbers, offset by the environment's origin)."""
    traj = result.trajectories[creature]
    origin = np.asarray(result.report.get("environment", {}).get("origin", (0.0, 0.0, 0.0)),
                        dtype=np.float64)
    spine = ("head",) + tuple(f"trunk_{k:02d}" for k in range(1, traj.spine_positions.shape[1]))
    out = {n: traj.spine_positions[:, k] + origin for k, n in enumerate(spine)}
    for k, n in enumerate(traj.joint_names):
        out[n] = traj.joint_positions[:, k] + origin
    return out


def judge_creatures(res, glb: Path, usd: Path, creatures: int) -> tuple[dict, dict]:
    """(metrics, worst) of a bake (inspect.judge_creatures): each limit's value is its worst
    creature's (a crowd's `worst` entries name the creature), diagnostics their largest."""
    from baker.inspect import judge_creatures as judge_each, worst_over

    return worst_over(judge_each(glb, usd, [sim_world_positions(res, i)
                                            for i in range(creatures)]))


def crowd_failures(report: dict) -> list[str]:
    """The crowd's own checks (the report's `crowd`) that a bake breaks."""
    crowd = report.get("crowd")
    if not crowd:
        return []
    return (["crowd_spines_apart"] * (not crowd["spines_apart"])
            + ["crowd_leg_bones_in_other_bodies"] * bool(crowd["leg_bones_in_other_bodies"]))


def bake_and_judge(scene: str, seed: int, seconds: float, work: str, keep: bool = False,
                   cache: str | None = None, creatures: int = 1, workers: int = 1) -> dict:
    """One sweep job: bake, read both files back, judge (every creature), validate. Returns a
    row. cache: navigation cache folder (default: WORK/navcache); workers: a crowd's
    processes (the same bytes whatever their number)."""
    from baker.context import Context
    from baker.inspect import failures
    from baker.pipeline import bake

    work = Path(work)
    env = scene_environment(scene, work)
    out = work / "bakes" / f"{scene}_{seed}"
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    row = {"scene": scene, "seed": seed, "seconds": seconds}
    try:
        res = bake(make_config(env, scene, seed, seconds, out,
                               Path(cache) if cache else work / "navcache", creatures, workers),
                   ctx=Context())
    except Exception as ex:  # noqa: BLE001 - a crashing bake is a result of the sweep
        row.update(error=f"{type(ex).__name__}: {ex}", failures=["bake"])
        return row
    row["bake_s"] = time.perf_counter() - t0
    glb, usd = out.with_suffix(".glb"), out.with_suffix(".usd")
    m, worst = judge_creatures(res, glb, usd, creatures)
    g_err = gltf_validator_errors(glb)
    m["validator_errors"] = None if g_err is None else g_err + usd_validator_errors(usd)
    m["distance_walked_m"] = res.report["metrics"]["distance_walked_m"]
    crowd = res.report.get("crowd") or {}
    for key in ("min_spine_gap_body_radii", "leg_bones_in_other_bodies"):
        if key in crowd:
            m["crowd_" + key] = crowd[key]
    row.update(metrics=m, worst=worst, failures=failures(m) + crowd_failures(res.report),
               judge_s=time.perf_counter() - t0 - row["bake_s"])
    if not keep:
        for p in (glb, usd, out.with_suffix(".json")):
            p.unlink(missing_ok=True)
    return row


def warm_navigation(scene: str, work: Path) -> None:
    """Build (or load) the scene's navigation surface once, before the parallel bakes."""
    from baker.environment import load_environment
    from baker.pipeline import navigation_surface

    env_path = scene_environment(scene, work)
    cfg = make_config(env_path, scene, 0, 1.0, work / "warm", work / "navcache")
    navigation_surface(cfg, load_environment(env_path))


def jobs_for(args) -> list[tuple[str, int, float]]:
    jobs = []
    for scene in args.scenes:
        n = args.default_seeds if scene == "default" else args.other_seeds
        secs = args.seconds or SCENES[scene]["seconds"]
        jobs += [(scene, args.seed_base + i, secs) for i in range(n)]
    return jobs


def print_table(rows: list[dict], scenes: list[str]) -> None:
    from baker.inspect import LIMITS

    names = [n for n, _, _ in LIMITS]
    print("\nPass rates (bakes meeting each limit / bakes judged on it):\n")
    print("| limit | " + " | ".join(scenes) + " |")
    print("|---|" + "---|" * len(scenes))
    crowd = any("crowd_min_spine_gap_body_radii" in r.get("metrics", {}) for r in rows)
    names += ["crowd_spines_apart", "crowd_leg_bones_in_other_bodies"] * crowd
    for name in ["bake"] + names:
        cells = []
        for s in scenes:
            rs = [r for r in rows if r["scene"] == s]
            judged = [r for r in rs if name == "bake" or name.startswith("crowd_")
                      or r.get("metrics", {}).get(name) is not None]
            ok = sum(name not in r.get("failures", []) for r in judged)
            cells.append(f"{ok}/{len(judged)}" if judged else "-")
        print(f"| {name} | " + " | ".join(cells) + " |")


def print_worst(rows: list[dict], top: int) -> None:
    from baker.inspect import LIMITS

    print("\nWorst bakes per limit (value, joint, frame):")
    for name, op, bound in LIMITS:
        rs = [r for r in rows if r.get("metrics", {}).get(name) is not None]
        if not rs:
            continue
        sign = -1.0 if op == ">=" else 1.0
        rs.sort(key=lambda r: -sign * r["metrics"][name])
        parts = []
        for r in rs[:top]:
            w = r["worst"].get(name, {})
            where = f" {w.get('joint')}@{w.get('frame')}" if w.get("joint") else ""
            where += f" creature {w['creature']}" if "creature" in w else ""
            parts.append(f"{r['scene']}/{r['seed']}={r['metrics'][name]:.4g}{where}")
        print(f"  {name} ({op} {bound:g}): " + "; ".join(parts))
    print("\nDiagnostics (largest values):")
    for name in DIAGNOSTICS:
        rs = sorted((r for r in rows if r.get("metrics", {}).get(name) is not None),
                    key=lambda r: -r["metrics"][name])
        if rs:
            print(f"  {name}: " + "; ".join(f"{r['scene']}/{r['seed']}={r['metrics'][name]:.4g}"
                                            for r in rs[:top]))
    for r in rows:
        if "error" in r:
            print(f"  bake failed: {r['scene']}/{r['seed']}: {r['error']}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="default,nav_test,multistorey,far,floor")
    ap.add_argument("--default-seeds", type=int, default=50)
    ap.add_argument("--other-seeds", type=int, default=10)
    ap.add_argument("--seed-base", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=None, help="override every scene's duration")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--work", type=Path, default=None, help="work folder (default: a temp dir)")
    ap.add_argument("--keep", action="store_true", help="keep the baked files")
    ap.add_argument("--json", type=Path, default=None, help="write every row here")
    ap.add_argument("--top", type=int, default=3)
    ap.add_argument("--creatures", type=int, default=1, help="bake crowds of N (every creature "
                    "judged; see the module)")
    ap.add_argument("--level", action="append", default=[], metavar="PATH[@SCALE]",
                    help="also sweep this level (--other-seeds seeds), the rig scaled by SCALE; "
                         "repeatable")
    ap.add_argument("--level-seconds", type=float, default=60.0)
    ap.add_argument("--level-prey", type=int, default=1)
    args = ap.parse_args(argv)
    args.scenes = [s for s in args.scenes.split(",") if s]
    extra = dict(level_scene(spec, args.level_seconds, args.level_prey) for spec in args.level)
    register_scenes(extra)
    args.scenes += [name for name in extra if name not in args.scenes]
    work = args.work or Path(tempfile.mkdtemp(prefix="baker-sweep-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        return sweep(args, extra, work)
    finally:
        # a temp work folder goes (its navigation caches and bakes: up to a gigabyte a sweep)
        if args.work is None and not args.keep:
            shutil.rmtree(work, ignore_errors=True)


def sweep(args, extra: dict, work: Path) -> int:
    """main's sweep in the work folder `work`: bake, judge, print; the exit code."""
    missing = [s for s in args.scenes if scene_environment(s, work) is None]
    for s in missing:
        print(f"scene {s}: environment not found, skipped")
    args.scenes = [s for s in args.scenes if s not in missing]
    t0 = time.perf_counter()
    if not ensure_validator():
        print("the Khronos glTF validator is not available (node and npm): GLBs are not validated")
    for s in args.scenes:
        warm_navigation(s, work)
    jobs = jobs_for(args)
    rows = []
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             initializer=register_scenes, initargs=(extra,)) as pool:
        # fewer crowds than workers: each crowd's bake shares out the cores left over
        per = max(1, args.workers // max(len(jobs), 1)) if args.creatures > 1 else 1
        futs = [pool.submit(bake_and_judge, s, seed, secs, str(work), args.keep, None,
                            args.creatures, per) for s, seed, secs in jobs]
        for i, f in enumerate(as_completed(futs), 1):
            r = f.result()
            rows.append(r)
            bad = ", ".join(r.get("failures", [])) or "ok"
            print(f"[{i}/{len(jobs)}] {r['scene']}/{r['seed']}: {bad}", flush=True)
    rows.sort(key=lambda r: (args.scenes.index(r["scene"]), r["seed"]))
    print_table(rows, args.scenes)
    print_worst(rows, args.top)
    clean = sum(not r.get("failures") for r in rows)
    print(f"\n{clean}/{len(rows)} bakes meet every limit; {time.perf_counter() - t0:.0f} s "
          f"with {args.workers} workers")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=float))
    return 0 if clean == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
