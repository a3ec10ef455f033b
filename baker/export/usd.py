"""USD writer (usd-core): environment, sun and the UsdSkel centipede, written atomically.

Stage layout (defaultPrim /World):

    /World                         Xform; customData carries the bake's extras
      Environment/<mesh>           Xform translated by env.origin; Meshes, displayColor,
                                   UsdPreviewSurface material (points in the local frame)
      Sun                          DistantLight, local -Z along the light
      Centipede                    SkelRoot translated by clip.placement
        Skeleton                   joints as paths, bindTransforms (skeleton space),
                                   restTransforms (local)
        Animation                  SkelAnimation, time samples keyed by frame number
        Clips/<name>               optional per-behaviour SkelAnimations (not bound)
        body, legs                 skinned Meshes (one per material)
      Centipede_01, ...            a crowd's further creatures (`--creatures N`), each a SkelRoot
                                   laid out as Centipede (its own Skeleton, Animation and
                                   Clips/root_motion) whose Meshes body_01, legs_01 reference
                                   /World/Centipede/body and legs (the mesh data is stored
                                   once) and bind to its own Skeleton; joints keep the rig's
                                   names (they are scoped by the Skeleton)
      Prey/<name>                  Xform translated by clip.placement; animated Xforms
                                   (translate, orient, scale, visibility) + mesh <name>_mesh
      Debug/<name>                 Xform translated by env.origin; optional overlay meshes
      Looks/<material>             Materials (<mesh>_mat, centipede_<part>)

Object prim names (Xforms, meshes, materials, clips) are unique across the stage, also without
regard to case, as the GLB's node, mesh and material names are.

The translations that carry positions far from the world origin are double3 translate ops
(`UsdGeom.XformOp.PrecisionDouble`), so float32 points and keys stay small; a zero offset
authors no op.

This is the only module that converts xyzw quaternions to USD's (w, x, y, z): Vt.QuatfArray's
memory layout is (x, y, z, w), so FromNumpy takes xyzw arrays directly; Gf.Quatf(w, x, y, z) takes
the real part first.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from baker.clip import Clip
from baker.environment.model import Environment
from baker.errors import ExportError, exception_text, utf8_text
from baker.export import checked_mesh, creature_label, environment_parts, jsonable, safe_name
from baker.geometry.transforms import light_rotation
from baker.atomic import atomic_output
from baker.rig.build import Rig

log = logging.getLogger(__name__)


def _pxr():
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdSkel, Vt

    return Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdSkel, Vt


def _matrices(m: np.ndarray):
    """(n, 4, 4) column-vector matrices -> Vt.Matrix4dArray (USD's row-vector layout)."""
    from pxr import Vt

    return Vt.Matrix4dArray.FromNumpy(np.ascontiguousarray(np.transpose(m, (0, 2, 1)), np.float64))


def _custom_data_value(v):
    """USD customData holds dict/str/int/float/bool; anything else becomes a JSON string. Text
    is stored as UTF-8 (utf8_text: a --rig path holding a byte that is not was a
    UnicodeEncodeError traceback)."""
    if isinstance(v, bool) or v is None:
        return v if v is not None else "null"
    if isinstance(v, int):
        return v if -2 ** 63 <= v < 2 ** 63 else str(v)
    if isinstance(v, float):
        return v
    if isinstance(v, str):
        return utf8_text(v)
    if isinstance(v, dict):
        return {utf8_text(str(k)): _custom_data_value(x) for k, x in v.items()}
    return json.dumps(v, separators=(",", ":"), allow_nan=False)


def _spec(layer, path, type_name: str):
    """A new `def <type_name>` prim spec at path (its parent spec exists)."""
    from pxr import Sdf

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef
    spec.typeName = type_name
    return spec


def _attr(spec, name: str, type_name, value=None, uniform: bool = False):
    """An attribute spec authored as the schema's Create*Attr authors it (not custom;
    uniform where the schema says so), its default value set unless None."""
    from pxr import Sdf

    a = Sdf.AttributeSpec(spec, name, type_name,
                          Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying,
                          declaresCustom=False)
    if value is not None:
        a.default = value
    return a


# _material and _mesh author their specs straight in the root layer (Sdf), the specs and the
# order UsdShade and UsdGeom would author (tests/export/test_usd.py compares them), so that a
# level of thousands of meshes is written in one Sdf.ChangeBlock, without a stage
# recomposition per prim.
def _material(stage, looks_path, name: str, rgb, opacity: float, metallic: float,
              roughness: float):
    """A UsdPreviewSurface material at looks_path/name; returns its path."""
    Gf, Sdf, _, _, _, _, _, _ = _pxr()
    T = Sdf.ValueTypeNames
    path = looks_path.AppendChild(name)
    layer = stage.GetRootLayer()
    mat = _spec(layer, path, "Material")
    shader_path = path.AppendChild("PreviewSurface")
    shader = _spec(layer, shader_path, "Shader")
    _attr(shader, "info:id", T.Token, "UsdPreviewSurface", uniform=True)
    _attr(shader, "inputs:diffuseColor", T.Color3f,
          Gf.Vec3f(*[float(np.clip(c, 0, 1)) for c in rgb[:3]]))
    _attr(shader, "inputs:metallic", T.Float, float(np.clip(metallic, 0, 1)))
    _attr(shader, "inputs:roughness", T.Float, float(np.clip(roughness, 0, 1)))
    if opacity < 1.0:
        _attr(shader, "inputs:opacity", T.Float, float(opacity))
    out = _attr(mat, "outputs:surface", T.Token)
    _attr(shader, "outputs:surface", T.Token)
    out.connectionPathList.explicitItems = [shader_path.AppendProperty("outputs:surface")]
    return path


def _mesh(stage, path, vertices, faces, normals, rgba, material_path, double_sided: bool):
    """A triangle mesh bound to material_path; returns it as a UsdGeom.Mesh (not valid until
    an enclosing Sdf.ChangeBlock ends)."""
    Gf, Sdf, _, UsdGeom, _, _, _, Vt = _pxr()
    T = Sdf.ValueTypeNames
    v, f, n = checked_mesh(path.name, vertices, faces, normals)
    spec = _spec(stage.GetRootLayer(), path, "Mesh")
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"]))
    _attr(spec, "points", T.Point3fArray, Vt.Vec3fArray.FromNumpy(v))
    _attr(spec, "faceVertexCounts", T.IntArray,
          Vt.IntArray.FromNumpy(np.full(len(f), 3, dtype=np.int32)))
    _attr(spec, "faceVertexIndices", T.IntArray,
          Vt.IntArray.FromNumpy(f.astype(np.int32).reshape(-1)))
    _attr(spec, "normals", T.Normal3fArray, Vt.Vec3fArray.FromNumpy(n)).SetInfo(
        "interpolation", "vertex")
    _attr(spec, "subdivisionScheme", T.Token, "none", uniform=True)
    _attr(spec, "orientation", T.Token, "rightHanded", uniform=True)
    _attr(spec, "doubleSided", T.Bool, bool(double_sided), uniform=True)
    _attr(spec, "extent", T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(*map(float, v.min(0))),
                                                        Gf.Vec3f(*map(float, v.max(0)))]))
    _attr(spec, "primvars:displayColor", T.Color3fArray,
          Vt.Vec3fArray([Gf.Vec3f(*[float(c) for c in rgba[:3]])]))
    if len(rgba) > 3 and rgba[3] < 1.0:
        _attr(spec, "primvars:displayOpacity", T.FloatArray, Vt.FloatArray([float(rgba[3])]))
    rel = Sdf.RelationshipSpec(spec, "material:binding", custom=False,
                               variability=Sdf.VariabilityUniform)
    rel.targetPathList.explicitItems = [material_path]
    return UsdGeom.Mesh(stage.GetPrimAtPath(path))


