"""Run with a Python that has Blender's `bpy` module (bpy 5.x, in a venv of its own: it wants
numpy<2): build a small level the way a technical artist would, export it with Blender's own
exporters (default settings and their common variants), and write beside each file the
triangles it should hold, from Blender itself.

usage: python blender_levels.py OUT_DIR [--only NAME[,NAME...]]

The level (Blender: +Z up, metres): a 16 m x 16 m floor (one quad), an L-shaped concave n-gon
terrace, a platform (a cube with an unapplied non-uniform scale) 2 m up reached by a rotated
ramp, a pillar parented under the scaled platform, a wall made by Array + Solidify modifiers,
a wall with a Mirror modifier, a mirrored (scale x = -1) wedge step, a crate mesh shared by two
objects (a linked duplicate), fence posts sharing a mesh under an empty, a collection of props
placed three times by collection-instance empties (one rotated and scaled, one mirrored), a
bevelled curve (a handrail) and a bare one (a path), an object hidden from render, one hidden
in the viewport (eye icon), one disabled in viewports, a camera and a sun. A second scene is the same level built at
`unit_settings.scale_length = 0.01` (a Blender unit is a centimetre: every length x 100).

OUT_DIR/manifest.json lists every export: {"name", "file", "up", "units", "ref", "note", "sun",
"mirrored_as_is"}, where up/units are what baker must be told (None: the file says it
itself), sun is the direction toward the sun the file holds (None: it holds no light), and ref
names OUT_DIR/ref_<ref>.npy, the (n, 3, 3) float64 world triangles (Blender's own triangulation
of the evaluated meshes, +Y up, metres: Blender's (x, y, z) -> (x, z, -y)) of what the exporter
writes as surfaces with those options, and OUT_DIR/mirrored_<ref>.npy, which of them belong to
a mirrored (negatively scaled) object. What each exporter writes (Blender 5.0.1, found by
reading the files):

- glTF: every object of the scene, hidden or not (use_visible and use_renderable are off by
  default), the objects of a collection excluded from the view layer too (at their own place),
  collection instances, bevelled curves as meshes; nothing in the file marks the hidden ones.
  use_visible + use_renderable: only what is shown and rendered.
- OBJ, PLY, STL: the objects of the viewport depsgraph: hidden-from-render ones included,
  hidden (eye) and disabled-in-viewport ones not. OBJ writes a bevelled curve object twice.
  PLY writes a mirrored object's faces in their own order, so it comes out inside out (OBJ
  and STL turn them). OBJ is +Y up by default (forward -Z, up Y); PLY and STL are +Z up
  (forward Y, up Z): baker needs --up z for them.
- USD (evaluation_mode RENDER): every object but the hidden-from-render ones (no visibility
  opinion is written); VIEWPORT: a hidden (eye) object is an empty Xform. Curves are
  BasisCurves (not surfaces: baker reads meshes), a bevelled one written twice. metersPerUnit
  is 1 (convert_scene_units) whatever the scene's unit scale: a centimetre scene needs
  --units cm. With use_instancing, a bevelled curve references itself (a composition cycle).
- scene unit scale: only STL's use_scene_unit applies it; glTF, OBJ and PLY write Blender
  units (a centimetre scene needs --units cm).
"""
import argparse
import json
import math
import os
import sys

import bpy
import numpy as np
from mathutils import Matrix, Vector

ap = argparse.ArgumentParser()
ap.add_argument("out")
ap.add_argument("--only", default="")
args = ap.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
OUT = os.path.abspath(args.out)
os.makedirs(OUT, exist_ok=True)
ONLY = {s for s in args.only.split(",") if s}


# ------------------------------------------------------------------ building the level
def mesh_object(name, verts, faces, coll, loc=(0, 0, 0), rot=(0, 0, 0), scale=(1, 1, 1),
                data=None):
    if data is None:
        data = bpy.data.meshes.new(name)
        data.from_pydata([Vector(v) for v in verts], [], faces)
        data.update()
    ob = bpy.data.objects.new(name, data)
    ob.location, ob.rotation_euler, ob.scale = loc, rot, scale
    coll.objects.link(ob)
    return ob


def box(name, size, coll, data=None, **kw):
    if data is not None:
        return mesh_object(name, None, None, coll, data=data, **kw)
    sx, sy, sz = (s / 2 for s in size)
    verts = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    # outward quads: corners of (x, y, z) bits (x*4 + y*2 + z)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return mesh_object(name, verts, faces, coll, **kw)


