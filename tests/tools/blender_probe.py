"""Run with a Python that has Blender's `bpy` module: import a GLB or USD file the way a user
would and print, as one JSON line prefixed "PROBE_JSON ", what Blender made of it: the armature,
its action and frame range, and the world position (Blender Z-up) of every bone head at the
requested frames.

usage: python blender_probe.py FILE FPS [FRAME[,FRAME...]] [--clip NAME] [--times T[,T...]]

  FRAME    whole frames: positions under "positions" {frame: {bone: [x, y, z]}}
  --clip   play this action (a glTF animation's name) on the armature instead of the first
  --times  seconds (frame = t * FPS, between frames as a subframe): positions under "samples",
           one list per time of [x, y, z] per bone, in the order of "bones"

bpy 5.x wants numpy<2, so it lives in its own venv, outside the project's dependencies.
"""
import argparse
import json
import math

import bpy

ap = argparse.ArgumentParser()
ap.add_argument("path")
ap.add_argument("fps", type=int)
ap.add_argument("frames", nargs="?", default="")
ap.add_argument("--clip", default=None)
ap.add_argument("--times", default="")
args = ap.parse_args()
path, fps = args.path, args.fps
frames = [int(x) for x in args.frames.split(",") if x]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = fps
scene.render.fps_base = 1.0
if path.endswith(".glb"):
    bpy.ops.import_scene.gltf(filepath=path)
else:
    bpy.ops.wm.usd_import(filepath=path)
arms = [o for o in scene.objects if o.type == "ARMATURE"]
out = {"objects": sorted(o.name for o in scene.objects), "armatures": [a.name for a in arms],
       "lights": [o.name for o in scene.objects if o.type == "LIGHT"]}
arm = arms[0]
ad = arm.animation_data
if args.clip is not None:
    # the glTF importer makes one action per animation (a slot per animated object) and stashes
    # all but the first in muted NLA tracks: make the asked one active, on the armature's slot
    action = bpy.data.actions[args.clip]
    slot = ad.action_slot.identifier if ad.action_slot else "OB" + arm.name
    ad.action = action
    ad.action_slot = next(s for s in action.slots if s.identifier == slot)
out["action"] = ad.action.name if ad and ad.action else None
if ad and ad.action:
    out["action_range"] = list(ad.action.frame_range)
out["bones"] = [b.name for b in arm.pose.bones]
pos = {}
for f in frames:
    scene.frame_set(f)
    pos[f] = {b.name: list(arm.matrix_world @ b.head) for b in arm.pose.bones}
out["positions"] = pos
samples = []
for t in [float(x) for x in args.times.split(",") if x]:
    f = t * fps
    whole = math.floor(f + 1e-9)
    scene.frame_set(whole, subframe=max(f - whole, 0.0))
    samples.append([list(arm.matrix_world @ b.head) for b in arm.pose.bones])
out["samples"] = samples
meshes = [o for o in scene.objects
          if o.type == "MESH" and any(m.type == "ARMATURE" and m.object == arm for m in o.modifiers)]
out["skinned_meshes"] = sorted(m.name for m in meshes)
out["skinned_vertices"] = sum(len(m.data.vertices) for m in meshes)
out["actions"] = {a.name: list(a.frame_range) for a in bpy.data.actions}
out["scene_properties"] = sorted(scene.keys())
print("PROBE_JSON " + json.dumps(out))
