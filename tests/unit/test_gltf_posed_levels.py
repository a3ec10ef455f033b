"""Skinned and morphed meshes of a glTF level load in the pose engines draw them with no
animation playing (environment/gltf_pose.py): skinned by the joints' world matrices and inverse
bind matrices (the skinned node's own transform ignored, as the spec says), morph targets at
their default weights (the node's over the mesh's). Bad skins are refused in one line; a level
of neither loads as before. One scene is checked against three.js (tests/tools/three_pose.mjs).
The bad skins' command-line refusals are in the bad-input corpus (glb_skin_*, glb_morph_*)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bad_inputs import good_glb, pack_glb, skinned_gltf
from baker.config import REPO_ROOT
from baker.environment import gltf_pose, load_environment
from baker.errors import EnvironmentLoadError

FLOOR = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], np.float64)
FLOOR_IDX = np.array([0, 2, 1, 0, 3, 2], np.uint32)
TOOLS = Path(__file__).resolve().parents[1] / "tools"


class Glb:
    """A GLB built in code: add() arrays as accessors, then pack()."""

    def __init__(self):
        self.blob = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}],
                    "nodes": [], "meshes": [], "accessors": [], "bufferViews": []}

    def add(self, a: np.ndarray, kind: str, normalized: bool = False, **extra) -> int:
        ctype = {np.dtype(np.float32): 5126, np.dtype(np.uint8): 5121,
                 np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125}[a.dtype]
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.blob),
                                        "byteLength": a.nbytes})
        self.blob += a.tobytes()
        n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[kind]
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": ctype,
               "count": a.size // n, "type": kind, **extra}
        if normalized:
            acc["normalized"] = True
        if kind == "VEC3" and a.dtype == np.float32:
            acc["min"] = a.reshape(-1, 3).min(0).tolist()
            acc["max"] = a.reshape(-1, 3).max(0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def node(self, root: bool = True, **fields) -> int:
        self.doc["nodes"].append(fields)
        if root:
            self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def floor_mesh(self, points=FLOOR, joints=None, weights=None, targets=(), mesh_weights=None,
                   normals=True) -> int:
        attrs = {"POSITION": self.add(np.asarray(points, np.float32), "VEC3")}
        if normals:
            attrs["NORMAL"] = self.add(np.tile(np.float32([0, 1, 0]), (len(points), 1)), "VEC3")
        if joints is not None:
            attrs["JOINTS_0"] = self.add(np.asarray(joints), "VEC4")
            attrs["WEIGHTS_0"] = self.add(np.asarray(weights), "VEC4",
                                          normalized=np.asarray(weights).dtype != np.float32)
        prim = {"attributes": attrs, "indices": self.add(FLOOR_IDX, "SCALAR")}
        if targets:
            prim["targets"] = [{"POSITION": self.add(np.asarray(t, np.float32), "VEC3")}
                               for t in targets]
        mesh = {"name": "floor", "primitives": [prim]}
        if mesh_weights is not None:
            mesh["weights"] = mesh_weights
        self.doc["meshes"].append(mesh)
        return len(self.doc["meshes"]) - 1

    def skin(self, joints: list[int], ibm: np.ndarray | None = None) -> int:
        skin = {"joints": joints}
        if ibm is not None:    # (J, 4, 4) row-major: stored column-major
            skin["inverseBindMatrices"] = self.add(
                np.ascontiguousarray(np.asarray(ibm, np.float32).transpose(0, 2, 1)), "MAT4")
        self.doc.setdefault("skins", []).append(skin)
        return len(self.doc["skins"]) - 1

    def pack(self) -> bytes:
        self.doc["buffers"] = [{"byteLength": len(self.blob)}]
        return pack_glb(self.doc, bytes(self.blob))

    def write(self, path: Path) -> Path:
        path.write_bytes(self.pack())
        return path


def world(env) -> np.ndarray:
    """The single mesh's world vertices (float64)."""
    assert len(env.meshes) == 1
    return env.meshes[0].vertices.astype(np.float64) + env.origin


def trs(t=(0, 0, 0), q=(0, 0, 0, 1), s=(1, 1, 1)) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(q).as_matrix() * np.asarray(s, float)
    m[:3, 3] = t
    return m


def apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    return v @ m[:3, :3].T + m[:3, 3]


