"""GLB writer: Khronos validator, structure, animation accessors, determinism."""

import numpy as np
import pytest
from glb_read import Glb
from validator import gltf_validate, issues_summary

from baker.atomic import atomic_write_bytes
from baker.export.gltf import build_glb
from baker.geometry.transforms import quat_rotate

NAV = ("navmesh", np.array([[0, 0.001, 0], [0.5, 0.001, 0], [0, 0.001, 0.5], [0.5, 0.001, 0.5]]),
       np.array([[0, 2, 1], [1, 2, 3]]), (0.1, 0.6, 1.0, 0.5))


@pytest.fixture(scope="module")
def glb_bytes(small_env, rig, clip, bake_extras):
    return build_glb(small_env, rig, clip, extras=bake_extras, debug_meshes=(NAV,))


@pytest.fixture(scope="module")
def glb(glb_bytes):
    return Glb(glb_bytes)


def _report(tmp_path, data):
    path = tmp_path / "scene.glb"
    atomic_write_bytes(path, data)
    return gltf_validate(path)


def test_khronos_validator_zero_errors_and_warnings(tmp_path, glb_bytes):
    report = _report(tmp_path, glb_bytes)
    errors = issues_summary(report, 0)
    warnings = issues_summary(report, 1)
    assert errors == [], errors
    assert warnings == [], warnings
    info = report["info"]
    assert info["animationCount"] == 1 and info["hasSkins"] is True
    assert "KHR_lights_punctual" in info.get("extensionsUsed", [])


def test_environment_only_and_rest_pose_files_validate(tmp_path, small_env, rig):
    for r in (None, rig):
        report = _report(tmp_path, build_glb(small_env, r, None, extras={}))
        assert issues_summary(report, 0) == []
        assert issues_summary(report, 1) == []


def test_deterministic_bytes(glb_bytes, small_env, rig, clip, bake_extras):
    again = build_glb(small_env, rig, clip, extras=dict(bake_extras), debug_meshes=(NAV,))
    assert again == glb_bytes
    assert len(glb_bytes) % 4 == 0


def test_node_layout(glb, rig):
    doc = glb.doc
    nodes = doc["nodes"]
    names = [n.get("name") for n in nodes]
    scene_roots = [names[i] for i in doc["scenes"][doc["scene"]]["nodes"]]
    assert scene_roots == ["Environment", "Sun", "Centipede", "centipede_mesh", "navmesh"]
    cent = nodes[glb.node_index("Centipede")]
    assert [names[c] for c in cent["children"]] == ["head"]
    assert not any(k in cent for k in ("translation", "rotation", "scale", "matrix"))
    mesh_node = nodes[glb.node_index("centipede_mesh")]
    assert not any(k in mesh_node for k in ("translation", "rotation", "scale", "matrix"))
    skin = doc["skins"][mesh_node["skin"]]
    assert [names[j] for j in skin["joints"]] == list(rig.skeleton.names)
    assert names[skin["skeleton"]] == "head"
    for j, p in enumerate(rig.skeleton.parents[1:], start=1):
        assert glb.node_index(rig.skeleton.names[j]) in nodes[glb.node_index(rig.skeleton.names[p])]["children"]
    assert all("matrix" not in n for n in nodes)
    env_children = [names[c] for c in nodes[glb.node_index("Environment")]["children"]]
    assert env_children == ["ground", "rock_1", "log_A"]


def test_inverse_bind_matrices(glb, rig):
    skin = glb.doc["skins"][0]
    ibm = glb.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    np.testing.assert_allclose(ibm @ rig.skeleton.world_bind(),
                               np.broadcast_to(np.eye(4), ibm.shape), atol=1e-6)