def build(scene, u):
    """The level in `scene`, every length in Blender units of 1/u metre (u = 1: metres)."""
    coll = scene.collection
    L = lambda *v: tuple(x * u for x in v)              # noqa: E731 (metres -> units)
    # floor: one quad
    mesh_object("Floor", [L(-8, -8, 0), L(8, -8, 0), L(8, 8, 0), L(-8, 8, 0)], [(0, 1, 2, 3)],
                coll)
    # an L-shaped terrace 0.3 m up: one concave hexagon (a fan from corner 0 would cover the
    # notch... from a reflex-adjacent corner it would)
    mesh_object("Terrace", [L(0, 0, 0), L(4, 0, 0), L(4, 1.5, 0), L(1.5, 1.5, 0), L(1.5, 4, 0),
                            L(0, 4, 0)], [(3, 4, 5, 0, 1, 2)], coll, loc=L(-7, -7, 0.3))
    # platform: a unit cube scaled (unapplied, non-uniform), its top 2 m up
    plat = box("Platform", L(1, 1, 1), coll, loc=L(3, 3, 1.75), scale=(5, 4, 0.5))
    # a pillar under the platform, parented to it (inherits the non-uniform scale)
    # (Ctrl+P, "Object": the parent inverse matrix keeps the child where it was)
    pillar = box("Pillar", L(0.4, 0.4, 1.5), coll, loc=L(4.5, 4.5, 0.75))
    bpy.context.view_layer.update()
    pillar.parent = plat
    pillar.matrix_parent_inverse = plat.matrix_world.inverted()
    # a ramp: a 1 m x 6 m slab rotated about x, from the floor to the platform's edge
    ang = math.atan2(2.0, 5.0)
    box("Ramp", L(2, math.hypot(2, 5), 0.1), coll, loc=L(3.5, 1 - 2.5, 1.0 - 0.05),
        rot=(ang, 0, 0))
    # a wall: one plane, made 4 panels long by an Array and thick by a Solidify
    wall = mesh_object("WallArray", [L(0, 0, 0), L(2, 0, 0), L(2, 0, 1.5), L(0, 0, 1.5)],
                       [(0, 1, 2, 3)], coll, loc=L(-8, 7.5, 0))
    arr = wall.modifiers.new("Array", "ARRAY")
    arr.count = 4
    wall.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.2 * u
    # a wall on one side, mirrored across the object's x = 0 by a Mirror modifier
    mirror = box("WallMirror", L(0.2, 3, 1.2), coll, loc=L(0, -6, 0.6))
    mirror.data.transform(Matrix.Translation(L(6, 0, 0)))
    mirror.modifiers.new("Mirror", "MIRROR")
    # a wedge step (asymmetric), and its mirror image by scale x = -1
    wedge = [L(0, 0, 0), L(1.5, 0, 0), L(0, 0, 0.6), L(0, 1, 0), L(1.5, 1, 0), L(0, 1, 0.6)]
    wfaces = [(0, 1, 2), (3, 5, 4), (0, 3, 4, 1), (1, 4, 5, 2), (0, 2, 5, 3)]   # outward
    mesh_object("Wedge", wedge, wfaces, coll, loc=L(-3, 2, 0))
    mesh_object("WedgeMirrored", wedge, wfaces, coll, loc=L(-4, 4, 0), scale=(-1, 1, 1))
    # a crate and its linked duplicate (the same mesh data), the second rotated
    crate = box("Crate", L(0.8, 0.8, 0.8), coll, loc=L(5, -3, 0.4))
    mesh_object("CrateLinked", None, None, coll, loc=L(6.2, -3.5, 0.4),
                rot=(0, 0, math.radians(30)), data=crate.data)
    # a fence: posts sharing one mesh, children of an empty (what glTF's
    # export_gpu_instances turns into one EXT_mesh_gpu_instancing node)
    fence = bpy.data.objects.new("Fence", None)
    fence.location, fence.rotation_euler = L(-6, -2, 0), (0, 0, 0.2)
    coll.objects.link(fence)
    post = None
    for i in range(5):
        post = box(f"Post{i}", L(0.15, 0.15, 1.0), coll, loc=L(0, i * 1.2, 0.5),
                   rot=(0, 0, 0.1 * i), data=post.data if post else None)
        post.parent = fence
    # props collection placed twice by collection-instance empties; the source collection is
    # excluded from the view layer, as artists keep asset collections
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    box("Barrel", L(0.6, 0.6, 1.0), props, loc=L(0, 0, 0.5))
    box("Plank", L(1.2, 0.3, 0.1), props, loc=L(0.8, 0, 0.05), rot=(0, 0, 0.4))
    for i, (loc, rot, s) in enumerate(((L(-2, -3, 0), 0.0, (1, 1, 1)),
                                       (L(-5, 0, 0), math.radians(75), (1.5, 1.5, 1.5)),
                                       (L(2, -6.5, 0), 0.0, (-1, 1, 1)))):    # mirrored
        e = bpy.data.objects.new(f"PropsInstance{i}", None)
        e.instance_type, e.instance_collection = "COLLECTION", props
        e.location, e.rotation_euler, e.scale = loc, (0, 0, rot), s
        coll.objects.link(e)
    scene.view_layers[0].layer_collection.children["Props"].exclude = True
    # a handrail along the ramp: a curve with a bevel (a tube), and a curve with no bevel (a
    # path: edges only, nothing to walk on)
    for name, depth in (("Handrail", 0.05 * u), ("Path", 0.0)):
        cu = bpy.data.curves.new(name, "CURVE")
        cu.dimensions, cu.bevel_depth, cu.bevel_resolution = "3D", depth, 1
        sp = cu.splines.new("POLY")
        sp.points.add(2)
        for k, q in enumerate((L(4.6, -3.9, 1.0), L(4.6, -1.5, 1.9), L(4.6, 1, 3.0))):
            sp.points[k].co = (*q, 1.0)
        coll.objects.link(bpy.data.objects.new(name, cu))
    # hidden objects: from render, in the viewport (eye icon), disabled in viewports
    box("HiddenRender", L(2, 2, 3), coll, loc=L(-5, 5, 1.5)).hide_render = True
    box("HiddenEye", L(2, 2, 3), coll, loc=L(5, 5, 5))
    box("DisabledViewport", L(2, 2, 3), coll, loc=L(0, 6, 1.5))
    bpy.context.view_layer.update()     # (world matrices are set by an evaluation)
    scene.objects["DisabledViewport"].hide_viewport = True
    scene.objects["HiddenEye"].hide_set(True)
    # non-mesh objects
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = L(0, -20, 12)
    coll.objects.link(cam)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (0.3, 0.2, 0)
    coll.objects.link(sun)
    bpy.context.view_layer.update()