ONE_JOINT = (np.tile(np.uint8([0, 0, 0, 0]), (4, 1)), np.tile(np.float32([1, 0, 0, 0]), (4, 1)))
Q30 = Rotation.from_euler("y", 30, degrees=True).as_quat().tolist()


# --------------------------------------------------------------------------- skins
def test_floor_skinned_to_a_raised_turned_joint_loads_raised_and_turned(tmp_path):
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    joint = g.node(name="bone", translation=[0, 2, 0], rotation=Q30)
    g.node(name="floor", mesh=mesh, skin=g.skin([joint]))
    env = load_environment(g.write(tmp_path / "a.glb"))
    expect = apply(trs((0, 2, 0), Q30), FLOOR)
    assert np.abs(world(env) - expect).max() < 1e-6
    assert np.allclose(world(env)[:, 1], 2.0)
    n = env.meshes[0].normals
    assert n is not None and np.allclose(n, [0, 1, 0], atol=1e-6)


def test_inverse_bind_matrices_are_applied(tmp_path):
    """Bound with the joint at (1, 0, 0) turned 30 deg; the joint now at (1, 2, 0) turned 120
    deg: the floor follows the joint's change (90 deg about the joint, 2 m up)."""
    bind = trs((1, 0, 0), Q30)
    now = trs((1, 2, 0), Rotation.from_euler("y", 120, degrees=True).as_quat())
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    joint = g.node(name="bone", matrix=now.T.reshape(-1).tolist())
    g.node(name="floor", mesh=mesh, skin=g.skin([joint], np.linalg.inv(bind)[None]))
    env = load_environment(g.write(tmp_path / "a.glb"))
    expect = apply(now @ np.linalg.inv(bind), FLOOR)
    assert np.abs(world(env) - expect).max() < 1e-5
    assert np.allclose(world(env)[:, 1], 2.0, atol=1e-6)


def test_two_joints_blend_half_and_half(tmp_path):
    """Weights 0.5/0.5 between a joint 2 m up and one 2 m along x: every vertex moves 1 m up and
    1 m along x. Weights that do not sum to 1 (0.3/0.3, normalized bytes 51/51) are normalized."""
    for weights in (np.float32([.5, .5, 0, 0]), np.float32([.3, .3, 0, 0]),
                    np.uint8([51, 51, 0, 0])):
        g = Glb()
        mesh = g.floor_mesh(joints=np.tile(np.uint16([0, 1, 0, 0]), (4, 1)),
                            weights=np.tile(weights, (4, 1)))
        a = g.node(name="up", translation=[0, 2, 0])
        b = g.node(name="along", translation=[2, 0, 0])
        g.node(name="floor", mesh=mesh, skin=g.skin([a, b]))
        env = load_environment(g.write(tmp_path / "b.glb"))
        assert np.abs(world(env) - (FLOOR + [1, 1, 0])).max() < 1e-6, weights


def test_per_vertex_blend(tmp_path):
    """Half the floor on a raised joint, half on one at rest, the seam's vertices shared: a ramp
    where each vertex follows its own joints."""
    joints = np.uint8([[0, 1, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]])
    weights = np.float32([[1, 0, 0, 0], [.25, .75, 0, 0], [1, 0, 0, 0], [.5, .5, 0, 0]])
    g = Glb()
    mesh = g.floor_mesh(joints=joints, weights=weights)
    rest = g.node(name="rest")
    up = g.node(name="up", translation=[0, 4, 0])
    g.node(name="floor", mesh=mesh, skin=g.skin([rest, up]))
    env = load_environment(g.write(tmp_path / "c.glb"))
    assert np.allclose(world(env)[:, 1], [0, 1, 4, 2], atol=1e-6)


def test_vertex_of_no_weight_follows_its_first_joint(tmp_path):
    """three.js's normalizeSkinWeights: a vertex of zero weights gets weight 1 on its first
    joint (JOINTS_0's first slot)."""
    joints = np.tile(np.uint8([1, 0, 0, 0]), (4, 1))
    weights = np.tile(np.float32([0, 0, 0, 0]), (4, 1))
    g = Glb()
    mesh = g.floor_mesh(joints=joints, weights=weights)
    rest = g.node(name="rest")
    up = g.node(name="up", translation=[0, 3, 0])
    g.node(name="floor", mesh=mesh, skin=g.skin([rest, up]))
    env = load_environment(g.write(tmp_path / "d.glb"))
    assert np.allclose(world(env)[:, 1], 3.0)


