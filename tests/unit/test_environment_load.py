"""load_environment: every format round-trips into world space (metres, +Y up) with colours and
the sun; every bad input is an EnvironmentLoadError."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from baker.environment import Environment, load_environment
from baker.environment.load import DEFAULT_SUN_DIRECTION, sanitize_name
from baker.errors import EnvironmentLoadError
from baker.geometry.conventions import is_valid_name


def _tri_mesh() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(1.0, 2.0, 3.0))


def _assert_env(env: Environment, n_meshes: int):
    assert isinstance(env, Environment)
    assert len(env.meshes) == n_meshes
    names = [m.name for m in env.meshes]
    assert len(set(names)) == len(names)
    for m in env.meshes:
        assert is_valid_name(m.name), m.name
        assert m.vertices.dtype == np.float32 and m.vertices.shape[1] == 3
        assert m.faces.dtype == np.uint32 and m.faces.shape[1] == 3 and len(m.faces)
        assert np.all(np.isfinite(m.vertices))
        assert m.faces.max() < len(m.vertices)
    assert np.isclose(np.linalg.norm(env.sun.direction), 1.0)


def _same_point_set(a: np.ndarray, b: np.ndarray, atol=1e-5):
    a = np.unique(np.round(np.asarray(a, float), 5), axis=0)
    b = np.unique(np.round(np.asarray(b, float), 5), axis=0)
    assert a.shape == b.shape
    np.testing.assert_allclose(a, b, atol=atol)


# --------------------------------------------------------------------------- hand-built GLB
def _glb(doc: dict, blob: bytes) -> bytes:
    blob = blob + b"\0" * (-len(blob) % 4)
    doc = dict(doc, buffers=[{"byteLength": len(blob)}])
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return (struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js), 0x4E4F534A)
            + js + struct.pack("<II", len(blob), 0x004E4942) + blob)


def _triangle_glb(nodes, positions, indices=None, mode=4, material=None, lights=None) -> bytes:
    pos = np.asarray(positions, np.float32)
    blob = pos.tobytes()
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
                  "min": pos.min(0).tolist(), "max": pos.max(0).tolist()}]
    prim = {"attributes": {"POSITION": 0}, "mode": mode}
    if indices is not None:
        idx = np.asarray(indices, np.uint16).tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(idx)})
        accessors.append({"bufferView": 1, "componentType": 5123, "count": len(indices),
                          "type": "SCALAR"})
        blob += idx
        prim["indices"] = 1
    doc = {"asset": {"version": "2.0"}, "scene": 0,
           "scenes": [{"nodes": [i for i, n in enumerate(nodes) if n.pop("_root", False)]}],
           "nodes": nodes, "meshes": [{"name": "tri mesh", "primitives": [prim]}],
           "accessors": accessors, "bufferViews": views}
    if material is not None:
        doc["materials"] = [material]
        prim["material"] = 0
    if lights is not None:
        doc["extensionsUsed"] = ["KHR_lights_punctual"]
        doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}
    return _glb(doc, blob)


QUAD = [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]]
QUAD_IDX = [0, 2, 1, 0, 3, 2]


def test_glb_node_hierarchy_is_applied(tmp_path):
    # parent translates, child rotates 90 deg about +Y and scales by 2
    q = [0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]
    nodes = [{"name": "parent", "translation": [10.0, 1.0, -2.0], "children": [1], "_root": True},
             {"name": "child/quad", "rotation": q, "scale": [2.0, 2.0, 2.0], "mesh": 0}]
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.3, 0.9],
                                    "metallicFactor": 0.0, "roughnessFactor": 0.7}}
    p = tmp_path / "scene.glb"
    p.write_bytes(_triangle_glb(nodes, QUAD, QUAD_IDX, material=mat))
    env = load_environment(p)
    _assert_env(env, 1)
    m = env.meshes[0]
    assert m.name == "child_quad"
    # Ry(90): (x, y, z) -> (z, y, -x); then scale 2, then translate
    local = np.asarray(QUAD, float)
    expect = np.stack([local[:, 2], local[:, 1], -local[:, 0]], 1) * 2 + [10.0, 1.0, -2.0]
    _same_point_set(env.to_world(m.vertices), expect)
    np.testing.assert_allclose(m.color, (0.1, 0.2, 0.3, 0.9), atol=1e-7)
    assert m.roughness == pytest.approx(0.7) and m.metallic == 0.0
    assert len(m.faces) == 2
    np.testing.assert_allclose(env.sun.direction, DEFAULT_SUN_DIRECTION)
    assert env.source == str(p)


def test_glb_from_trimesh_with_matrix_transform(tmp_path):
    mesh = _tri_mesh()
    T = trimesh.transformations.compose_matrix(
        translate=[1.0, 2.0, 3.0], angles=[0.3, -0.5, 1.1], scale=[1.5, 1.5, 1.5])
    scene = trimesh.Scene()
    scene.add_geometry(mesh, node_name="box node", geom_name="box", transform=T)
    scene.add_geometry(_tri_mesh(), node_name="box-node", geom_name="box2")  # same sanitized name
    p = tmp_path / "boxes.glb"
    p.write_bytes(scene.export(file_type="glb"))
    env = load_environment(p)
    _assert_env(env, 2)
    world = trimesh.transform_points(mesh.vertices, T)
    got = [m for m in env.meshes if np.allclose(np.sort(env.to_world(m.vertices), 0), np.sort(world, 0),
                                               atol=1e-5)]
    assert len(got) == 1
    np.testing.assert_allclose(env.bounds[1], np.maximum(world.max(0), [0.5, 1.0, 1.5]),
                               atol=1e-5)


def test_glb_points_and_lines_only_is_no_faces(tmp_path):
    for mode in (0, 1, 3):
        p = tmp_path / f"mode{mode}.glb"
        p.write_bytes(_triangle_glb([{"name": "pts", "mesh": 0, "_root": True}], QUAD,
                                    mode=mode))
        with pytest.raises(EnvironmentLoadError, match="no triangle faces"):
            load_environment(p)


def test_glb_strip_and_fan(tmp_path):
    for mode in (5, 6):
        p = tmp_path / f"mode{mode}.glb"
        p.write_bytes(_triangle_glb([{"name": "s", "mesh": 0, "_root": True}], QUAD,
                                    [0, 1, 3, 2] if mode == 5 else [0, 1, 2, 3], mode=mode))
        env = load_environment(p)
        assert len(env.meshes[0].faces) == 2


def test_glb_directional_light_gives_sun(tmp_path):
    # a light node rotated -60 deg about X: its +Z (toward the sun) is (0, sin60, cos60)
    a = np.radians(-60.0)
    q = [np.sin(a / 2), 0.0, 0.0, np.cos(a / 2)]
    nodes = [{"name": "ground", "mesh": 0, "_root": True},
             {"name": "pivot", "children": [2], "_root": True, "rotation": [0, 0, 0, 1]},
             {"name": "sun", "rotation": q, "extensions": {"KHR_lights_punctual": {"light": 1}}}]
    lights = [{"type": "point", "intensity": 100.0},
              {"type": "directional", "intensity": 2.5, "color": [1.0, 0.9, 0.8]}]
    p = tmp_path / "lit.glb"
    p.write_bytes(_triangle_glb(nodes, QUAD, QUAD_IDX, lights=lights))
    env = load_environment(p)
    np.testing.assert_allclose(env.sun.direction, [0.0, np.sin(np.pi / 3), np.cos(np.pi / 3)],
                               atol=1e-9)
    assert env.sun.intensity == pytest.approx(2.5)
    assert env.sun.color == pytest.approx((1.0, 0.9, 0.8))
    # the override wins, keeping the light's intensity and colour
    env2 = load_environment(p, sun_override=(0.0, 2.0, 0.0))
    np.testing.assert_allclose(env2.sun.direction, [0.0, 1.0, 0.0])
    assert env2.sun.intensity == pytest.approx(2.5)


@pytest.mark.parametrize("scale", [1.0, 1e200, 1e300])
def test_a_light_scaled_past_a_float_keeps_its_direction(scale, tmp_path):
    """A sun node, or a DistantLight, scaled 1e300: the length of its +Z overflowed to inf and
    the sun's direction came out (0, 0, 0), a traceback when the GLB's light was written."""
    a = np.radians(-60.0)
    q = [np.sin(a / 2), 0.0, 0.0, np.cos(a / 2)]
    expect = [0.0, np.sin(np.pi / 3), np.cos(np.pi / 3)]
    nodes = [{"name": "ground", "mesh": 0, "_root": True},
             {"name": "sun", "rotation": q, "scale": [scale] * 3, "_root": True,
              "extensions": {"KHR_lights_punctual": {"light": 0}}}]
    p = tmp_path / "lit.glb"
    p.write_bytes(_triangle_glb(nodes, QUAD, QUAD_IDX, lights=[{"type": "directional"}]))
    np.testing.assert_allclose(load_environment(p).sun.direction, expect, atol=1e-9)
    u = tmp_path / "lit.usda"
    u.write_text('#usda 1.0\n(\n    upAxis = "Y"\n    metersPerUnit = 1\n)\n'
                 'def Mesh "floor"\n{\n    int[] faceVertexCounts = [3, 3]\n'
                 '    int[] faceVertexIndices = [0, 2, 1, 0, 3, 2]\n'
                 '    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]\n}\n'
                 'def DistantLight "sun"\n{\n    float3 xformOp:rotateXYZ = (-60, 0, 0)\n'
                 f'    double3 xformOp:scale = ({scale}, {scale}, {scale})\n'
                 '    uniform token[] xformOpOrder = ["xformOp:rotateXYZ", "xformOp:scale"]\n}\n')
    np.testing.assert_allclose(load_environment(u).sun.direction, expect, atol=1e-6)


def test_sun_override_without_light(tmp_path):
    p = tmp_path / "a.stl"
    _tri_mesh().export(p)
    env = load_environment(p, sun_override=[1.0, 1.0, 0.0])
    np.testing.assert_allclose(env.sun.direction, np.array([1.0, 1.0, 0.0]) / np.sqrt(2))
    with pytest.raises(EnvironmentLoadError):
        load_environment(p, sun_override=[0.0, 0.0, 0.0])


# --------------------------------------------------------------------------- OBJ / PLY / STL
def test_obj_with_material_colour(tmp_path):
    (tmp_path / "rock.mtl").write_text("newmtl stone\nKd 0.2 0.4 0.6\n")
    (tmp_path / "rock.obj").write_text(
        "mtllib rock.mtl\no Rock-1\nusemtl stone\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    env = load_environment(tmp_path / "rock.obj")
    _assert_env(env, 1)
    m = env.meshes[0]
    assert len(m.faces) == 2  # quad triangulated
    _same_point_set(env.to_world(m.vertices), [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_allclose(m.color[:3], (0.2, 0.4, 0.6), atol=1 / 255)


def test_obj_without_material_is_grey(tmp_path):
    p = tmp_path / "plain.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    env = load_environment(p)
    assert env.meshes[0].color == (0.5, 0.5, 0.5, 1.0)


def test_ply_round_trip_with_face_colours(tmp_path):
    mesh = _tri_mesh()
    mesh.apply_translation([0.0, 5.0, 0.0])
    mesh.visual.face_colors = np.tile([188, 188, 188, 255], (len(mesh.faces), 1))
    p = tmp_path / "b.ply"
    mesh.export(p)
    env = load_environment(p)
    _assert_env(env, 1)
    _same_point_set(env.to_world(env.meshes[0].vertices), mesh.vertices)
    # sRGB 188 is linear ~0.5
    np.testing.assert_allclose(env.meshes[0].color[:3], [0.5029] * 3, atol=2e-3)


def test_stl_round_trip(tmp_path):
    mesh = _tri_mesh()
    p = tmp_path / "c.stl"
    mesh.export(p)
    env = load_environment(p)
    _assert_env(env, 1)
    assert len(env.meshes[0].faces) == 12
    _same_point_set(env.to_world(env.meshes[0].vertices), mesh.vertices)
    assert env.name == "c"


def test_degenerate_faces_are_dropped_and_nan_vertices_refused(tmp_path):
    p = tmp_path / "dirty.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nv 3 0 0\nv 2 0 0\nv 5 5 5\n"
                 "f 1 2 3\nf 1 2 4\nf 1 2 5\nf 1 1 3\n")
    env = load_environment(p)
    m = env.meshes[0]
    assert len(m.faces) == 1  # two collinear faces and one with a repeated vertex dropped
    assert len(m.vertices) == 3  # unused vertices removed too
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nv nan 0 0\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(EnvironmentLoadError, match="non-finite vertex"):
        load_environment(p)


# --------------------------------------------------------------------------- USD
USDA = """#usda 1.0
(
    upAxis = "Z"
    metersPerUnit = 0.01
)

