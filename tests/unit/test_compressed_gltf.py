"""Compressed and instanced glTF levels load: EXT_meshopt_compression and
KHR_meshopt_compression bufferViews (lossless for float data: the same vertices, the same
triangles up to the rotation the index codec may apply) with their filters,
KHR_draco_mesh_compression primitives (within the quantization step) and EXT_mesh_gpu_instancing
nodes (every instance placed). The broken streams are in the bad-input corpus (glb_meshopt_*,
glb_draco_*)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from bad_inputs import good_gltf, pack_glb, scene_arrays
from baker.cli import main
from baker.config import REPO_ROOT
from baker.environment.load import load_environment
from compress_glb import draco_glb, meshopt_glb, read_glb

ENVIRONMENTS_DIR = REPO_ROOT / "environments"
BUNDLED = sorted(ENVIRONMENTS_DIR.glob("*.glb"))


def canonical(faces: np.ndarray) -> np.ndarray:
    """Each triangle rotated to start at its smallest index (winding kept)."""
    r = np.argmin(faces, axis=1)
    rows = np.arange(len(faces))
    return np.stack([faces[rows, (r + k) % 3] for k in range(3)], axis=1)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
@pytest.mark.parametrize("name", ["EXT_meshopt_compression", "KHR_meshopt_compression"])
def test_meshopt_level_loads_the_same_geometry(tmp_path, path, name):
    plain = load_environment(path)
    packed = tmp_path / "packed.glb"
    packed.write_bytes(meshopt_glb(path.read_bytes(), name))
    assert packed.stat().st_size < path.stat().st_size
    env = load_environment(packed)
    assert np.array_equal(env.mesh.vertices, plain.mesh.vertices)
    assert np.array_equal(canonical(env.mesh.faces), canonical(plain.mesh.faces))
    assert [m.color for m in env.meshes] == [m.color for m in plain.meshes]


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_draco_level_loads_within_the_quantization_step(tmp_path, path):
    plain = load_environment(path)
    packed = tmp_path / "draco.glb"
    packed.write_bytes(draco_glb(path.read_bytes(), bits=16))
    env = load_environment(packed)
    step = np.ptp(plain.mesh.vertices, axis=0).max() / (2**16 - 1)
    assert env.mesh.vertices.shape == plain.mesh.vertices.shape
    assert np.abs(env.mesh.vertices - plain.mesh.vertices).max() <= step
    assert np.array_equal(env.mesh.faces, plain.mesh.faces)


def _filtered_glb() -> tuple[bytes, np.ndarray]:
    """The corpus scene with gltfpack's filters: positions as EXPONENTIAL floats, normals as
    OCTAHEDRAL bytes (KHR_mesh_quantization), indices as TRIANGLES; and its positions."""
    import meshopt

    pos, nrm, idx = scene_arrays()
    pos = pos * np.float32(3.7) + np.float32(1234.5)          # exponents that differ
    streams = [
        (meshopt.encode_filter_exp(pos, 22, "SharedComponent"), "ATTRIBUTES", "EXPONENTIAL"),
        (meshopt.encode_filter_oct(np.c_[nrm, np.ones(len(nrm), np.float32)], 4, 8),
         "ATTRIBUTES", "OCTAHEDRAL"),
        (idx, "TRIANGLES", "NONE")]
    doc, _ = good_gltf()
    doc = copy.deepcopy(doc)
    blob, views, fallback = bytearray(), [], 0
    for rows, mode, filt in streams:
        if mode == "TRIANGLES":
            enc, stride, count = meshopt.encode_index_buffer(rows), 4, len(rows)
        else:
            enc, stride, count = meshopt.encode_vertex_buffer(rows), rows.shape[1], len(rows)
        views.append({"buffer": 1, "byteOffset": fallback, "byteLength": count * stride,
                      **({"byteStride": stride} if mode == "ATTRIBUTES" else {}),
                      "extensions": {"EXT_meshopt_compression": {
                          "buffer": 0, "byteOffset": len(blob), "byteLength": len(enc),
                          "byteStride": stride, "count": count, "mode": mode, "filter": filt}}})
        blob += enc + bytes(-len(enc) % 4)
        fallback += count * stride
    doc["bufferViews"] = views
    doc["buffers"] = [{"byteLength": len(blob)}, {
        "byteLength": fallback, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}]
    doc["accessors"][0].update(min=pos.min(0).tolist(), max=pos.max(0).tolist())
    doc["accessors"][1].update(componentType=5120, normalized=True)
    doc["extensionsUsed"] = ["EXT_meshopt_compression", "KHR_lights_punctual",
                             "KHR_mesh_quantization"]
    doc["extensionsRequired"] = ["EXT_meshopt_compression", "KHR_mesh_quantization"]
    return pack_glb(doc, bytes(blob)), pos


def test_meshopt_filters_are_undone(tmp_path):
    data, pos = _filtered_glb()
    p = tmp_path / "filtered.glb"
    p.write_bytes(data)
    env = load_environment(p)
    world = env.mesh.vertices + env.origin
    _, _, idx = scene_arrays()
    assert len(env.mesh.faces) == len(idx) // 3
    assert np.abs(world - pos).max() <= 4 * np.abs(pos).max() * 2.0**-22


@pytest.mark.parametrize("name", ["EXT_meshopt_compression", "KHR_draco_mesh_compression"])
def test_required_but_unused_compression_loads(tmp_path, name):
    """A file may require the extension and use it nowhere: it reads as it is."""
    doc, blob = good_gltf()
    doc = {**doc, "extensionsUsed": [name], "extensionsRequired": [name]}
    p = tmp_path / "scene.glb"
    p.write_bytes(pack_glb(doc, blob))
    plain = tmp_path / "plain.glb"
    plain.write_bytes(pack_glb(*good_gltf()))
    assert np.array_equal(load_environment(p).mesh.vertices,
                          load_environment(plain).mesh.vertices)


@pytest.mark.parametrize("kind", ["meshopt", "draco"])
def test_bake_on_a_compressed_level(tmp_path, kind):
    source = ENVIRONMENTS_DIR / "multistorey.glb"
    level = tmp_path / f"{kind}.glb"
    level.write_bytes((meshopt_glb if kind == "meshopt" else draco_glb)(source.read_bytes()))
    code = main(["bake", str(level), "--seconds", "2", "--no-cache", "--out",
                 str(tmp_path / "out" / "c")])
    assert code == 0
    assert {p.name for p in (tmp_path / "out").iterdir()} == {"c.glb", "c.usd", "c.json"}
    doc, _ = read_glb((tmp_path / "out" / "c.glb").read_bytes())
    assert "EXT_meshopt_compression" not in doc.get("extensionsUsed", [])


def _instanced_glb(rotation=None, scale=None, translation=None, node_scale=(1.0, 1.0, 1.0)):
    """The corpus scene's mesh placed by EXT_mesh_gpu_instancing: float accessors appended
    in a second buffer (a data: URI)."""
    import base64

    doc, blob = good_gltf()
    doc = copy.deepcopy(doc)
    attrs, extra = {}, bytearray()
    for name, arr, kind in (("ROTATION", rotation, "VEC4"), ("SCALE", scale, "VEC3"),
                            ("TRANSLATION", translation, "VEC3")):
        if arr is None:
            continue
        arr = np.asarray(arr, np.float32)
        doc["bufferViews"].append({"buffer": 1, "byteOffset": len(extra),
                                   "byteLength": arr.nbytes})
        doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1,
                                 "componentType": 5126, "count": len(arr), "type": kind})
        attrs[name] = len(doc["accessors"]) - 1
        extra += arr.tobytes()
    if extra:
        doc["buffers"].append({"byteLength": len(extra), "uri": "data:application/octet-stream;"
                               f"base64,{base64.b64encode(bytes(extra)).decode()}"})
    doc["nodes"][0]["scale"] = list(node_scale)
    doc["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": attrs}}
    doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing", "KHR_lights_punctual"]
    doc["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    return pack_glb(doc, blob)


def test_gpu_instancing_places_every_instance(tmp_path):
    """Three instances: moved, turned 90 degrees about +Y and mirrored (winding kept facing
    out), under a node scaled by 2."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_euler("y", [[0], [90], [0]], degrees=True).as_quat()
    t = np.array([[0, 0, 0], [10, 0, 0], [0, 0, -10]], float)
    s = np.array([[1, 1, 1], [1, 1, 1], [-1, 1, 1]], float)
    p = tmp_path / "instanced.glb"
    p.write_bytes(_instanced_glb(q, s, t, node_scale=(2, 2, 2)))
    env = load_environment(p)
    pos, _, idx = scene_arrays()
    world = env.mesh.vertices.astype(np.float64) + env.origin
    mats = [np.diag([2.0, 2, 2]) @ Rotation.from_quat(qk).as_matrix() @ np.diag(sk)
            for qk, sk in zip(q, s)]
    expected = np.concatenate([pos @ m.T + 2 * tk for m, tk in zip(mats, t)])
    assert len(env.mesh.faces) == 3 * len(idx) // 3
    # every expected vertex is in the level (the loader may drop duplicated corners)
    d = np.linalg.norm(world[None, :, :] - expected[:, None, :], axis=2).min(axis=1)
    assert d.max() < 1e-4
    # the mirrored copy's floor still faces up: its triangles' normals point +Y
    tri = world[env.mesh.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    floor = (np.abs(tri[:, :, 1]).max(axis=1) < 1e-6) & (np.ptp(tri[:, :, 0], axis=1) > 4)
    assert floor.sum() == 6 and np.all(n[floor, 1] > 0)


@pytest.mark.parametrize("bad, message", [
    (dict(rotation=[[0, 0, 0, 0]], translation=[[1, 0, 0]]), "zero rotation"),
    (dict(translation=[[1, 0, 0], [2, 0, 0]], scale=[[1, 1, 1]]), "different counts"),
    (dict(), "none of TRANSLATION"),
])
def test_gpu_instancing_refusals(tmp_path, bad, message):
    from baker.errors import EnvironmentLoadError

    p = tmp_path / "bad.glb"
    p.write_bytes(_instanced_glb(**bad))
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)