def test_skinned_node_transform_is_ignored_joint_hierarchy_is_not(tmp_path):
    """The skinned mesh's node is moved, turned and scaled (and has a parent that moves it
    too): none of it counts. The joint is the child of a node 1 m up: its world matrix does."""
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    joint = g.node(root=False, name="bone", translation=[0, 1, 0], rotation=Q30)
    g.node(name="rig", translation=[0, 1, 0], children=[joint])
    skinned = g.node(root=False, name="floor", mesh=mesh, translation=[100, 50, -7],
                     rotation=[0.5, 0.5, 0.5, 0.5], scale=[3, 3, 3], skin=g.skin([joint]))
    g.node(name="holder", translation=[-40, 9, 0], children=[skinned])
    env = load_environment(g.write(tmp_path / "e.glb"))
    assert np.abs(world(env) - apply(trs((0, 2, 0), Q30), FLOOR)).max() < 1e-6


def test_joint_outside_the_scene_is_posed_by_its_own_parents(tmp_path):
    """A joint the scene does not list (an armature left out of it) still has the world matrix
    its parents give it."""
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    joint = g.node(root=False, name="bone", translation=[0, 1, 0])
    g.node(root=False, name="armature", translation=[0, 0.5, 0], children=[joint])
    g.node(name="floor", mesh=mesh, skin=g.skin([joint]))
    env = load_environment(g.write(tmp_path / "f.glb"))
    assert np.allclose(world(env)[:, 1], 1.5)


def test_skinned_node_primitive_without_weights_keeps_the_node_transform(tmp_path):
    """A skinned node's primitive with no JOINTS_0/WEIGHTS_0 is drawn unskinned by three.js
    (placed by the node): so here."""
    g = Glb()
    mesh = g.floor_mesh()
    joint = g.node(name="bone", translation=[0, 5, 0])
    g.node(name="floor", mesh=mesh, translation=[0, 1, 0], skin=g.skin([joint]))
    env = load_environment(g.write(tmp_path / "g.glb"))
    assert np.allclose(world(env), FLOOR + [0, 1, 0])


def test_weights_on_an_unskinned_node_are_ignored(tmp_path):
    """JOINTS_0/WEIGHTS_0 on a mesh whose node has no skin: a plain mesh, the same bytes as
    without them."""
    g, h = Glb(), Glb()
    g.node(name="floor", mesh=g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1]),
           translation=[0, 1, 0])
    h.node(name="floor", mesh=h.floor_mesh(), translation=[0, 1, 0])
    a = load_environment(g.write(tmp_path / "a.glb"))
    b = load_environment(h.write(tmp_path / "b.glb"))
    assert a.meshes[0].vertices.tobytes() == b.meshes[0].vertices.tobytes()
    assert a.meshes[0].normals.tobytes() == b.meshes[0].normals.tobytes()


