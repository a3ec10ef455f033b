"""Run with a Python that has Blender's `bpy` module: import a GLB or USD file the way a user
would and print, as one JSON line prefixed "PROBE_JSON ", what Blender made of it: the armature,
its action and frame range, and the world position (Blender Z-up) of every bone head at the
requested frames.

usage: python blender_probe.py FILE FPS FRAME[,FRAME...]

bpy 5.x wants numpy<2, so it lives in its own venv, outside the project's dependencies.
"""
import json
import sys

import bpy

path, fps, frames = sys.argv[1], int(sys.argv[2]), [int(x) for x in sys.argv[3].split(",")]
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
out["action"] = ad.action.name if ad and ad.action else None
if ad and ad.action:
    out["action_range"] = list(ad.action.frame_range)
out["bones"] = [b.name for b in arm.pose.bones]
pos = {}
for f in frames:
    scene.frame_set(f)
    pos[f] = {b.name: list(arm.matrix_world @ b.head) for b in arm.pose.bones}
out["positions"] = pos
meshes = [o for o in scene.objects
          if o.type == "MESH" and any(m.type == "ARMATURE" and m.object == arm for m in o.modifiers)]
out["skinned_meshes"] = sorted(m.name for m in meshes)
out["skinned_vertices"] = sum(len(m.data.vertices) for m in meshes)
out["actions"] = {a.name: list(a.frame_range) for a in bpy.data.actions}
print("PROBE_JSON " + json.dumps(out))
