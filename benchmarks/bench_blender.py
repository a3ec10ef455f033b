"""The bake against Blender: `baker bake` (CLI, warm navigation cache, default scene, 60 s at
30 fps: simulation, keyframe reduction, GLB + USD + JSON) against Blender (bpy) merely keying a
clip of the same size on an armature of the same joints with bulk F-curves (keyframe_points.add
+ foreach_set, the fast way; no simulation at all) and exporting it as GLB. Both medians and
their ratio are printed from one run (the issue-15 target: baker <= 0.14x Blender).

Blender's side runs in a Python with bpy installed (`pip install bpy`, the `blender` extra):
    python benchmarks/bench_blender.py --blender /path/to/bpy-python [--runs 3]
or with BAKER_BLENDER_PYTHON set. Without one it says so and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: run in the bpy Python: key every joint's location and rotation for every frame, export GLB;
#: prints the seconds spent keying and exporting (after bpy's own start-up)
BLENDER_SCRIPT = r"""
import json, sys, time
import numpy as np
import bpy

spec = json.load(open(sys.argv[1]))
loc = np.load(sys.argv[2])            # (F, J, 3) local translations
rot = np.load(sys.argv[3])            # (F, J, 4) local rotations, wxyz
out = sys.argv[4]
t0 = time.perf_counter()
bpy.ops.wm.read_factory_settings(use_empty=True)
arm = bpy.data.armatures.new("rig")
obj = bpy.data.objects.new("rig", arm)
bpy.context.scene.collection.objects.link(obj)
bpy.context.view_layer.objects.active = obj
bpy.ops.object.mode_set(mode="EDIT")
heads = np.array(spec["rest_world"])
bones = []
for name, parent, head in zip(spec["names"], spec["parents"], heads):
    b = arm.edit_bones.new(name)
    b.head = head.tolist()
    b.tail = (head + [0.0, 0.0, 0.01]).tolist()
    if parent >= 0:
        b.parent = bones[parent]
    bones.append(b)
bpy.ops.object.mode_set(mode="OBJECT")
action = bpy.data.actions.new("clip")
obj.animation_data_create().action = action
F = loc.shape[0]
frames = np.arange(1, F + 1, dtype=np.float32)
co = np.empty(2 * F, dtype=np.float32)
co[0::2] = frames
for j, name in enumerate(spec["names"]):
    for path, values in (("location", loc[:, j]), ("rotation_quaternion", rot[:, j])):
        for i in range(values.shape[1]):
            fc = action.fcurve_ensure_for_datablock(obj, f'pose.bones["{name}"].{path}',
                                                    index=i, group_name=name)
            fc.keyframe_points.add(F)
            co[1::2] = values[:, i]
            fc.keyframe_points.foreach_set("co", co)
            fc.update()
scene = bpy.context.scene
scene.frame_start, scene.frame_end, scene.render.fps = 1, F, spec["fps"]
t1 = time.perf_counter()
bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_animations=True)
t2 = time.perf_counter()
print(json.dumps({"key_s": t1 - t0, "export_s": t2 - t1}))
"""


def clip_of(glb: Path, work: Path) -> tuple[Path, Path, Path]:
    """The joint hierarchy and the local animation of a baked GLB, as files for Blender."""
    from baker.geometry.transforms import quat_rotate
    from baker.inspect import read_glb

    g = read_glb(glb)
    inv = g.rotations * np.array([-1.0, -1.0, -1.0, 1.0])
    loc = g.positions.copy()
    child = g.parents >= 0
    p = g.parents[child]
    loc[:, child] = quat_rotate(inv[:, p], g.positions[:, child] - g.positions[:, p])
    rot = g.local[..., [3, 0, 1, 2]]                                  # xyzw -> wxyz
    spec = work / "rig.json"
    spec.write_text(json.dumps({"names": list(g.names), "parents": g.parents.tolist(),
                                "rest_world": g.positions[0].tolist(), "fps": g.fps}))
    np.save(work / "loc.npy", loc.astype(np.float32))
    np.save(work / "rot.npy", rot.astype(np.float32))
    return spec, work / "loc.npy", work / "rot.npy"


#: the runs' environment: bytecode written as on any machine (an environment that sets
#: PYTHONDONTWRITEBYTECODE would have each run compile the package's sources again)
RUN_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str], **kw) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    done = subprocess.run(cmd, check=True, capture_output=True, text=True, env=RUN_ENV, **kw)
    return time.perf_counter() - t, done


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--blender", default=os.environ.get("BAKER_BLENDER_PYTHON"),
                    help="a Python with bpy installed [default: $BAKER_BLENDER_PYTHON]")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    if not args.blender:
        print("bench_blender: no bpy Python (pass --blender or set BAKER_BLENDER_PYTHON); skipped")
        return
    med = statistics.median
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bake = [sys.executable, "-m", "baker", "bake", "--seconds", str(args.seconds),
                "--out", str(tmp / "centipede"), "--cache-dir", str(tmp / "cache")]
        timed(bake)                     # warms the navigation cache (and writes the bytecode)
        files = clip_of(tmp / "centipede.glb", tmp)
        F, J = np.load(files[1]).shape[:2]
        script = tmp / "key.py"
        script.write_text(BLENDER_SCRIPT)
        ours, blender, inner = [], [], []
        for _ in range(args.runs):                # paired: one of each per round
            ours.append(timed(bake)[0])
            t, done = timed([args.blender, str(script), *map(str, files), str(tmp / "b.glb")])
            blender.append(t)
            inner.append(json.loads(done.stdout.strip().splitlines()[-1]))
    print(f"{args.seconds:.0f} s at 30 fps: {F} frames x {J} joints, {args.runs} paired runs "
          "(medians)")
    print(f"  baker bake (CLI, warm cache, GLB + USD + JSON)   : {med(ours):6.2f} s")
    print(f"  Blender: key with bulk F-curves + export GLB      : {med(blender):6.2f} s "
          f"(keying {med(r['key_s'] for r in inner):.2f} s, export "
          f"{med(r['export_s'] for r in inner):.2f} s, the rest bpy's start-up)")
    print(f"  ratio baker / Blender                             : {med(ours) / med(blender):6.2f}x"
          "   (target <= 0.14x)")


if __name__ == "__main__":
    main()