def test_gpu_instancing_bounded(tmp_path, monkeypatch):
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_TRIANGLES", 100)
    p = tmp_path / "many.glb"
    p.write_bytes(_instanced_glb(translation=np.arange(60.0).reshape(20, 3)))
    with pytest.raises(EnvironmentLoadError,
                       match=r"places 280 triangles and 240 vertices \(20 mesh placements"):
        load_environment(p)


def test_triangle_cap_counts_placements_before_reading(tmp_path, monkeypatch):
    """MAX_TRIANGLES bounds the placed triangles: a glTF's meshes times their nodes and
    instances, counted from the accessors before any is read; an OBJ's after reading."""
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_TRIANGLES", 40)
    p = tmp_path / "three.glb"
    p.write_bytes(_instanced_glb(translation=np.arange(9.0).reshape(3, 3)))   # 3 x 14
    with pytest.raises(EnvironmentLoadError,
                       match=r"places 42 triangles and 36 vertices \(3 mesh placements"):
        load_environment(p)
    p.write_bytes(_instanced_glb(translation=np.arange(6.0).reshape(2, 3)))   # 2 x 14
    assert len(load_environment(p).mesh.faces) == 28
    obj = tmp_path / "many.obj"
    obj.write_text("".join(f"v {i} 0 {i % 2}\n" for i in range(50))
                   + "".join(f"f {i} {i + 1} {i + 2}\n" for i in range(1, 48)))
    with pytest.raises(EnvironmentLoadError, match="has 47 triangles"):
        load_environment(obj)