def test_position_min_max_exact_and_skin_attributes(glb, rig):
    for mesh in glb.doc["meshes"]:
        for prim in mesh["primitives"]:
            acc = glb.doc["accessors"][prim["attributes"]["POSITION"]]
            pos = glb.accessor(prim["attributes"]["POSITION"])
            assert acc["min"] == [float(x) for x in pos.min(0)]
            assert acc["max"] == [float(x) for x in pos.max(0)]
            n = glb.accessor(prim["attributes"]["NORMAL"])
            assert np.abs(np.linalg.norm(n, axis=1) - 1).max() < 1e-6
    prims = glb.doc["meshes"][glb.doc["nodes"][glb.node_index("centipede_mesh")]["mesh"]]["primitives"]
    total = 0
    for prim in prims:
        a = prim["attributes"]
        assert glb.doc["accessors"][a["JOINTS_0"]]["componentType"] == 5123
        assert glb.doc["accessors"][a["WEIGHTS_0"]]["componentType"] == 5126
        w = glb.accessor(a["WEIGHTS_0"])
        assert np.all(np.abs(w.sum(1, dtype=np.float32) - 1) <= 2e-7)
        total += len(w)
    assert total == len(rig.mesh.vertices)


def test_animation_matches_clip(glb, clip, rig):
    anim = glb.doc["animations"][0]
    assert anim["name"] == "bake"
    assert {s["interpolation"] for s in anim["samplers"]} == {"LINEAR"}
    targets = [(c["target"]["node"], c["target"]["path"]) for c in anim["channels"]]
    assert len(targets) == len(set(targets)) == 2 * rig.skeleton.n_joints
    tracks = glb.animation_tracks()
    for j, name in enumerate(rig.skeleton.names):
        t, tr = tracks[(name, "translation")]
        _, rot = tracks[(name, "rotation")]
        np.testing.assert_array_equal(t, clip.times)
        np.testing.assert_array_equal(tr, clip.translations[:, j])
        np.testing.assert_array_equal(rot, clip.rotations[:, j])
    inp = glb.doc["accessors"][anim["samplers"][0]["input"]]
    assert inp["min"] == [float(clip.times[0])] and inp["max"] == [float(clip.times[-1])]


def test_fk_of_glb_tracks_reproduces_trajectory(glb, rig, trajectory):
    tracks = glb.animation_tracks()
    n = rig.skeleton.n_joints
    wt = np.zeros((trajectory.n_frames, n, 3))
    wq = np.zeros((trajectory.n_frames, n, 4))
    from baker.geometry.transforms import quat_mul
    for j, name in enumerate(rig.skeleton.names):
        t = tracks[(name, "translation")][1].astype(np.float64)
        q = tracks[(name, "rotation")][1].astype(np.float64)
        p = rig.skeleton.parents[j]
        if p < 0:
            wt[:, j], wq[:, j] = t, q
        else:
            wt[:, j] = wt[:, p] + quat_rotate(wq[:, p], t)
            wq[:, j] = quat_mul(wq[:, p], q)
    assert np.abs(wt[:, rig.spine] - trajectory.spine_positions).max() < 1e-5


def test_sun_points_along_the_light(glb, small_env):
    doc = glb.doc
    light = doc["extensions"]["KHR_lights_punctual"]["lights"][0]
    assert light["type"] == "directional"
    node = doc["nodes"][glb.node_index("Sun")]
    assert node["extensions"]["KHR_lights_punctual"]["light"] == 0
    minus_z = quat_rotate(np.array(node["rotation"]), np.array([0.0, 0.0, -1.0]))
    np.testing.assert_allclose(minus_z, -small_env.sun.direction, atol=1e-6)


def test_materials(glb, small_env, rig):
    mats = {m["name"]: m for m in glb.doc["materials"]}
    g = mats["ground_mat"]["pbrMetallicRoughness"]
    assert g["baseColorFactor"] == list(small_env.meshes[0].color)
    assert g["metallicFactor"] == 0.0 and g["roughnessFactor"] == 1.0
    body = mats["centipede_body"]["pbrMetallicRoughness"]["baseColorFactor"]
    np.testing.assert_allclose(body[:3], rig.config.colors.body)
    assert mats["navmesh_mat"]["alphaMode"] == "BLEND"


def test_extras_are_plain_json(glb):
    ex = glb.doc["scenes"][0]["extras"]
    assert "extras" not in glb.doc["asset"]                  # stored once, on the scene
    assert ex["seed"] == 7 and ex["events"] == [] and ex["note"] is None
    assert ex["timeline"][0]["state"] == "wander"
    assert isinstance(ex["spacing"], float)
    assert glb.doc["asset"]["version"] == "2.0"
    assert glb.doc["asset"]["generator"].startswith("baker")