def _offset(xformable, v) -> None:
    """A double-precision translate op of v (3,) float64 metres, unless v is zero."""
    Gf, _, _, UsdGeom, _, _, _, _ = _pxr()
    v = np.asarray(v, dtype=np.float64).reshape(3)
    if np.any(v != 0):
        xformable.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, v)))


#: prim names the stage's layout uses (see the module docstring)
_FIXED_PRIMS = ("World", "Looks", "Environment", "Sun", "Centipede", "Skeleton", "Animation",
                "Clips", "Prey", "Debug")


def _reserved_names(names: Sequence[str]) -> set[str]:
    """The fixed prim names and `names` (prey Xforms, clips: prims that keep their exact
    names), each with its lower-case form, as a `taken` set for safe_name. ExportError when
    two of them are equal without regard to case."""
    fixed = list(_FIXED_PRIMS) + list(names)
    taken = {n.lower() for n in fixed}
    if len(taken) != len(fixed):
        raise ExportError("prey or clip names clash with each other or with the stage's prim "
                          f"names ({', '.join(_FIXED_PRIMS)}), also when case is ignored")
    return taken | set(fixed)


def _stage_names(rig: Rig, props: Sequence, debug_meshes: Sequence, extra_clips: Sequence,
                 creatures: int = 1):
    """One name space for the stage's objects (Xforms, meshes, materials, clips), unique also
    without regard to case, as in the GLB: Blender names its objects and materials by prim
    name, and two prims named `mesh` would arrive as `mesh` and `mesh.001`. baker's own names
    are reserved before the environment's.

    returns (taken: for safe_name, updated as names are given out; the debug layers' names;
    (mesh, material) names of each rig.mesh.materials entry)"""
    taken = _reserved_names([p[0] for p in props] + [c.name for c in extra_clips]
                            + [creature_label(i, creatures)[0] for i in range(1, creatures)])
    debug_names = [safe_name(d[0], taken, "debug") for d in debug_meshes]
    part_names = [(safe_name(m, taken, "part"), safe_name(f"centipede_{m}", taken))
                  for m, _ in rig.mesh.materials]
    return taken, debug_names, part_names