def Xform "World"
{
    double3 xformOp:translate = (100, 200, 300)
    uniform token[] xformOpOrder = ["xformOp:translate"]

    def Mesh "floor_piece"
    {
        int[] faceVertexCounts = [4, 3]
        int[] faceVertexIndices = [0, 1, 2, 3, 1, 4, 2]
        point3f[] points = [(0, 0, 0), (100, 0, 0), (100, 100, 0), (0, 100, 0), (200, 50, 0)]
        color3f[] primvars:displayColor = [(0.25, 0.5, 0.75)]
        uniform token subdivisionScheme = "none"
    }

    def Mesh "painted" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 10), (10, 0, 10), (0, 10, 10)]
        color3f[] primvars:displayColor = [(1, 1, 1)]
        rel material:binding = </World/Mat>
    }

    def Material "Mat"
    {
        token outputs:surface.connect = </World/Mat/Surface.outputs:surface>
        def Shader "Surface"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = (0.1, 0.6, 0.2)
            float inputs:roughness = 0.8
            token outputs:surface
        }
    }

    def Mesh "hidden"
    {
        token visibility = "invisible"
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    }

    def DistantLight "Sun"
    {
        float inputs:intensity = 4
        float xformOp:rotateX = 30
        uniform token[] xformOpOrder = ["xformOp:rotateX"]
    }
}
"""


def test_usda_z_up_centimetres(tmp_path):
    p = tmp_path / "stage.usda"
    p.write_text(USDA)
    env = load_environment(p)
    _assert_env(env, 2)
    floor = next(m for m in env.meshes if m.name == "floor_piece")
    assert len(floor.faces) == 3  # quad fan-triangulated into 2, plus a triangle
    pts_cm = np.array([[0, 0, 0], [100, 0, 0], [100, 100, 0], [0, 100, 0], [200, 50, 0]], float)
    world_m = (pts_cm + [100, 200, 300]) * 0.01
    expect = np.stack([world_m[:, 0], world_m[:, 2], -world_m[:, 1]], 1)  # Z up -> Y up
    _same_point_set(env.to_world(floor.vertices), expect)
    np.testing.assert_allclose(floor.color, (0.25, 0.5, 0.75, 1.0), atol=1e-6)
    # all faces of the (z = const) floor are horizontal in +Y-up space
    tm = trimesh.Trimesh(env.to_world(floor.vertices), floor.faces, process=False)
    np.testing.assert_allclose(np.abs(tm.face_normals[:, 1]), 1.0, atol=1e-6)

    painted = next(m for m in env.meshes if m.name == "painted")
    np.testing.assert_allclose(painted.color, (0.1, 0.6, 0.2, 1.0), atol=1e-6)
    assert painted.roughness == pytest.approx(0.8)
    # DistantLight rotated 30 deg about X in Z-up space: +Z -> (0, -sin30, cos30) (Z up);
    # converted to Y up: (x, z, -y) = (0, cos30, sin30)
    np.testing.assert_allclose(env.sun.direction, [0.0, np.cos(np.pi / 6), np.sin(np.pi / 6)],
                               atol=1e-6)
    assert env.sun.intensity == pytest.approx(4.0)


def test_usd_binary_crate(tmp_path):
    from pxr import Usd, UsdGeom

    p = tmp_path / "crate.usdc"
    stage = Usd.Stage.CreateNew(str(p))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    mesh = UsdGeom.Mesh.Define(stage, "/Tri")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 0, 1)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.GetRootLayer().Save()
    env = load_environment(p)
    _assert_env(env, 1)
    _same_point_set(env.to_world(env.meshes[0].vertices), [[0, 0, 0], [1, 0, 0], [0, 0, 1]])
    assert env.meshes[0].color == (0.5, 0.5, 0.5, 1.0)


def test_usd_unauthored_units_are_centimetres(tmp_path):
    """USD's fallback metersPerUnit is 0.01 (UsdGeomLinearUnits); the loader honours it."""
    p = tmp_path / "nounits.usda"
    p.write_text('#usda 1.0\ndef Mesh "m"\n{\n    int[] faceVertexCounts = [3]\n'
                 '    int[] faceVertexIndices = [0, 1, 2]\n'
                 '    point3f[] points = [(0, 0, 0), (100, 0, 0), (0, 0, 100)]\n}\n')
    env = load_environment(p)
    _same_point_set(env.to_world(env.meshes[0].vertices), [[0, 0, 0], [1, 0, 0], [0, 0, 1]])


