"""USD writer: UsdValidation, UsdSkel read-back against the GLB, metadata, determinism."""

import json
import os
import secrets
from pathlib import Path

import numpy as np
import pytest
from glb_read import Glb
from validator import usd_issues, usd_validate

from baker.errors import ExportError
from baker.export.gltf import build_glb
from baker.export.usd import write_usd
from baker.geometry.transforms import quat_rotate, trs_to_matrix

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdLux, UsdSkel  # noqa: E402

NAV = ("navmesh", np.array([[0, 0.001, 0], [0.5, 0.001, 0], [0, 0.001, 0.5]]),
       np.array([[0, 2, 1]]), (0.1, 0.6, 1.0, 0.5))


@pytest.fixture(scope="module", params=[".usd", ".usda"])
def usd_path(request, tmp_path_factory, small_env, rig, clip, bake_extras):
    path = tmp_path_factory.mktemp("usd") / f"centipede{request.param}"
    write_usd(path, small_env, rig, clip, fps=30, extras=bake_extras, debug_meshes=(NAV,))
    return path


@pytest.fixture(scope="module")
def stage(usd_path):
    return Usd.Stage.Open(str(usd_path))


def test_file_format_follows_the_suffix(usd_path):
    head = usd_path.read_bytes()[:8]
    assert head == (b"PXR-USDC" if usd_path.suffix == ".usd" else b"#usda 1.")


def test_usd_validation_zero_errors(stage):
    assert usd_validate(stage) == []
    # and nothing else either (warnings/notes) at the time of writing
    assert [(e.GetName(), e.GetMessage()) for e in usd_issues(stage)] == []


def test_stage_metadata(stage, clip):
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 30 and stage.GetFramesPerSecond() == 30
    assert stage.GetStartTimeCode() == 0 and stage.GetEndTimeCode() == clip.n_frames - 1
    assert stage.GetDefaultPrim().GetPath() == "/World"


def test_prims(stage, rig, small_env):
    for p in ("/World/Environment/ground", "/World/Environment/rock_1", "/World/Environment/log_A",
              "/World/Debug/navmesh", "/World/Centipede/body", "/World/Centipede/legs"):
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(p))
        assert mesh, p
        assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
        assert mesh.GetNormalsAttr().HasValue()
        assert mesh.GetDisplayColorAttr().HasValue()
    assert stage.GetPrimAtPath("/World/Centipede").IsA(UsdSkel.Root)
    light = UsdLux.DistantLight(stage.GetPrimAtPath("/World/Sun"))
    m = np.array(light.ComputeLocalToWorldTransform(0)).T          # column-vector convention
    np.testing.assert_allclose(m[:3, :3] @ [0, 0, -1], -small_env.sun.direction, atol=1e-6)


def test_skeleton_and_binding(stage, rig):
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Centipede/Skeleton"))
    assert list(skel.GetJointsAttr().Get()) == list(rig.skeleton.joint_paths())
    bind = np.array(skel.GetBindTransformsAttr().Get()).transpose(0, 2, 1)
    np.testing.assert_allclose(bind, rig.skeleton.world_bind(), atol=1e-12)
    rest = np.array(skel.GetRestTransformsAttr().Get()).transpose(0, 2, 1)
    np.testing.assert_allclose(rest, rig.skeleton.local_rest_matrices(), atol=1e-12)
    src = UsdSkel.BindingAPI(skel.GetPrim()).GetAnimationSourceRel().GetTargets()
    assert [str(p) for p in src] == ["/World/Centipede/Animation"]
    total = 0
    for name in ("body", "legs"):
        prim = stage.GetPrimAtPath(f"/World/Centipede/{name}")
        assert prim.HasAPI(UsdSkel.BindingAPI)
        b = UsdSkel.BindingAPI(prim)
        ji, jw = b.GetJointIndicesPrimvar(), b.GetJointWeightsPrimvar()
        assert ji.GetElementSize() == 4 and jw.GetElementSize() == 4
        assert ji.GetInterpolation() == "vertex" and jw.GetInterpolation() == "vertex"
        w = np.array(jw.Get()).reshape(-1, 4)
        assert np.all(np.abs(w.sum(1) - 1) <= 2e-7)
        assert np.array(b.GetGeomBindTransformAttr().Get()).tolist() == np.eye(4).tolist()
        assert [str(p) for p in b.GetSkeletonRel().GetTargets()] == ["/World/Centipede/Skeleton"]
        total += len(w)
    assert total == len(rig.mesh.vertices)
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Centipede/Animation"))
    assert anim.GetRotationsAttr().GetTypeName() == "quatf[]"
    assert anim.GetScalesAttr().GetTypeName() == "half3[]"
    assert anim.GetTranslationsAttr().GetTypeName() == "float3[]"