def test_awkward_names_large_meshes_and_empty_layers(tmp_path, rig, clip, small_env):
    from conftest import box_mesh

    from baker.environment.model import EnvMesh, Environment

    n = 300                                    # 90601 vertices: needs 32-bit indices
    xs = np.linspace(-1, 1, n + 1)
    gx, gz = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([gx.ravel(), 0.01 * np.sin(5 * gx.ravel()), gz.ravel()], -1).astype(np.float32)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    f = np.concatenate([np.stack([i, i + 1, i + n + 2], -1).reshape(-1, 3),
                        np.stack([i, i + n + 2, i + n + 1], -1).reshape(-1, 3)]).astype(np.uint32)
    big = EnvMesh(name="head", vertices=v, faces=f, normals=np.zeros((3, 3)),  # wrong shape: recomputed
                  color=(0.3, 0.2, 0.1))
    env = Environment(meshes=(big, box_mesh("Sun", (0, 0, 0), (1, 1, 1), (1, 1, 1, 1)),
                              box_mesh("Sun", (0, 0, 0), (1, 1, 1), (1, 1, 1, 1)),
                              box_mesh("3 rocks!", (0, 0, 0), (1, 1, 1), (1, 1, 1, 1))),
                      sun=small_env.sun)
    empty = ("empty", np.zeros((0, 3)), np.zeros((0, 3), int), (1, 0, 0, 1))
    data = build_glb(env, rig, clip, extras={}, debug_meshes=(empty,))
    g = Glb(data)
    names = [nd.get("name") for nd in g.doc["nodes"]]
    assert len(names) == len(set(names))
    assert names.count("head") == 1 and names.count("Sun") == 1 and "empty" not in names
    env_names = [names[c] for c in g.doc["nodes"][g.node_index("Environment")]["children"]]
    assert env_names == ["head_1", "Sun_1", "Sun_2", "_3_rocks_"]
    report = _report(tmp_path, data)
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []
    big_prim = g.doc["meshes"][0]["primitives"][0]
    assert g.doc["accessors"][big_prim["indices"]]["componentType"] == 5125


def test_single_frame_clip_validates(tmp_path, small_env, rig, trajectory):
    from baker.clip import build_clip
    from baker.solve.trajectory import Trajectory

    one = Trajectory(times=trajectory.times[:1], spine_positions=trajectory.spine_positions[:1],
                     spine_rotations=trajectory.spine_rotations[:1],
                     head_surface_normal=trajectory.head_surface_normal[:1],
                     ground_heights=trajectory.ground_heights[:1])
    report = _report(tmp_path, build_glb(small_env, rig, build_clip(one, rig), extras={}))
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []


def test_document_is_pygltflibs_json():
    """gltf._document gives the dict pygltflib's own JSON pass gives (keys, order, values),
    empty and None values dropped, extension dicts kept, attributes included."""
    import json

    import pygltflib as gl

    from baker.export.gltf import _document

    g = gl.GLTF2(asset=gl.Asset(generator="baker", extras={"a": [1, 2.5], "b": {}}))
    g.nodes = [gl.Node(name="n", children=[], translation=[0.0, 1.0, 2.5],
                       extensions={"KHR_lights_punctual": {"light": 0}}),
               gl.Node(name="", mesh=0, rotation=(0.0, 0.0, 0.0, 1.0))]
    g.meshes = [gl.Mesh(primitives=[gl.Primitive(attributes=gl.Attributes(POSITION=0, NORMAL=1),
                                                 indices=2)])]
    g.accessors = [gl.Accessor(bufferView=0, componentType=gl.FLOAT, count=3, type=gl.VEC3,
                               min=[0.0, 0.0, 0.0], max=[1.0, 1.0, 1.0])]
    g.extensionsUsed = ["KHR_lights_punctual"]
    g.scenes = [gl.Scene(name="Scene", nodes=[0, 1])]
    g.scene = 0
    want = json.loads(g.gltf_to_json(separators=(",", ":"), indent=None))
    got = _document(g)
    assert got == want
    assert json.dumps(got) == json.dumps(want)      # the same key order