def test_usd_instances_are_expanded(tmp_path):
    p = tmp_path / "inst.usda"
    p.write_text("""#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
class "Proto"
{
    def Mesh "tri"
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 0, 1)]
    }
}
def Xform "A" (instanceable = true
    references = </Proto>)
{
    double3 xformOp:translate = (5, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Xform "B" (instanceable = true
    references = </Proto>)
{
    double3 xformOp:translate = (-5, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
""")
    env = load_environment(p)
    _assert_env(env, 2)
    xs = sorted(float(env.to_world(m.vertices)[:, 0].min()) for m in env.meshes)
    assert xs == [-5.0, 5.0]


def test_gltf_json_with_data_uri_and_external_bin(tmp_path):
    import base64

    pos = np.asarray(QUAD, np.float32)
    idx = np.asarray(QUAD_IDX, np.uint16)
    (tmp_path / "idx.bin").write_bytes(idx.tobytes())
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"name": "q", "mesh": 0, "translation": [0, 3, 0]}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"byteLength": pos.nbytes, "uri": "data:application/octet-stream;base64,"
                        + base64.b64encode(pos.tobytes()).decode()},
                       {"byteLength": idx.nbytes, "uri": "idx.bin"}],
           "bufferViews": [{"buffer": 0, "byteLength": pos.nbytes},
                           {"buffer": 1, "byteLength": idx.nbytes}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5123, "count": 6,
                          "type": "SCALAR"}]}
    p = tmp_path / "q.gltf"
    p.write_text(json.dumps(doc))
    env = load_environment(p)
    _assert_env(env, 1)
    _same_point_set(env.to_world(env.meshes[0].vertices), pos + [0, 3, 0])
    (tmp_path / "idx.bin").unlink()
    with pytest.raises(EnvironmentLoadError, match="q.gltf"):
        load_environment(p)