def _skel_animation(stage, path, joints, clip: Clip):
    """A SkelAnimation prim with the clip's joint TRS, time samples keyed by frame number. A
    reduced clip (clip.keys) is written at the frames its joints keep (the played values, see
    _reduced_samples; USD interpolates quatf with GfSlerp and vectors with GfLerp, like glTF
    LINEAR); an attribute whose joints are all static is one default value."""
    _, Sdf, Usd, _, _, _, UsdSkel, Vt = _pxr()
    anim = UsdSkel.Animation.Define(stage, path)
    anim.CreateJointsAttr(joints)
    t_attr = anim.CreateTranslationsAttr()
    r_attr = anim.CreateRotationsAttr()
    s_attr = anim.CreateScalesAttr()
    if clip.keys is not None:
        _reduced_samples(clip, ((t_attr, Vt.Vec3fArray, np.float32),
                                (r_attr, Vt.QuatfArray, np.float32),
                                (s_attr, Vt.Vec3hArray, np.float16)))
        return anim
    tr = np.ascontiguousarray(clip.translations, dtype=np.float32)
    rot = np.ascontiguousarray(clip.rotations, dtype=np.float32)      # xyzw == GfQuatf memory
    sc = np.ascontiguousarray(clip.scales, dtype=np.float16)
    with Sdf.ChangeBlock():
        for f in range(clip.n_frames):
            tc = Usd.TimeCode(float(f))
            t_attr.Set(Vt.Vec3fArray.FromNumpy(tr[f]), tc)
            r_attr.Set(Vt.QuatfArray.FromNumpy(rot[f]), tc)
            s_attr.Set(Vt.Vec3hArray.FromNumpy(sc[f]), tc)
    return anim


def _events(anim, clip: Clip) -> None:
    """The clip's events as the SkelAnimation prim's customData (one dictionary)."""
    if clip.events:
        anim.GetPrim().SetCustomData(_custom_data_value(jsonable(dict(clip.events))))


def _root_motion(stage, path, skel, track: NodeTrack):
    """A SkelAnimation over the `root` joint alone, with the track's translations/rotations."""
    _, Sdf, Usd, _, _, _, UsdSkel, Vt = _pxr()
    root = [p for p, n in zip(skel.joint_paths(), skel.names) if n == track.node]
    if not root:
        raise ExportError(f"root motion drives joint {track.node!r}, which the skeleton lacks")
    anim = UsdSkel.Animation.Define(stage, path)
    anim.CreateJointsAttr(Vt.TokenArray(root))
    t_attr, r_attr = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr()
    anim.CreateScalesAttr().Set(Vt.Vec3hArray.FromNumpy(np.ones((1, 3), np.float16)))
    tr = np.ascontiguousarray(track.translations, dtype=np.float32)
    rot = np.ascontiguousarray(track.rotations, dtype=np.float32)
    with Sdf.ChangeBlock():
        for f in range(len(tr)):
            tc = Usd.TimeCode(float(f))
            t_attr.Set(Vt.Vec3fArray.FromNumpy(tr[f:f + 1]), tc)
            r_attr.Set(Vt.QuatfArray.FromNumpy(rot[f:f + 1]), tc)
    return anim