def test_instanced_skinned_mesh_places_each_instance_after_skinning(tmp_path):
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    joint = g.node(name="bone", translation=[0, 2, 0])
    t = g.add(np.float32([[0, 0, 0], [10, 0, 0]]), "VEC3")
    g.node(name="floor", mesh=mesh, skin=g.skin([joint]), translation=[0, 7, 0],
           extensions={"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t}}})
    g.doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    env = load_environment(g.write(tmp_path / "i.glb"))
    assert np.allclose(world(env), np.concatenate([FLOOR, FLOOR + [10, 0, 0]]) + [0, 2, 0])


# --------------------------------------------------------------------------- morph targets
LIFT = np.tile([0.0, 1.0, 0.0], (4, 1))


def test_morph_target_of_weight_1_lifts_the_floor(tmp_path):
    g = Glb()
    g.node(name="floor", mesh=g.floor_mesh(targets=[LIFT], mesh_weights=[1.0]),
           translation=[0, 0.5, 0])
    env = load_environment(g.write(tmp_path / "m.glb"))
    assert np.allclose(world(env), FLOOR + [0, 1.5, 0])     # morphed, then placed by the node


def test_node_weights_override_mesh_weights(tmp_path):
    """Mesh weights (1, 0), node weights (0, 0.5) of targets lifting 1 m and 4 m: 2 m up. A
    second node of the same mesh without weights uses the mesh's: 1 m up."""
    g = Glb()
    mesh = g.floor_mesh(targets=[LIFT, 4 * LIFT], mesh_weights=[1.0, 0.0])
    g.node(name="a", mesh=mesh, weights=[0.0, 0.5])
    g.node(name="b", mesh=mesh, translation=[10, 0, 0])
    env = load_environment(g.write(tmp_path / "n.glb"))
    by = {m.name: m.vertices.astype(np.float64) + env.origin for m in env.meshes}
    assert np.allclose(by["a"], FLOOR + [0, 2, 0])
    assert np.allclose(by["b"], FLOOR + [10, 1, 0])


def test_sparse_morph_target(tmp_path):
    """A target stored as a sparse accessor with no bufferView (zeros, then two vertices set),
    as Blender and gltf-transform write them: a ramp."""
    g = Glb()
    mesh = g.floor_mesh(targets=[LIFT], mesh_weights=[2.0])
    tgt = g.doc["meshes"][mesh]["primitives"][0]["targets"][0]["POSITION"]
    idx = g.add(np.uint32([2, 3]), "SCALAR")
    vals = g.add(np.float32([[0, 1, 0], [0, 0.5, 0]]), "VEC3")
    a = g.doc["accessors"][tgt]
    del a["bufferView"]
    a["sparse"] = {"count": 2, "indices": {"bufferView": g.doc["accessors"][idx]["bufferView"],
                                           "componentType": 5125},
                   "values": {"bufferView": g.doc["accessors"][vals]["bufferView"]}}
    g.node(name="floor", mesh=mesh)
    env = load_environment(g.write(tmp_path / "s.glb"))
    assert np.allclose(world(env)[:, 1], [0, 0, 2, 1])


def test_morph_then_skin(tmp_path):
    """The target moves the bind-pose vertices, then the joints pose them (the spec's order)."""
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1], targets=[LIFT],
                        mesh_weights=[1.0])
    joint = g.node(name="bone", translation=[0, 2, 0], rotation=Q30)
    g.node(name="floor", mesh=mesh, skin=g.skin([joint]))
    env = load_environment(g.write(tmp_path / "ms.glb"))
    assert np.abs(world(env) - apply(trs((0, 2, 0), Q30), FLOOR + [0, 1, 0])).max() < 1e-6


def test_zero_weights_leave_the_mesh_as_it_was(tmp_path):
    g, h = Glb(), Glb()
    g.node(name="floor", mesh=g.floor_mesh(targets=[LIFT], mesh_weights=[0.0]))
    h.node(name="floor", mesh=h.floor_mesh())
    a = load_environment(g.write(tmp_path / "a.glb"))
    b = load_environment(h.write(tmp_path / "b.glb"))
    assert a.meshes[0].vertices.tobytes() == b.meshes[0].vertices.tobytes()


# --------------------------------------------------------------------------- refused
def _skinned(tmp_path, edit) -> Path:
    doc, blob = skinned_gltf()
    blob = bytearray(blob)
    edit(doc, blob)
    p = tmp_path / "bad.glb"
    p.write_bytes(pack_glb(doc, bytes(blob)))
    return p


def test_the_corpus_skinned_scene_loads_posed(tmp_path):
    """bad_inputs.skinned_gltf, the base of the glb_skin_* cases, is good: its floor is on a
    joint 1 m up and lifted 0.5 m more by its morph target."""
    env = load_environment(_skinned(tmp_path, lambda d, b: None))
    lo = min(m.vertices[:, 1].min() for m in env.meshes) + env.origin[1]
    assert abs(lo - 1.5) < 1e-6


@pytest.mark.parametrize("cid", sorted(k for k in __import__("bad_inputs").SKIN_EDITS))
def test_bad_skins_are_refused_in_one_line(cid, tmp_path):
    import bad_inputs

    with pytest.raises(EnvironmentLoadError) as e:
        load_environment(_skinned(tmp_path, bad_inputs.SKIN_EDITS[cid]))
    assert "\n" not in str(e.value)
    assert bad_inputs.SKIN_EXPECT[cid] in str(e.value), str(e.value)