# --------------------------------------------------------------------------- errors
def test_missing_file(tmp_path):
    with pytest.raises(EnvironmentLoadError, match="not found") as ei:
        load_environment(tmp_path / "nope.glb")
    assert "nope.glb" in str(ei.value) and "\n" not in str(ei.value)


def test_unsupported_extension(tmp_path):
    p = tmp_path / "points.xyz"
    p.write_text("0 0 0\n")
    with pytest.raises(EnvironmentLoadError, match="unsupported") as ei:
        load_environment(p)
    assert "points.xyz" in str(ei.value) and "export" not in str(ei.value)


@pytest.mark.parametrize("name", ["level.fbx", "level.blend", "Level.UMAP"])
def test_unsupported_tool_format_says_to_export(tmp_path, name):
    p = tmp_path / name
    p.write_bytes(b"Kaydara FBX Binary  \x00")
    with pytest.raises(EnvironmentLoadError, match=r"export the level from its tool as glTF"):
        load_environment(p)


@pytest.mark.parametrize("data", [b"", b"glTF", b"not a glb at all" * 10,
                                  b"glTF\x02\x00\x00\x00\xff\xff\x00\x00garbage",
                                  b"glTF\x02\x00\x00\x00\x20\x00\x00\x00"
                                  b"\x0c\x00\x00\x00JSON{not json}"])