def _reduced_samples(clip: Clip, attrs) -> None:
    """Time samples of a reduced clip's translations, rotations and scales: attrs are
    (attribute, Vt array type, numpy dtype) in that order. An attribute whose joints are all
    static gets one default value; the others get the played values at every frame that any of
    their joints keeps (one set of time codes for all of them: Blender's USD importer does not
    interpolate an attribute at a time code where only another one has a sample)."""
    _, Sdf, Usd, _, _, _, _, _ = _pxr()
    k = clip.keys
    parts = list(zip(attrs, (k.translations, k.rotations, k.scales), (False, True, False)))
    frames = np.flatnonzero(np.any([keys.keep.any(axis=0) for _, keys, _ in parts], axis=0))
    with Sdf.ChangeBlock():
        for (attr, vt_type, dtype), keys, rot in parts:
            if keys.is_static.all():
                attr.Set(vt_type.FromNumpy(np.ascontiguousarray(keys.static, dtype=dtype)))
                continue
            played = np.ascontiguousarray(keys.play(clip.times, rot), dtype=dtype)
            for f in frames:
                attr.Set(vt_type.FromNumpy(played[f]), Usd.TimeCode(float(f)))


def _animate_xform(xf, track, keys=None) -> None:
    """translate / orient / scale ops on an Xformable, sampled per frame from a NodeTrack, or,
    with its TrackKeys (a reduced clip), at its kept frames (a static path: one default value),
    with the visibility authored where it changes (visibility is held, not interpolated)."""
    Gf, Sdf, Usd, UsdGeom, _, _, _, _ = _pxr()
    vec3d = (lambda v: Gf.Vec3d(*map(float, v)))
    quatf = (lambda q: Gf.Quatf(float(q[3]), float(q[0]), float(q[1]), float(q[2])))
    vec3f = (lambda v: Gf.Vec3f(*map(float, v)))
    ops = []
    for path, values, add, conv in (("translation", track.translations, xf.AddTranslateOp, vec3d),
                                    ("rotation", track.rotations, xf.AddOrientOp, quatf),
                                    ("scale", track.scales, xf.AddScaleOp, vec3f)):
        if values is None:
            continue
        part = None if keys is None else dict(keys.parts())[path]
        op = add()
        if part is None:
            ops.append((op, [(f, conv(v)) for f, v in enumerate(values)]))
        elif part.is_static[0]:
            op.Set(conv(part.static[0]))
        else:
            ops.append((op, [(f, conv(part.values[f, 0])) for f in part.frames(0)]))
    if track.scales is not None:
        vis = xf.CreateVisibilityAttr()
        shown = np.asarray(track.scales)[:, 0] > 0
        frames = (range(len(shown)) if keys is None
                  else np.flatnonzero(np.r_[True, shown[1:] != shown[:-1]]))
        for f in frames:
            vis.Set(UsdGeom.Tokens.inherited if shown[f] else UsdGeom.Tokens.invisible,
                    Usd.TimeCode(float(f)))
    with Sdf.ChangeBlock():
        for op, samples in ops:
            for f, v in samples:
                op.Set(v, Usd.TimeCode(float(f)))