def test_pose_work_is_bounded(tmp_path, monkeypatch):
    """A mesh posed by many influences or targets passes MAX_POSE_TERMS: refused before the
    work (here with the bound lowered to 100)."""
    monkeypatch.setattr(gltf_pose, "MAX_POSE_TERMS", 100)
    g = Glb()
    g.node(name="floor", mesh=g.floor_mesh(targets=[LIFT] * 30, mesh_weights=[1.0] * 30))
    with pytest.raises(EnvironmentLoadError, match="vertex influences and morph targets"):
        load_environment(g.write(tmp_path / "w.glb"))


def test_too_many_influence_sets_are_refused(tmp_path):
    g = Glb()
    mesh = g.floor_mesh(joints=ONE_JOINT[0], weights=ONE_JOINT[1])
    attrs = g.doc["meshes"][mesh]["primitives"][0]["attributes"]
    for s in range(1, gltf_pose.MAX_SETS + 1):
        attrs[f"JOINTS_{s}"], attrs[f"WEIGHTS_{s}"] = attrs["JOINTS_0"], attrs["WEIGHTS_0"]
    g.node(name="floor", mesh=mesh, skin=g.skin([g.node(name="bone")]))
    with pytest.raises(EnvironmentLoadError, match="JOINTS_n/WEIGHTS_n sets"):
        load_environment(g.write(tmp_path / "sets.glb"))


# --------------------------------------------------------------------------- unchanged levels
def test_levels_without_skins_or_morphs_never_reach_the_poser(tmp_path, monkeypatch):
    """The bundled levels and the corpus scene load without a Poser being made (so their bakes
    keep their bytes)."""
    def refuse(*a, **k):
        raise AssertionError("posed")

    monkeypatch.setattr(gltf_pose.Poser, "__init__", refuse)
    p = tmp_path / "good.glb"
    p.write_bytes(good_glb())
    for path in [p, *sorted((REPO_ROOT / "environments").glob("*.glb"))]:
        assert load_environment(path).meshes


# --------------------------------------------------------------------------- three.js
def three_pose(path: Path) -> list[dict]:
    from validator import ensure_node

    node = ensure_node("the three.js probe")
    r = subprocess.run([node, str(TOOLS / "three_pose.mjs"), str(path.resolve())], cwd=TOOLS,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"three_pose failed ({r.returncode}):\n{r.stderr[-3000:]}")
    return json.loads(r.stdout)["meshes"]