def test_corrupt_glb(tmp_path, data):
    p = tmp_path / "bad.glb"
    p.write_bytes(data)
    with pytest.raises(EnvironmentLoadError) as ei:
        load_environment(p)
    assert "bad.glb" in str(ei.value) and "\n" not in str(ei.value)


def test_truncated_glb(tmp_path):
    good = tmp_path / "good.glb"
    good.write_bytes(_triangle_glb([{"name": "q", "mesh": 0, "_root": True}], QUAD, QUAD_IDX))
    load_environment(good)
    bad = tmp_path / "cut.glb"
    bad.write_bytes(good.read_bytes()[:-40])
    with pytest.raises(EnvironmentLoadError, match="cut.glb"):
        load_environment(bad)


@pytest.mark.parametrize("text", ["v 1 2 foo\nv a b c\nf 1 2 3\n",
                                  "\x00\x01\x02\xff binary junk",
                                  "f 1 2 3\nf 4 5 6\n"])
def test_corrupt_obj(tmp_path, text):
    p = tmp_path / "bad.obj"
    p.write_bytes(text.encode("latin-1"))
    with pytest.raises(EnvironmentLoadError, match="bad.obj"):
        load_environment(p)


@pytest.mark.parametrize("eol", ["\n", "\r\n"])
def test_obj_relative_indices_count_back_from_the_face(tmp_path, eol):
    """OBJ's -1 is the last vertex (texture coordinate, normal) defined before the face, not
    the file's last: two objects each ending in `f -3 -2 -1` are two triangles (they read as
    the second one, once)."""
    text = eol.join(["o a", "v 0 0 0", "vt 0 0", "vn 0 1 0", "v 0 0 1", "v 1 0 0",
                     "f -3/-1/-1 -2/-1/-1 -1/-1/-1", "o b", "v 5 0 5", "v 5 0 6", "vt 1 1",
                     "v 6 0 5", "f -3//1 -2//1 -1//1", "o c", "v 9 0 9", "f 4 5 -1", ""])
    p = tmp_path / "relative.obj"
    p.write_text(text)
    env = load_environment(p)
    tri = {tuple(map(tuple, np.round(env.mesh.vertices[f] + env.origin, 6)))
           for f in env.mesh.faces}
    assert tri == {((0, 0, 0), (0, 0, 1), (1, 0, 0)), ((5, 0, 5), (5, 0, 6), (6, 0, 5)),
                   ((5, 0, 5), (5, 0, 6), (9, 0, 9))}


