"""Long-body benchmark: how a bake's stages grow with the number of body segments.

Bakes the default scene with the default rig changed only in `body.segments` (and its
`width_profile`, the default profile resampled to that many values), for each segment count and
bake length given, in fresh processes (`baker bake --no-cache`), and prints one row per bake:
the stages' times from the bake's report, the keys before and after the keyframe reduction and
its largest world error. The skeleton's chains are about segments + 3 joints deep; the
reduction's world refinement blames each offending joint over all of them.

Run from the repo root:
    python benchmarks/bench_long_body.py [--segments 21,100,255] [--seconds 5,10]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RIG = ROOT / "rigs" / "scolopendra.toml"


def long_rig(segments: int, path: Path) -> Path:
    """The default rig with `segments` body segments (its width profile resampled)."""
    text = RIG.read_text()
    m = re.search(r"^width_profile = \[([^\]]*)\]", text, flags=re.M)
    base = np.array([float(x) for x in m.group(1).replace("\n", " ").split(",") if x.strip()])
    widths = np.interp(np.linspace(0, len(base) - 1, segments), np.arange(len(base)), base)
    text = text[:m.start()] + "width_profile = [" + ", ".join(f"{w:.4f}" for w in widths) \
        + "]" + text[m.end():]
    text = re.sub(r"^segments = \d+", f"segments = {segments}", text, count=1, flags=re.M)
    path.write_text(text)
    return path


def bake(segments: int, seconds: float, tmp: Path) -> dict:
    rig = long_rig(segments, tmp / f"rig{segments}.toml")
    out = tmp / f"s{segments}_{seconds:g}" / "c"
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "baker", "bake", "--rig", str(rig), "--seconds",
                    str(seconds), "--no-cache", "--format", "glb", "--out", str(out)],
                   check=True, capture_output=True, cwd=ROOT)
    wall = time.perf_counter() - t
    report = json.loads(out.with_suffix(".json").read_text())
    anim = report.get("animation", {})
    return {"wall": wall, "timings": report.get("timings_s", {}), "anim": anim}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--segments", default="21,100,255")
    ap.add_argument("--seconds", default="5,10")
    a = ap.parse_args(argv)
    print("| segments | bake length (s) | wall (s) | simulate (s) | reduce (s) | keys before | "
          "keys after | max error (mm) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(x) for x in a.segments.split(",")):
            for s in (float(x) for x in a.seconds.split(",")):
                r = bake(n, s, Path(tmp))
                t, an = r["timings"], r["anim"]
                err = an.get("max_error_m")
                print(f"| {n} | {s:g} | {r['wall']:.1f} | {t.get('simulate', 0):.1f} | "
                      f"{t.get('reduce', 0):.1f} | {an.get('keys_before', '')} | "
                      f"{an.get('keys_after', '')} | "
                      f"{'' if err is None else f'{1000 * err:.3f}'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