# ------------------------------------------------------------------ the reference
TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])

#: which object instances each kind of export writes as drawn geometry, by the flags of the
#: instance's own object (or of the empty that instances it): hidden in the viewport (eye),
#: disabled in viewports, hidden from render, in a collection excluded from the view layer
MODES = {
    "all": lambda eye, disabled, render, excluded: True,          # glTF, default options
    "visible": lambda eye, disabled, render, excluded: not (eye or disabled or render
                                                             or excluded),
    "viewport": lambda eye, disabled, render, excluded: not (eye or disabled or excluded),
    "render": lambda eye, disabled, render, excluded: not (render or excluded),
}


def instances(scene, modifiers: bool):
    """(flags, world triangles in Blender's frame) of every mesh object instance of the scene,
    hidden ones and those of excluded collections too (made visible for the moment)."""
    vl = scene.view_layers[0]
    excluded = {c.name: c.exclude for c in vl.layer_collection.children}
    hidden = {o.name: (o.hide_get(), o.hide_viewport) for o in scene.objects}
    in_excluded = {o.name for c in vl.layer_collection.children if c.exclude
                   for o in c.collection.all_objects}
    for c in vl.layer_collection.children:
        c.exclude = False
    for o in scene.objects:
        o.hide_viewport = False
        o.hide_set(False)
    vl.update()
    dg = bpy.context.evaluated_depsgraph_get()
    out = []
    for inst in dg.object_instances:
        ob = inst.instance_object if inst.is_instance else inst.object
        if ob.type not in ("MESH", "CURVE") or (inst.is_instance and inst.parent.type == "CURVE"):
            continue    # (a curve object is listed twice: itself and its geometry's instance)
        top = (inst.parent if inst.is_instance else ob).original
        eye, disabled = hidden[top.name]
        flags = (eye, disabled, top.hide_render or ob.original.hide_render,
                 not inst.is_instance and top.name in in_excluded, ob.type == "CURVE")
        me = ob.to_mesh() if modifiers or ob.type != "MESH" else ob.original.data.copy()
        me.calc_loop_triangles()
        co = np.array([v.co for v in me.vertices], dtype=np.float64).reshape(-1, 3)
        idx = np.array([t.vertices for t in me.loop_triangles], dtype=np.int64).reshape(-1, 3)
        m = np.array(inst.matrix_world, dtype=np.float64)
        if np.linalg.det(m[:3, :3]) < 0:
            idx = idx[:, ::-1]
        out.append((flags, (co @ m[:3, :3].T + m[:3, 3])[idx],
                    np.full(len(idx), np.linalg.det(m[:3, :3]) < 0)))
        if modifiers or ob.type != "MESH":
            ob.to_mesh_clear()
        else:
            bpy.data.meshes.remove(me)
    for c in vl.layer_collection.children:
        c.exclude = excluded[c.name]
    for o in scene.objects:
        o.hide_viewport = hidden[o.name][1]
        o.hide_set(hidden[o.name][0])
    vl.update()
    return out