@pytest.mark.parametrize("text, message", [
    ("f -1 -2 -3\nv 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n", "-1 outside the 0 vertices defined"),
    ("v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 0 0 1\nf 1 2 3\n", "-3 outside the 2 vertices defined"),
])
def test_obj_relative_index_before_its_vertices(tmp_path, text, message):
    p = tmp_path / "early.obj"
    p.write_text(text)
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)


def test_obj_with_vertices_but_no_faces(tmp_path):
    p = tmp_path / "cloud.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(EnvironmentLoadError, match="no triangle faces"):
        load_environment(p)


def test_corrupt_usd(tmp_path):
    p = tmp_path / "bad.usda"
    p.write_text("#usda 1.0\ndef Mesh \"m\" {{{{ garbage\n")
    with pytest.raises(EnvironmentLoadError, match="bad.usda"):
        load_environment(p)


def test_corrupt_ply_and_stl(tmp_path):
    for name in ("bad.ply", "bad.stl"):
        p = tmp_path / name
        p.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n"
                      if name.endswith("ply") else b"solid x\nfacet normal 0 0\n")
        with pytest.raises(EnvironmentLoadError, match=name):
            load_environment(p)


FACET = "facet normal 0 1 0\nouter loop\n{}endloop\nendfacet\n"


@pytest.mark.parametrize("corners, end, message", [
    (2, "endsolid x\n", "facet 2 has 2 vertices"),
    (4, "endsolid x\n", "facet 2 has 4 vertices"),
    (3, "", "cut short"),
])
def test_ascii_stl_facets_and_end(tmp_path, corners, end, message):
    tri = "".join(f"vertex {x} 0 {z}\n" for x, z in [(0, 0), (0, 1), (1, 0), (1, 1)])
    text = ("solid Part1 - Body\n" + FACET.format("".join(tri.splitlines(True)[:3]))
            + FACET.format("".join(tri.splitlines(True)[:corners])) + end)
    p = tmp_path / "level.stl"
    p.write_text(text)
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)
    p.write_text("solid Part1 - Body\n" + FACET.format("".join(tri.splitlines(True)[:3]))
                 + "endsolid Part1 - Body\n")
    assert len(load_environment(p).mesh.faces) == 1