def _placements(n: int) -> bytes:
    """The corpus mesh placed n times, every other placement with a second material."""
    doc, blob = good_gltf()
    doc = copy.deepcopy(doc)
    doc["materials"].append({"pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.6, 0.2, 1]}})
    doc["meshes"].append({"primitives": [{**doc["meshes"][0]["primitives"][0], "material": 1}]})
    doc["nodes"] = [{"mesh": i % 2, "translation": [5.0 * (i % 40), 0.0, 5.0 * (i // 40)]}
                    for i in range(n)]
    doc["scenes"][0]["nodes"] = list(range(n))
    return pack_glb(doc, blob)


def test_many_objects_merge_into_one_mesh_per_material(tmp_path, monkeypatch):
    from baker.environment import load

    p = tmp_path / "objects.glb"
    p.write_bytes(_placements(40))
    monkeypatch.setattr(load, "MERGE_ABOVE", 1000)
    plain = load_environment(p)
    monkeypatch.setattr(load, "MERGE_ABOVE", 10)
    merged = load_environment(p)
    assert len(plain.meshes) == 40 and len(merged.meshes) == 2
    assert [m.color for m in merged.meshes] == [plain.meshes[0].color, plain.meshes[1].color]
    for m, k in zip(merged.meshes, (0, 1)):
        parts = plain.meshes[k::2]
        assert np.array_equal(m.vertices, np.concatenate([q.vertices for q in parts]))
        assert len(m.faces) == sum(len(q.faces) for q in parts)
        tri = m.vertices[m.faces]
        assert np.array_equal(np.sort(tri.reshape(-1, 9), axis=0), np.sort(np.concatenate(
            [q.vertices[q.faces] for q in parts]).reshape(-1, 9), axis=0))


def test_placements_bounded(tmp_path, monkeypatch):
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_MESHES", 30)
    p = tmp_path / "objects.glb"
    p.write_bytes(_placements(40))
    with pytest.raises(EnvironmentLoadError, match=r"\(40 mesh placements\)"):
        load_environment(p)


def test_vertex_cap_counts_placed_vertices(tmp_path, monkeypatch):
    """A mesh of few triangles and many vertices placed many times is bounded by its
    vertices (MAX_VERTICES), before anything is read."""
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_VERTICES", 30)
    p = tmp_path / "three.glb"
    p.write_bytes(_instanced_glb(translation=np.arange(9.0).reshape(3, 3)))   # 3 x 12
    with pytest.raises(EnvironmentLoadError, match=r"and 36 vertices \(3 mesh placements"):
        load_environment(p)


def test_meshopt_fallback_file_not_needed(tmp_path):
    """A fallback buffer may name an uncompressed file; a decoder never reads it, so a
    missing one is no error (a plain view that reads it is: the corpus' placeholder case)."""
    import base64
    import json

    doc, blob = read_glb(meshopt_glb(pack_glb(*good_gltf())))
    doc["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                + base64.b64encode(blob).decode())
    doc["buffers"][1]["uri"] = "fallback.bin"          # never written
    p = tmp_path / "scene.gltf"
    p.write_text(json.dumps(doc))
    plain = tmp_path / "plain.glb"
    plain.write_bytes(pack_glb(*good_gltf()))
    assert np.array_equal(load_environment(p).mesh.vertices,
                          load_environment(plain).mesh.vertices)