def build_stage(env: Environment, rig: Rig, clip: Clip, *, fps: int, extras: dict,
                debug_meshes: Sequence = (), props: Sequence = (),
                extra_clips: Sequence[Clip] = (), root_motion: NodeTrack | None = None,
                crowd: Sequence[Clip] = (), crowd_root_motion: Sequence[NodeTrack | None] = ()):
    """The scene as an in-memory Usd.Stage (see the module docstring for its layout).

    props       : (name, vertices, faces, rgba) animated objects (prey) under /World/Prey,
                  driven by the clip's node tracks of the same name
    debug_meshes: (name, vertices, faces, rgba) overlays in the environment's local frame
    extra_clips : per-behaviour clips, written as SkelAnimation prims under
                  /World/Centipede/Clips (not bound: the Skeleton plays the full clip)
    root_motion : the motion an in-place clip leaves out (a track on the `root` joint), written
                  as the SkelAnimation /World/Centipede/Clips/root_motion over that joint alone
    crowd       : the bake clips of a crowd's further creatures (creature 1, 2, ...), each a
                  SkelRoot of its own at its clip's placement; extra_clips drive creature 0 only
    crowd_root_motion : their root motion tracks (in-place), as root_motion
    Each clip's `events` go into its SkelAnimation's customData.
    """
    Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdSkel, Vt = _pxr()
    if fps <= 0:
        raise ExportError(f"fps must be > 0 (got {fps})")
    skel = rig.skeleton
    f_count, j_count = clip.translations.shape[:2]
    if j_count != skel.n_joints:
        raise ExportError(f"clip has {j_count} joints, the skeleton {skel.n_joints}")
    if f_count == 0:
        raise ExportError("the clip has no frames")

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(float(fps))
    stage.SetFramesPerSecond(float(fps))
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(float(f_count - 1))

    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    Usd.ModelAPI(world.GetPrim()).SetKind("assembly")
    # set as one dictionary: SetCustomDataByKey would split keys containing ":" into levels
    world.GetPrim().SetCustomData(_custom_data_value(jsonable(dict(extras))))
    looks = UsdGeom.Scope.Define(stage, "/World/Looks").GetPath()
    taken, debug_names, part_names = _stage_names(rig, props, debug_meshes, extra_clips,
                                                  1 + len(crowd))

    # -- environment
    env_xf = UsdGeom.Xform.Define(stage, "/World/Environment")
    _offset(env_xf, env.origin)
    env_path = env_xf.GetPath()
    with Sdf.ChangeBlock():     # one recomposition for the level's meshes, however many
        for m, rgba in environment_parts(env):
            nm = safe_name(m.name, taken, "env_mesh")
            mat = _material(stage, looks, safe_name(f"{nm}_mat", taken), rgba, 1.0, m.metallic,
                            m.roughness)
            _mesh(stage, env_path.AppendChild(nm), m.vertices, m.faces, m.normals, rgba, mat,
                  double_sided=True)

    # -- sun: DistantLight shines along its local -Z
    sun = env.sun
    light = UsdLux.DistantLight.Define(stage, "/World/Sun")
    tracks = {t.node: t for t in clip.tracks}
    track_keys = {} if clip.keys is None else dict(zip(tracks, clip.keys.tracks))
    if "Sun" in tracks:
        _animate_xform(light, tracks["Sun"], track_keys.get("Sun"))
    else:
        q = light_rotation(sun.direction)
        light.AddOrientOp().Set(Gf.Quatf(float(q[3]), float(q[0]), float(q[1]), float(q[2])))
    light.CreateIntensityAttr().Set(float(sun.intensity))
    light.CreateColorAttr().Set(Gf.Vec3f(*[float(c) for c in sun.color]))

    # -- the creature, the props (prey, under a static Xform at the placement), the skinned
    # meshes; then a crowd's further creatures, whose meshes reference creature 0's
    root, sk = _creature(stage, rig, clip, "/World/Centipede", extra_clips, root_motion)
    if props:
        _props(stage, looks, taken, props, tracks, clip.placement, track_keys)
    meshes = _skinned_meshes(stage, looks, part_names, rig, root, sk)
    motions = list(crowd_root_motion) + [None] * (len(crowd) - len(crowd_root_motion))
    for i, (c, motion) in enumerate(zip(crowd, motions), start=1):
        if c.tracks:
            raise ExportError("only the main clip drives scene nodes (prey, sun)")
        top = creature_label(i, 1 + len(crowd))[0]
        names = [(safe_name(f"{m}_{top[len('Centipede_'):]}", taken), mat)
                 for m, mat in part_names]
        root_i, sk_i = _creature(stage, rig, c, f"/World/{top}", (), motion)
        _skinned_meshes(stage, looks, names, rig, root_i, sk_i, meshes)

    # -- debug overlays, in the environment's frame
    if debug_meshes:
        _debug_layers(stage, looks, taken, debug_meshes, debug_names, env.origin)
    return stage