def test_posed_level_matches_three_js(tmp_path):
    """A hill of 9 x 9 vertices skinned to a chain of three joints (a parent 1 m up, turned and
    scaled; inverse bind matrices of a bind pose elsewhere; 1 to 3 influences per vertex of
    uneven weights) and a morph target at node weight 0.7, beside a morphed plain mesh: three.js
    places every vertex where we do, and SkinnedMesh.computeBoundingBox gives our box."""
    rng = np.random.default_rng(7)
    gx, gz = np.meshgrid(np.linspace(-3, 3, 9), np.linspace(-3, 3, 9))
    pts = np.c_[gx.ravel(), 0.3 * np.sin(gx.ravel()), gz.ravel()]
    quads = np.array([[r * 9 + c, (r + 1) * 9 + c, r * 9 + c + 1] for r in range(8)
                      for c in range(8)] + [[r * 9 + c + 1, (r + 1) * 9 + c, (r + 1) * 9 + c + 1]
                                            for r in range(8) for c in range(8)], np.uint32)
    joints = np.stack([rng.permutation(4) for _ in range(len(pts))]).astype(np.uint8)
    w = rng.random((len(pts), 4)) * (np.arange(4) < rng.integers(1, 4, len(pts))[:, None])
    w = (w / w.sum(1, keepdims=True)).astype(np.float32)
    g = Glb()
    prim = {"attributes": {"POSITION": g.add(pts.astype(np.float32), "VEC3"),
                           "JOINTS_0": g.add(joints, "VEC4"),
                           "WEIGHTS_0": g.add(w, "VEC4")},
            "indices": g.add(quads.reshape(-1), "SCALAR"),
            "targets": [{"POSITION": g.add(rng.normal(0, .2, pts.shape).astype(np.float32),
                                           "VEC3")}]}
    g.doc["meshes"].append({"name": "hill", "primitives": [prim], "weights": [0.0]})
    q = lambda axis, deg: Rotation.from_euler(axis, deg, degrees=True).as_quat().tolist()  # noqa
    j3 = g.node(root=False, name="j3", translation=[0.5, 0, 0.2], rotation=q("z", 15))
    j2 = g.node(root=False, name="j2", translation=[1, 0.3, 0], rotation=q("x", -20),
                children=[j3])
    j1 = g.node(root=False, name="j1", translation=[0, 0, 1], scale=[1.2, 0.9, 1.1],
                children=[j2])
    j0 = g.node(name="j0", translation=[0, 1, 0], rotation=q("y", 40), children=[j1])
    bind = [trs((0, 0.2 * k, 0.1 * k), q("y", 10 * k)) for k in range(4)]
    skin = g.skin([j0, j1, j2, j3], np.linalg.inv(np.stack(bind)))
    g.node(name="hill", mesh=0, skin=skin, weights=[0.7], translation=[5, 5, 5])
    flat = {"name": "ledge", "primitives": [{
        "attributes": {"POSITION": g.add((FLOOR + [6, 0, 0]).astype(np.float32), "VEC3")},
        "indices": g.add(FLOOR_IDX, "SCALAR"),
        "targets": [{"POSITION": g.add(LIFT.astype(np.float32), "VEC3")}]}], "weights": [0.25]}
    g.doc["meshes"].append(flat)
    g.node(name="ledge", mesh=1, translation=[0, 0.5, 0])
    path = g.write(tmp_path / "hill.glb")

    env = load_environment(path)
    ours = {m.name: m.vertices.astype(np.float64) + env.origin for m in env.meshes}
    three = {m["name"]: m for m in three_pose(path)}
    assert set(three) == set(ours) == {"hill", "ledge"}
    assert three["hill"]["skinned"] and not three["ledge"]["skinned"]
    for name in ours:
        theirs = np.asarray(three[name]["positions"])
        assert theirs.shape == ours[name].shape
        assert np.abs(theirs - ours[name]).max() < 2e-5, name     # three.js computes in float32
    box = np.asarray(three["hill"]["box"])
    assert np.abs(box - [ours["hill"].min(0), ours["hill"].max(0)]).max() < 2e-5
    assert np.ptp(ours["hill"][:, 1]) > 0.5          # the pose is not a translated copy


def test_draco_skinned_primitive_reads_its_weights_from_the_stream(tmp_path):
    """gltf-transform and gltfpack compress JOINTS_0 and WEIGHTS_0 into the Draco stream with
    the positions (their accessors have no bufferView): the weights come from the stream."""
    import DracoPy

    joints = np.uint8([[0, 1, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]])
    weights = np.float32([[1, 0, 0, 0], [.25, .75, 0, 0], [1, 0, 0, 0], [.5, .5, 0, 0]])
    enc = DracoPy.encode(FLOOR.astype(np.float32), FLOOR_IDX.reshape(-1, 3),
                         quantization_bits=16, preserve_order=True,
                         generic_attributes={1: joints, 2: weights})
    dec = DracoPy.decode(enc)
    pos_id = next(u for u in range(16) if (a := dec.get_attribute_by_unique_id(u)) is not None
                  and a["attribute_type"] == 0)
    g = Glb()
    g.blob += enc
    g.doc["bufferViews"].append({"buffer": 0, "byteOffset": 0, "byteLength": len(enc)})
    g.doc["accessors"] = [
        {"componentType": 5126, "count": 4, "type": "VEC3", "min": [-2, 0, -2],
         "max": [2, 0, 2]},
        {"componentType": 5121, "count": 4, "type": "VEC4"},
        {"componentType": 5126, "count": 4, "type": "VEC4"},
        {"componentType": 5125, "count": 6, "type": "SCALAR"}]
    g.doc["meshes"].append({"primitives": [{
        "attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2}, "indices": 3,
        "extensions": {"KHR_draco_mesh_compression": {
            "bufferView": 0, "attributes": {"POSITION": pos_id, "JOINTS_0": 1,
                                            "WEIGHTS_0": 2}}}}]})
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    rest = g.node(name="rest")
    up = g.node(name="up", translation=[0, 4, 0])
    g.node(name="floor", mesh=0, skin=g.skin([rest, up]))
    env = load_environment(g.write(tmp_path / "draco.glb"))
    assert np.allclose(world(env)[:, 1], [0, 1, 4, 2], atol=1e-6)