# --------------------------------------------------------------------------- names
@pytest.mark.parametrize("raw", ["log-A", "rock 1", "ümlaut/ß", "", "9lives", "x" * 100,
                                 "__a__b__"])
def test_sanitize_name(raw):
    s = sanitize_name(raw)
    assert is_valid_name(s)
    assert not s[0].isdigit()


@pytest.mark.parametrize("light, material, message", [
    ({"color": ["nan", 1, 1]}, None, r"lights\[0\]\.color must be 3 finite numbers from 0 to 1"),
    ({"color": [1, 1]}, None, r"lights\[0\]\.color must be 3 finite numbers"),
    ({"color": [-5, 2, 1]}, None, r"lights\[0\]\.color must be 3 finite numbers from 0 to 1"),
    ({"intensity": -3}, None, r"lights\[0\]\.intensity must be a finite number of at least 0"),
    ({"intensity": float("inf")}, None, r"lights\[0\]\.intensity must be a finite number"),
    ({"intensity": [1]}, None, r"lights\[0\]\.intensity must be a finite number"),
    ({}, {"pbrMetallicRoughness": {"roughnessFactor": "nan"}}, r"roughnessFactor must be a finite"),
    ({}, {"pbrMetallicRoughness": {"metallicFactor": True}}, r"metallicFactor must be a finite"),
])
def test_out_of_range_light_and_material_values_are_one_error(tmp_path, light, material,
                                                              message):
    """A light or material value outside glTF's ranges (which the writers would store, or which
    the report's JSON cannot hold) is a one-line error naming it, not a traceback later."""
    nodes = [{"name": "ground", "mesh": 0, "_root": True},
             {"name": "sun", "_root": True, "extensions": {"KHR_lights_punctual": {"light": 0}}}]
    p = tmp_path / "bad.glb"
    p.write_bytes(_triangle_glb(nodes, QUAD, QUAD_IDX, material=material,
                                lights=[dict({"type": "directional"}, **light)]))
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)


USD_SUN = """#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 1
)

def Mesh "floor"
{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 3, 2, 1]
    point3f[] points = [(-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3)]
    color3f[] primvars:displayColor = [(%s, 0.5, 0.5)]
}

def DistantLight "sun"
{
    float inputs:intensity = %s
    color3f inputs:color = (%s, 1, 1)
    float xformOp:rotateX = -60
    uniform token[] xformOpOrder = ["xformOp:rotateX"]
}
"""


@pytest.mark.parametrize("grey, intensity, red, message", [
    ("0.5", "nan", "1", "intensity nan"), ("0.5", "-2", "1", "at least 0"),
    ("0.5", "1", "-1", "at least 0"), ("nan", "1", "1", "must be finite numbers")])
def test_usd_light_and_material_values_outside_their_ranges_are_one_error(
        tmp_path, grey, intensity, red, message):
    p = tmp_path / "bad.usda"
    p.write_text(USD_SUN % (grey, intensity, red))
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)