def _usd_local(stage, n_frames):
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath("/World/Centipede"))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Centipede/Skeleton"))
    query = cache.GetSkelQuery(skel)
    anim_query = query.GetAnimQuery()
    assert anim_query
    assert list(anim_query.GetJointTransformTimeSamples()) == list(range(n_frames))
    return np.stack([np.array(anim_query.ComputeJointLocalTransforms(Usd.TimeCode(f))).transpose(0, 2, 1)
                     for f in range(n_frames)])


def test_usd_joint_transforms_match_glb(stage, small_env, rig, clip, bake_extras):
    usd_m = _usd_local(stage, clip.n_frames)                       # (F, J, 4, 4) column vectors
    glb = Glb(build_glb(small_env, rig, clip, extras=bake_extras))
    tracks = glb.animation_tracks()
    t = np.stack([tracks[(n, "translation")][1] for n in rig.skeleton.names], 1).astype(np.float64)
    q = np.stack([tracks[(n, "rotation")][1] for n in rig.skeleton.names], 1).astype(np.float64)
    glb_m = trs_to_matrix(t, q)
    err = np.abs(usd_m - glb_m).max()
    assert err < 1e-4, err


def test_usd_skinning_poses_the_mesh_on_the_trajectory(stage, rig, trajectory):
    # world-space joint transforms from UsdSkel put the head where the trajectory says
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath("/World/Centipede"))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Centipede/Skeleton")))
    for f in (0, trajectory.n_frames // 2, trajectory.n_frames - 1):
        xf = np.array(query.ComputeJointSkelTransforms(Usd.TimeCode(f))).transpose(0, 2, 1)
        np.testing.assert_allclose(xf[rig.spine, :3, 3], trajectory.spine_positions[f], atol=1e-5)


def test_extras_as_custom_data(stage):
    cd = stage.GetPrimAtPath("/World").GetCustomData()
    assert cd["seed"] == 7 and cd["rig"] == "scolopendra"
    assert json.loads(cd["timeline"])[0]["state"] == "wander"
    assert json.loads(cd["events"]) == []


def test_usda_is_deterministic(tmp_path, small_env, rig, clip, bake_extras):
    a, b = tmp_path / "a.usda", tmp_path / "b.usda"
    for p in (a, b):
        write_usd(p, small_env, rig, clip, fps=30, extras=bake_extras)
    assert a.read_bytes() == b.read_bytes()


def test_usdc_is_deterministic(tmp_path, small_env, rig, clip, bake_extras):
    a, b = tmp_path / "a.usd", tmp_path / "b.usd"
    for p in (a, b):
        write_usd(p, small_env, rig, clip, fps=30, extras=bake_extras)
    assert a.read_bytes() == b.read_bytes()


def test_write_usd_errors(tmp_path, small_env, rig, clip):
    with pytest.raises(ExportError):
        write_usd(tmp_path / "missing" / "x.usd", small_env, rig, clip, fps=30, extras={})
    with pytest.raises(ExportError):
        write_usd(tmp_path / "x.abc", small_env, rig, clip, fps=30, extras={})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not os.access("/", os.W_OK), reason="/ is not writable here")