def reference(scene, modifiers: bool, mode: str, metres: float, curves: int):
    """World triangles (+Y up, metres) of the object instances a `mode` export writes, with
    curve objects' geometry (a bevelled curve is a tube) `curves` times (0, 1 or 2)."""
    keep = MODES[mode]
    kept = [(t, mirrored) for (*flags, curve), t, mirrored in instances(scene, modifiers)
            if keep(*flags) for _ in range(curves if curve else 1)]
    return (np.concatenate([t for t, _ in kept]) @ TO_Y_UP.T * metres,
            np.concatenate([mirrored for _, mirrored in kept]))


# ------------------------------------------------------------------ exports
MANIFEST = []
REFS = {}


def ref(scene, key, modifiers, mode, metres, curves=1):
    name = f"{key}_{'mod' if modifiers else 'raw'}_{mode}_curves{curves}"
    if name not in REFS:
        REFS[name], mirrored = reference(scene, modifiers, mode, metres, curves)
        np.save(os.path.join(OUT, f"ref_{name}.npy"), REFS[name])
        np.save(os.path.join(OUT, f"mirrored_{name}.npy"), mirrored)
    return name


def sun_direction(scene):
    """Toward the sun (+Y up): the sun lamp shines down its local -Z."""
    m = np.array(scene.objects["Sun"].matrix_world, dtype=np.float64)
    d = TO_Y_UP @ m[:3, :3] @ np.array([0.0, 0, 1])
    return (d / np.linalg.norm(d)).tolist()


def export(name, file, op, kwargs, up, units, refname, note="", **extra):
    """Write one export and its manifest entry. extra: sun (the direction toward the sun the
    file holds, or None for none), mirrored_as_is (the exporter writes a mirrored object's
    faces in their own order: inside out, see PLY below)."""
    if ONLY and name not in ONLY:
        return
    path = os.path.join(OUT, file)
    op(filepath=path, **kwargs)
    MANIFEST.append(dict(name=name, file=file, up=up, units=units, ref=refname, note=note,
                         **{"sun": None, "mirrored_as_is": False, **extra}))


