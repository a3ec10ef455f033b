"""Keyframe reduction benchmark: baker's world-space reduction against gltf-transform resample and
gltfpack on the same 60 s default-scene bake.

For each seed it bakes the default scene unreduced (`baker bake --tolerance 0`) and reduced
(`baker bake`, the default --tolerance 0.001 BL; also `--rotations float`), runs the other tools
on the unreduced GLB, and prints one Markdown table per seed:

- animation bytes: the bufferViews that animation samplers read (times and values);
- file size, key count (sum of the samplers' input counts);
- joint error: every joint's world position at every frame (baker.inspect.read_glb) against the
  unreduced file, max and median in mm;
- planted slide: how far a foot moves within one of its stances, stances taken from the unreduced
  file's `foot_contacts` (asset.extras), max over all stances in mm; and skate, the per-frame
  motion of a foot on the ground as baker.inspect.judge measures it from the file (median, %BL;
  against the unreduced file's environment, as the tools may rewrite the meshes);
- the Khronos glTF-Validator's errors / warnings; the tool's run time (baker: its reduce stage).

Run from the repo root:
    python benchmarks/reduction.py [--seconds 60] [--seeds 0,1,2] [--workdir DIR]

The npm tools are installed on first use into ~/.cache/baker-bench/node (outside the repo):
    npm install --prefix ~/.cache/baker-bench/node @gltf-transform/cli@4 gltfpack@1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "tools"))

from baker.inspect import judge, read_glb  # noqa: E402
from glb_read import Glb  # noqa: E402
from validator import gltf_validate, issues_summary  # noqa: E402

NODE_DIR = Path.home() / ".cache" / "baker-bench" / "node"
PACKAGES = ("@gltf-transform/cli@4", "gltfpack@1")


def node_tool(name: str) -> Path:
    """The npm tool `name` in NODE_DIR, installed there on first use."""
    exe = NODE_DIR / "node_modules" / ".bin" / name
    if not exe.exists():
        if shutil.which("npm") is None:
            raise SystemExit("npm is needed for the comparison tools")
        NODE_DIR.mkdir(parents=True, exist_ok=True)
        subprocess.run(["npm", "install", "--no-audit", "--no-fund", "--prefix", str(NODE_DIR),
                        *PACKAGES], check=True, capture_output=True)
    return exe


def bake(out: Path, seconds: float, seed: int, *extra: str) -> dict:
    """`baker bake` of the default scene; returns its JSON report."""
    subprocess.run([sys.executable, "-m", "baker", "bake", "--seconds", str(seconds), "--seed",
                    str(seed), "--format", "glb", "--out", str(out), *extra],
                   check=True, capture_output=True)
    return json.loads(out.with_suffix(".json").read_text())


def animation_stats(path: Path) -> tuple[int, int]:
    """(bytes of the bufferViews animation samplers read, keys: the samplers' input counts)."""
    g = Glb(path.read_bytes())
    doc = g.doc
    views, keys = set(), 0
    for a in doc.get("animations", []):
        for s in a["samplers"]:
            keys += doc["accessors"][s["input"]]["count"]
            views.update(doc["accessors"][s[k]]["bufferView"] for k in ("input", "output"))
    return sum(doc["bufferViews"][v]["byteLength"] for v in views), keys


def stances(extras: dict) -> list[tuple[str, int, int]]:
    """(foot joint, first frame, last frame) of every planted interval in a bake's extras."""
    return [(foot, a, b) for foot, spans in extras.get("foot_contacts", {}).items()
            for a, b in spans]


def measure(path: Path, ref, spans, runtime: float) -> dict:
    """The table row of one file against the unreduced scene `ref` (a BakedScene). Skate is
    judged against the unreduced file's environment (the tools may rewrite the meshes)."""
    scene = dataclasses.replace(read_glb(path), env_vertices=ref.env_vertices,
                                env_faces=ref.env_faces)
    idx = [scene.names.index(n) for n in ref.names]
    err = np.linalg.norm(scene.positions[:, idx] - ref.positions, axis=-1)
    slide = [np.linalg.norm(scene.positions[a:b + 1, scene.index(f)]
                            - scene.positions[a, scene.index(f)], axis=-1).max()
             for f, a, b in spans if b > a]
    report = gltf_validate(path)
    anim_bytes, keys = animation_stats(path)
    return {"anim": anim_bytes, "size": path.stat().st_size, "keys": keys,
            "err_max": err.max() * 1e3, "err_med": float(np.median(err)) * 1e3,
            "slide": max(slide, default=0.0) * 1e3,
            "skate": judge(scene)["metrics"].get("skate_median_pct_bl", 0.0),
            "val": f"{len(issues_summary(report, 0))} / {len(issues_summary(report, 1))}",
            "time": runtime}


def run_seed(work: Path, seconds: float, seed: int) -> list[tuple[str, dict]]:
    base = work / f"s{seed}_unreduced"
    bake(base, seconds, seed, "--tolerance", "0")
    glb = base.with_suffix(".glb")
    ref = read_glb(glb)
    spans = stances(ref.extras)
    rows = [("unreduced", measure(glb, ref, spans, 0.0))]
    for label, extra in (("baker --tolerance 0.001 (default)", ()),
                         ("baker --tolerance 0.001 --rotations float", ("--rotations", "float"))):
        out = work / f"s{seed}_{'float' if extra else 'reduced'}"
        rep = bake(out, seconds, seed, *extra)
        rows.append((label, measure(out.with_suffix(".glb"), ref, spans,
                                    rep["timings_s"]["reduce"])))
    tools = (("gltf-transform resample", "gltf-transform", lambda i, o: ["resample", i, o]),
             ("gltfpack", "gltfpack", lambda i, o: ["-i", i, "-o", o]),
             ("gltfpack -kn -ke", "gltfpack", lambda i, o: ["-kn", "-ke", "-i", i, "-o", o]))
    for label, tool, args in tools:
        out = work / f"s{seed}_{label.replace(' ', '_').replace('-', '')}.glb"
        exe = node_tool(tool)
        t = time.perf_counter()
        subprocess.run([str(exe), *args(str(glb), str(out))], check=True, capture_output=True)
        rows.append((label, measure(out, ref, spans, time.perf_counter() - t)))
    return rows


def table(rows, seconds: float, seed: int) -> str:
    base = rows[0][1]["anim"]
    lines = [f"{seconds:.0f} s default-scene bake, seed {seed}",
             "",
             "| file | animation bytes | ratio | file size | keys | joint error max / median "
             "(mm) | planted slide max (mm) | skate median (%BL) | validator errors / warnings "
             "| run time (s) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|---:|"]
    for label, r in rows:
        lines.append(f"| {label} | {r['anim']:,} | {base / r['anim']:.2f}x | {r['size']:,} | "
                     f"{r['keys']:,} | {r['err_max']:.3f} / {r['err_med']:.4f} | "
                     f"{r['slide']:.3f} | {r['skate']:.4f} | {r['val']} | {r['time']:.2f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated seeds")
    ap.add_argument("--workdir", type=Path, default=None,
                    help="keep the files here (default: a temporary folder)")
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        per_label: dict[str, list[dict]] = {}
        for seed in seeds:
            rows = run_seed(work, args.seconds, seed)
            print(table(rows, args.seconds, seed) + "\n", flush=True)
            for label, r in rows:
                per_label.setdefault(label, []).append({**r, "ratio": rows[0][1]["anim"] / r["anim"]})
    med = statistics.median
    print(f"medians over seeds {args.seeds}:")
    print("| file | animation ratio | joint error max (mm) | planted slide max (mm) "
          "| skate median (%BL) | run time (s) |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, rs in per_label.items():
        print(f"| {label} | {med(r['ratio'] for r in rs):.2f}x | "
              f"{med(r['err_max'] for r in rs):.3f} | {med(r['slide'] for r in rs):.3f} | "
              f"{med(r['skate'] for r in rs):.4f} | {med(r['time'] for r in rs):.2f} |")


if __name__ == "__main__":
    main()