def test_a_usd_sun_brighter_than_white_is_clamped(tmp_path):
    p = tmp_path / "hdr.usda"
    p.write_text(USD_SUN % ("0.5", "3", "2"))
    env = load_environment(p)
    assert env.sun.color == (1.0, 1.0, 1.0) and env.sun.intensity == pytest.approx(3.0)


@pytest.mark.parametrize("names, kept", [
    (["floor", "navmesh", "UCX_floor", "rock-colonly", "sky-noimp"], ["floor"]),
    (["floor", "floor-col", "navmesh_floor"], ["floor", "floor_col", "navmesh_floor"]),
    (["NavMesh.001"], ["NavMesh_001"]),              # all there is: kept (names made safe)
])
def test_engine_helper_meshes_are_not_level(tmp_path, names, kept):
    """Meshes engines' naming conventions mark as helpers (a navigation overlay, Unreal's
    collision hulls, Godot's collision-only and not-imported meshes) are left out of the level,
    unless they are all it has."""
    nodes = [{"name": n, "mesh": 0, "_root": True, "translation": [0.0, 0.1 * k, 0.0]}
             for k, n in enumerate(names)]
    p = tmp_path / "level.glb"
    p.write_bytes(_triangle_glb(nodes, QUAD, QUAD_IDX))
    env = load_environment(p)
    assert [m.name for m in env.meshes] == kept


def test_an_obj_s_objects_are_meshes_of_their_own(tmp_path):
    """Each `o` of an OBJ is a mesh, named by it, as Blender imports it (trimesh merged them
    into the first object's mesh): a collision hull or navigation overlay among them is then
    left out as in any other format."""
    quad = "v -2 {y} -2\nv 2 {y} -2\nv 2 {y} 2\nv -2 {y} 2\nf {a} {c} {b}\nf {a} {d} {c}\n"

    def obj(names):
        return "".join(f"o {n}\n" + quad.format(y=0.1 * k, a=4 * k + 1, b=4 * k + 2, c=4 * k + 3,
                                                 d=4 * k + 4) for k, n in enumerate(names))

    p = tmp_path / "level.obj"
    p.write_text(obj(["Floor", "UCX_Floor_00", "navmesh"]))
    env = load_environment(p)
    assert [m.name for m in env.meshes] == ["Floor"]
    assert np.allclose(env.meshes[0].vertices[:, 1] + env.origin[1], 0.0)
    p.write_text(obj(["Floor", "Deck"]))
    env = load_environment(p)
    assert sorted((m.name, len(m.faces)) for m in env.meshes) == [("Deck", 2), ("Floor", 2)]


def test_an_obj_of_many_objects_is_split_only_for_its_helpers(tmp_path):
    """Over MERGE_ABOVE objects the meshes are merged again by material, so they are split
    (about half a millisecond an object in trimesh) only to leave a helper out."""
    from baker.environment.load import MERGE_ABOVE, _obj_split

    n = MERGE_ABOVE + 1
    tiles = "".join(f"o tile_{k}\nv {k} 0 0\nv {k + 1} 0 0\nv {k} 0 1\nf {3 * k + 1} {3 * k + 3} "
                    f"{3 * k + 2}\n" for k in range(n))
    assert _obj_split(b"o a\nv 0 0 0\no b\n") and not _obj_split(b"o only\nv 0 0 0\n")
    assert not _obj_split(tiles.encode())
    helper = f"o navmesh\nv 0 0.1 0\nv {n} 0.1 0\nv 0 0.1 1\nf {3 * n + 1} {3 * n + 3} {3 * n + 2}\n"
    assert _obj_split((tiles + helper).encode())
    p = tmp_path / "level.obj"
    p.write_text(tiles + helper)
    env = load_environment(p)
    assert sum(len(m.faces) for m in env.meshes) == n
    assert np.allclose(np.concatenate([m.vertices[:, 1] for m in env.meshes]) + env.origin[1], 0)