def _creature(stage, rig: Rig, clip: Clip, path: str, extra_clips=(),
              root_motion: NodeTrack | None = None):
    """One creature's SkelRoot at `path`, translated by clip.placement, with its Skeleton, the
    bound Animation (the clip) and Clips/<name> (extra_clips, root_motion).
    Returns (the SkelRoot, the Skeleton)."""
    _, _, Usd, UsdGeom, _, _, UsdSkel, Vt = _pxr()
    skel = rig.skeleton
    j_count = skel.n_joints
    if clip.translations.shape[1] != j_count:
        raise ExportError(f"clip has {clip.translations.shape[1]} joints, the skeleton {j_count}")
    root = UsdSkel.Root.Define(stage, path)
    Usd.ModelAPI(root.GetPrim()).SetKind("component")
    _offset(root, clip.placement)
    sk = UsdSkel.Skeleton.Define(stage, f"{path}/Skeleton")
    joints = Vt.TokenArray(list(skel.joint_paths()))
    sk.CreateJointsAttr(joints)
    sk.CreateJointNamesAttr(Vt.TokenArray(list(skel.names)))
    sk.CreateBindTransformsAttr(_matrices(skel.world_bind()))
    sk.CreateRestTransformsAttr(_matrices(skel.local_rest_matrices()))

    anim = _skel_animation(stage, f"{path}/Animation", joints, clip)
    _events(anim, clip)
    UsdSkel.BindingAPI.Apply(sk.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    if extra_clips or root_motion is not None:
        clips_path = UsdGeom.Scope.Define(stage, f"{path}/Clips").GetPath()
        for c in extra_clips:
            if c.translations.shape[1] != j_count:
                raise ExportError(f"clip {c.name!r} has {c.translations.shape[1]} joints, "
                                  f"the skeleton {j_count}")
            if np.any(c.placement != clip.placement):
                raise ExportError(f"clip {c.name!r} does not share the main clip's placement")
            _events(_skel_animation(stage, clips_path.AppendChild(c.name), joints, c), c)
        if root_motion is not None:
            _root_motion(stage, clips_path.AppendChild("root_motion"), skel, root_motion)
    return root, sk


def _skinned_meshes(stage, looks, part_names, rig: Rig, root, sk, meshes: dict | None = None):
    """The creature's skinned Meshes under its SkelRoot `root`, bound to its Skeleton `sk`,
    named by part_names ((mesh, material) per rig.mesh.materials entry).
    meshes : {material index: (Mesh prim path, Material)} of a creature already written: the
             Meshes then reference those prims (the mesh data is stored once), with their own
             skeleton and material bindings
    Returns {material index: (Mesh prim path, Material path)}."""
    Gf, _, _, UsdGeom, _, UsdShade, UsdSkel, Vt = _pxr()
    mesh = rig.mesh
    identity = Gf.Matrix4d(1.0)
    out = {}
    for mi, (mname, rgb) in enumerate(mesh.materials):
        used, faces = mesh.submesh(mi)
        if not len(faces):
            continue
        nm, mat_nm = part_names[mi]
        path = root.GetPath().AppendChild(nm)
        if meshes is not None:
            src, mat = meshes[mi]
            prim = UsdGeom.Mesh.Define(stage, path).GetPrim()
            prim.GetReferences().AddInternalReference(src)
            UsdShade.MaterialBindingAPI.Apply(prim).Bind(
                UsdShade.Material(stage.GetPrimAtPath(mat)))
            UsdSkel.BindingAPI.Apply(prim).CreateSkeletonRel().SetTargets([sk.GetPath()])
            out[mi] = (src, mat)
            continue
        mat = _material(stage, looks, mat_nm, rgb, 1.0, 0.0, 0.6)
        m = _mesh(stage, path, mesh.vertices[used], faces, mesh.normals[used], tuple(rgb), mat,
                  double_sided=False)
        out[mi] = (path, mat)
        binding = UsdSkel.BindingAPI.Apply(m.GetPrim())
        binding.CreateSkeletonRel().SetTargets([sk.GetPath()])
        binding.CreateJointIndicesPrimvar(False, 4).Set(
            Vt.IntArray.FromNumpy(mesh.joints[used].astype(np.int32).reshape(-1)))
        binding.CreateJointWeightsPrimvar(False, 4).Set(
            Vt.FloatArray.FromNumpy(mesh.weights[used].astype(np.float32).reshape(-1)))
        binding.CreateGeomBindTransformAttr(identity)
    return out



def _props(stage, looks, taken: set[str], props: Sequence, tracks: dict, placement,
           track_keys: dict | None = None) -> None:
    """/World/Prey (translated by placement (3,) float64 metres, world) with one animated Xform
    per prop (name, vertices, faces, rgba), named `name` and driven by tracks[name] (at the kept
    frames track_keys[name] of a reduced clip), holding its mesh `<name>_mesh`; materials
    `<name>_mat` (names made unique against `taken`)."""
    _, _, _, UsdGeom, _, _, _, _ = _pxr()
    prey_xf = UsdGeom.Xform.Define(stage, "/World/Prey")
    _offset(prey_xf, placement)
    for name, verts, faces, rgba in props:
        xf = UsdGeom.Xform.Define(stage, prey_xf.GetPath().AppendChild(name))
        if name in tracks:
            _animate_xform(xf, tracks[name], (track_keys or {}).get(name))
        rgba = tuple(float(c) for c in rgba) + (1.0,) * (4 - len(rgba))
        mat = _material(stage, looks, safe_name(f"{name}_mat", taken), rgba, 1.0, 0.0, 0.7)
        _mesh(stage, xf.GetPath().AppendChild(safe_name(f"{name}_mesh", taken)), verts, faces,
              None, rgba, mat, double_sided=False)


def _debug_layers(stage, looks, taken: set[str], debug_meshes: Sequence, names: Sequence[str],
                  origin) -> None:
    """/World/Debug (translated by origin (3,) float64 metres, world: the meshes are in the
    environment's local frame) with one mesh per non-empty (name, vertices, faces, rgba), named
    by `names` (reserved in `taken`); materials `<name>_mat`."""
    _, _, _, UsdGeom, _, _, _, _ = _pxr()
    dbg_xf = UsdGeom.Xform.Define(stage, "/World/Debug")
    _offset(dbg_xf, origin)
    for (name, verts, faces, rgba), nm in zip(debug_meshes, names):
        if len(verts) == 0 or len(faces) == 0:
            log.warning("skipping empty debug layer %r", name)
            continue
        rgba = tuple(float(c) for c in rgba) + (1.0,) * (4 - len(rgba))
        mat = _material(stage, looks, safe_name(f"{nm}_mat", taken), rgba, rgba[3], 0.0, 1.0)
        _mesh(stage, dbg_xf.GetPath().AppendChild(nm), verts, faces, None, rgba, mat,
              double_sided=True)


def write_usd(path: Path, env: Environment, rig: Rig, clip: Clip, *, fps: int, extras: dict,
              debug_meshes: Sequence = (), props: Sequence = (),
              extra_clips: Sequence[Clip] = ()) -> None:
    """Write the stage to `path`: `.usda` gives text, `.usd`/`.usdc` crate (binary).

    Written to a temporary file in the same folder and renamed, so a failure leaves any previous
    file intact. ExportError when the folder is missing or unwritable.
    """
    path = Path(path)
    if path.suffix not in (".usd", ".usda", ".usdc"):
        raise ExportError(f"cannot write {path}: USD output needs a .usd, .usda or .usdc suffix")
    stage = build_stage(env, rig, clip, fps=fps, extras=extras, debug_meshes=debug_meshes,
                        props=props, extra_clips=extra_clips)
    with atomic_output(path) as tmp:
        save_stage(stage, tmp, path)


def save_stage(stage, tmp: Path, path: Path) -> None:
    """Export `stage` into the (temporary) file `tmp`, in the format `path`'s suffix asks for:
    `.usda` text, `.usd`/`.usdc` crate. ExportError when USD fails."""
    tmp = Path(tmp)
    if len(Path(os.path.abspath(tmp)).parts) == 2:
        # a file right under / : USD's safe output refuses it ("Destination directory ''
        # does not exist"), so the layer goes into a hidden folder there and is moved up
        staging = Path(tempfile.mkdtemp(prefix=".baker-usd-", dir=tmp.parent))
        try:
            _export_layer(stage, staging / tmp.name, path)
            os.replace(staging / tmp.name, tmp)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        return
    _export_layer(stage, tmp, path)


def _export_layer(stage, tmp: Path, path: Path) -> None:
    from pxr import Tf

    args = {"format": "usdc"} if Path(path).suffix == ".usd" else {}
    try:
        ok = stage.GetRootLayer().Export(str(tmp), args=args)
    except Tf.ErrorException as e:      # a failed write (a full disk): USD's first reason
        raise ExportError(f"cannot write {path}: {usd_error_reason(e)}") from None
    if not ok:
        raise ExportError(f"cannot write {path}: USD export failed")


def usd_error_reason(error: Exception) -> str:
    """The first reason in a pxr Tf.ErrorException (its text lists every error USD posted,
    each as "Error in '<function>' at line <n> in file <file> : '<reason>'")."""
    for line in exception_text(error).splitlines():
        reason = line.partition(" : ")[2].strip().strip("'")
        if reason:
            return reason
    return "USD export failed"