def export_all(scene, key, u):
    metres = 1.0 / u
    unit = None if u == 1 else "cm"
    gl, ob, pl, st, us = (bpy.ops.export_scene.gltf, bpy.ops.wm.obj_export,
                          bpy.ops.wm.ply_export, bpy.ops.wm.stl_export, bpy.ops.wm.usd_export)
    r = lambda mod, mode, curves=1: ref(scene, key, mod, mode, metres, curves)  # noqa: E731
    p = key + "_"
    export(p + "gltf_glb", p + "level.glb", gl, {}, None, unit, r(False, "all"))
    export(p + "gltf_glb_apply", p + "level_apply.glb", gl, {"export_apply": True}, None, unit,
           r(True, "all"))
    export(p + "gltf_sep", p + "level_sep.gltf", gl,
           {"export_format": "GLTF_SEPARATE", "export_apply": True}, None, unit, r(True, "all"))
    export(p + "gltf_zup", p + "level_zup.glb", gl, {"export_yup": False, "export_apply": True},
           "z", unit, r(True, "all"), "export_yup=False: +Z up, not glTF's +Y")
    export(p + "gltf_visible", p + "level_visible.glb", gl,
           {"use_visible": True, "use_renderable": True, "export_apply": True}, None, unit,
           r(True, "visible"))
    export(p + "gltf_lights", p + "level_lights.glb", gl,
           {"export_lights": True, "export_apply": True}, None, unit, r(True, "all"),
           sun=sun_direction(scene))
    export(p + "gltf_draco", p + "level_draco.glb", gl,
           {"export_draco_mesh_compression_enable": True, "export_apply": True,
            "export_draco_position_quantization": 30}, None, unit, r(True, "all"))
    export(p + "gltf_gpu_inst", p + "level_gpu_inst.glb", gl,
           {"export_gpu_instances": True, "export_apply": True}, None, unit, r(True, "all"))
    # (Blender 5.0's OBJ export writes a bevelled curve object twice: `o Handrail` twice)
    export(p + "obj", p + "level.obj", ob, {}, None, unit, r(True, "viewport", 2))
    export(p + "obj_raw", p + "level_raw.obj", ob, {"apply_modifiers": False}, None, unit,
           r(False, "viewport", 2))
    export(p + "obj_zup", p + "level_zup.obj", ob, {"forward_axis": "Y", "up_axis": "Z"}, "z",
           unit, r(True, "viewport", 2))
    export(p + "obj_tri", p + "level_tri.obj", ob, {"export_triangulated_mesh": True}, None,
           unit, r(True, "viewport", 2))
    # (Blender 5.0's PLY export keeps a mirrored object's faces in their order: inside out)
    ply = dict(mirrored_as_is=True)
    export(p + "ply_bin", p + "level_bin.ply", pl, {}, "z", unit, r(True, "viewport"), **ply)
    export(p + "ply_ascii", p + "level_ascii.ply", pl, {"ascii_format": True}, "z", unit,
           r(True, "viewport"), **ply)
    export(p + "ply_yup", p + "level_yup.ply", pl, {"forward_axis": "NEGATIVE_Z",
                                                    "up_axis": "Y"}, None, unit,
           r(True, "viewport"), **ply)
    export(p + "stl_bin", p + "level_bin.stl", st, {}, "z", unit, r(True, "viewport"))
    export(p + "stl_ascii", p + "level_ascii.stl", st, {"ascii_format": True}, "z", unit,
           r(True, "viewport"))
    # USD: metersPerUnit is 1 whatever the scene's unit scale (convert_scene_units sets it and
    # scales the root to convert from metres: a Blender unit is taken for a metre), so a
    # centimetre scene's stage needs --units cm
    sun = dict(sun=sun_direction(scene))
    for ext in ("usda", "usdc", "usdz"):
        export(f"{p}usd_{ext}", f"{p}level.{ext}", us, {}, None, unit, r(True, "render", 0),
               **sun)
    # (Blender 5.0 writes a bevelled curve twice, and with use_instancing as a reference to
    # itself: a composition cycle no USD reader opens; curves are left out of that export)
    export(p + "usd_inst", p + "level_inst.usda", us,
           {"use_instancing": True, "export_curves": False}, None, unit,
           r(True, "render", 0), **sun)
    export(p + "usd_matrix", p + "level_matrix.usda", us, {"xform_op_mode": "MAT"}, None, unit,
           r(True, "render", 0), **sun)
    export(p + "usd_viewport", p + "level_viewport.usda", us, {"evaluation_mode": "VIEWPORT"},
           None, unit, r(True, "viewport", 0), **sun)
    export(p + "usd_yup", p + "level_yup.usda", us,
           {"convert_orientation": True, "export_global_forward_selection": "NEGATIVE_Z",
            "export_global_up_selection": "Y"}, None, unit, r(True, "render", 0), **sun)
    export(p + "usd_tri", p + "level_tri.usdc", us, {"triangulate_meshes": True}, None, unit,
           r(True, "render", 0), **sun)
    if u == 1:   # (metersPerUnit 0.01, the root scaled by 100: right only for a metre unit)
        export(p + "usd_cm", p + "level_usd_cm.usda", us,
               {"convert_scene_units": "CENTIMETERS"}, None, None, r(True, "render", 0), **sun)
    else:        # the exporter with a scene-unit option
        export(p + "stl_units", p + "level_units.stl", st, {"use_scene_unit": True}, "z", None,
               r(True, "viewport"))


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    build(scene, 1.0)
    export_all(scene, "m", 1.0)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.scale_length = 0.01
    build(scene, 100.0)
    export_all(scene, "cm", 100.0)
    with open(os.path.join(OUT, "manifest.json"), "w") as fh:
        json.dump(MANIFEST, fh, indent=1)
    print("LEVELS_JSON " + json.dumps({"exports": len(MANIFEST), "refs": sorted(REFS)}))


main()