@pytest.mark.parametrize("suffix", [".usd", ".usda"])
def test_a_file_right_under_the_root_folder(tmp_path, small_env, rig, clip, bake_extras, suffix):
    """`--out /` writes /centipede.*: USD's own safe output refused a file right under /
    ('Destination directory '' does not exist'); the same bytes as anywhere else, nothing
    left beside them."""
    name = f"baker-test-{secrets.token_hex(6)}"
    before = set(os.listdir("/"))
    path = Path("/") / f"{name}{suffix}"
    try:
        write_usd(path, small_env, rig, clip, fps=30, extras=bake_extras)
        write_usd(tmp_path / path.name, small_env, rig, clip, fps=30, extras=bake_extras)
        assert path.read_bytes() == (tmp_path / path.name).read_bytes()
        assert set(os.listdir("/")) - before == {path.name}
    finally:
        path.unlink(missing_ok=True)


def test_quaternion_order_round_trips(stage, clip):
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Centipede/Animation"))
    rots = anim.GetRotationsAttr().Get(Usd.TimeCode(5))
    q = rots[3]
    np.testing.assert_allclose([*q.GetImaginary(), q.GetReal()], clip.rotations[5, 3], atol=0)
    v = quat_rotate(clip.rotations[5, 3].astype(float), np.array([0.0, 0, 1]))
    assert np.isfinite(v).all()


def _schema_material(stage, looks_path, name, rgb, opacity, metallic, roughness):
    """The material as UsdShade authors it (the reference usd._material matches)."""
    from pxr import Gf, Sdf, UsdShade

    mat = UsdShade.Material.Define(stage, looks_path.AppendChild(name))
    shader = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("PreviewSurface"))
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(
        Gf.Vec3f(*[float(np.clip(c, 0, 1)) for c in rgb[:3]]))
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(np.clip(metallic, 0, 1)))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(np.clip(roughness, 0, 1)))
    if opacity < 1.0:
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(opacity))
    mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return mat


def _schema_mesh(stage, path, v, f, n, rgba, material, double_sided):
    """The mesh as UsdGeom and UsdShade author it (the reference usd._mesh matches)."""
    from pxr import Gf, UsdGeom, UsdShade, Vt

    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(v))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(f), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(f.astype(np.int32).reshape(-1)))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(n))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreateDoubleSidedAttr(bool(double_sided))
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, v.min(0))),
                                         Gf.Vec3f(*map(float, v.max(0)))]))
    mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*[float(c) for c in rgba[:3]])]))
    if len(rgba) > 3 and rgba[3] < 1.0:
        mesh.CreateDisplayOpacityAttr(Vt.FloatArray([float(rgba[3])]))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


@pytest.mark.parametrize("rgba, double_sided", [((0.2, 0.3, 0.4, 1.0), True),
                                                ((0.9, 0.1, 0.1, 0.5), False)])
def test_meshes_authored_in_sdf_match_the_schema_api(rgba, double_sided):
    """Meshes and materials are authored straight in the layer (one recomposition for a
    level's thousands of meshes): the same specs, in the same order, as UsdGeom/UsdShade
    author."""
    from pxr import Sdf, Usd, UsdGeom

    from baker.export import checked_mesh, usd

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0.5, 1]], np.float32)
    f = np.array([[0, 2, 1], [1, 2, 3]])
    texts = []
    for sdf in (False, True):
        stage = Usd.Stage.CreateInMemory()
        looks = UsdGeom.Scope.Define(stage, "/World/Looks").GetPath()
        env = UsdGeom.Xform.Define(stage, "/World/Environment").GetPath()
        if sdf:
            with Sdf.ChangeBlock():
                mat = usd._material(stage, looks, "m", rgba, rgba[3], 0.1, 0.8)
                usd._mesh(stage, env.AppendChild("g"), v, f, None, rgba, mat, double_sided)
        else:
            mat = _schema_material(stage, looks, "m", rgba, rgba[3], 0.1, 0.8)
            _schema_mesh(stage, env.AppendChild("g"), *checked_mesh("g", v, f, None), rgba, mat,
                         double_sided)
        texts.append(stage.GetRootLayer().ExportToString())
    assert texts[0] == texts[1]
    assert ("displayOpacity" in texts[0]) == (rgba[3] < 1)
