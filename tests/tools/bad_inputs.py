"""A corpus of bad inputs for `baker`, generated in code (tests/integration/test_bad_inputs.py).

Each case is a `Case(id, make)`: `make(folder)` writes whatever files the case needs into
`folder` and returns the extra command-line arguments of a `baker bake` (or, when the first
item is "navmesh", of a `baker navmesh`). Classes:

- glb_*   : a small good GLB (a floor and a box, a light, a material; built here), its JSON or
            binary mutated: counts, component types, views, strides, buffers, URIs, indices,
            NaN/inf/huge vertices, node transforms, references, required extensions, truncation
- glb_skin_*, glb_morph_* : the good GLB skinned and morphed (`skinned_gltf`), its skin,
            weights, joints, inverse bind matrices and morph targets broken
- gltf_*  : the same scene as .gltf with external and data: buffers, mutated
- obj_*, stl_*, ply_* : text and binary meshes with bad numbers, indices, structure
- usd_*   : bad USD layers: missing or outside sublayers, references, payloads, bad topology
- rig_*   : the default rig file mutated, generated from the declared schema (every key: a wrong
            type, each bound crossed, NaN) plus structural cases (not a table, unknown key, ...)
- opt_*   : bad option values (every numeric option: NaN, inf, out of range, not a number)
- batch_* : `baker batch` of a jobs file (the first item "batch") whose paths cannot be
            resolved: a '~user' with no home, a NUL character, a loop of symbolic links; or
            whose outputs would replace what it reads (a level, a rig, the jobs file)

`GOOD_LATIN1` are files in other encodings that must load.
"""

from __future__ import annotations

import base64
import copy
import json
import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from baker.config import DEFAULT_RIG


@dataclass(frozen=True)
class Case:
    id: str
    make: Callable[[Path], list]


# --------------------------------------------------------------------------- a good scene
def scene_arrays():
    """A 4 x 4 m floor (2 triangles) and a 0.4 m box on it: positions (n, 3) float32, normals,
    uint32 indices."""
    floor = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], np.float32)
    fi = np.array([0, 2, 1, 0, 3, 2], np.uint32)
    c = np.array([[x, y, z] for x in (-.2, .2) for y in (0, .4) for z in (-.2, .2)], np.float32)
    c[:, 0] += 1.0
    bi = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
                  np.uint32).reshape(-1) + 4
    pos = np.concatenate([floor, c])
    idx = np.concatenate([fi, bi]).astype(np.uint32)
    nrm = np.tile(np.array([[0, 1, 0]], np.float32), (len(pos), 1))
    return pos, nrm, idx


def good_gltf():
    """(doc, bin) of the good scene: buffer 0 = positions | normals | indices."""
    pos, nrm, idx = scene_arrays()
    blob = pos.tobytes() + nrm.tobytes() + idx.tobytes()
    doc = {
        "asset": {"version": "2.0", "generator": "bad_inputs"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "ground", "mesh": 0, "translation": [0.0, 0.0, 0.0]},
                  {"name": "sun", "rotation": [-0.5, 0.0, 0.0, 0.8660254],
                   "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional",
                                                            "intensity": 3.0}]}},
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.4, 0.3, 0.2, 1.0]}}],
        "meshes": [{"name": "ground", "primitives": [
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
            {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": nrm.nbytes},
            {"buffer": 0, "byteOffset": pos.nbytes + nrm.nbytes, "byteLength": idx.nbytes}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
             "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
    }
    return doc, blob


def pack_glb(doc, blob: bytes | None, json_bytes: bytes | None = None) -> bytes:
    j = json_bytes if json_bytes is not None else json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    chunks = struct.pack("<II", len(j), 0x4E4F534A) + j
    if blob is not None:
        b = blob + b"\0" * (-len(blob) % 4)
        chunks += struct.pack("<II", len(b), 0x004E4942) + b
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def good_glb() -> bytes:
    doc, blob = good_gltf()
    return pack_glb(doc, blob)


# --------------------------------------------------------------------------- glTF mutations
def _set(doc, path: str, value):
    """Set doc[a][b]... from 'a.b.0.c'; value DELETE removes the key."""
    parts = [int(p) if p.lstrip("-").isdigit() else p for p in path.split(".")]
    obj = doc
    for p in parts[:-1]:
        obj = obj[p]
    if value is DELETE:
        del obj[parts[-1]]
    else:
        obj[parts[-1]] = value


DELETE = object()

#: JSON edits of the good GLB: (id, [(path, value), ...])
GLB_JSON_EDITS = [
    ("count_2e9_no_view", [("accessors.0.count", 2_000_000_000),
                           ("accessors.0.bufferView", DELETE)]),
    ("count_2e9", [("accessors.0.count", 2_000_000_000)]),
    ("count_huge_indices", [("accessors.2.count", 4_000_000_000)]),
    ("count_negative", [("accessors.0.count", -1)]),
    ("count_zero", [("accessors.0.count", 0)]),
    ("count_string", [("accessors.0.count", "many")]),
    ("count_float", [("accessors.0.count", 12.5)]),
    ("count_null", [("accessors.0.count", None)]),
    ("count_past_view", [("accessors.0.count", 13)]),
    ("component_9999", [("accessors.0.componentType", 9999)]),
    ("component_string", [("accessors.0.componentType", "FLOAT")]),
    ("component_5124", [("accessors.1.componentType", 5124)]),
    ("component_missing", [("accessors.0.componentType", DELETE)]),
    ("indices_float", [("accessors.2.componentType", 5126)]),
    ("indices_signed", [("accessors.2.componentType", 5122)]),
    ("indices_vec3", [("accessors.2.type", "VEC3"), ("accessors.2.count", 18)]),
    ("type_vec7", [("accessors.0.type", "VEC7")]),
    ("type_number", [("accessors.0.type", 3)]),
    ("position_vec2", [("accessors.0.type", "VEC2")]),
    ("accessor_offset_big", [("accessors.0.byteOffset", 1 << 40)]),
    ("accessor_offset_negative", [("accessors.0.byteOffset", -4)]),
    ("accessor_offset_unaligned", [("accessors.1.byteOffset", 2), ("accessors.1.count", 11)]),
    ("view_index_99", [("accessors.0.bufferView", 99)]),
    ("view_index_negative", [("accessors.0.bufferView", -1)]),
    ("view_index_string", [("accessors.0.bufferView", "0")]),
    ("view_offset_huge", [("bufferViews.0.byteOffset", 1 << 50)]),
    ("view_offset_negative", [("bufferViews.0.byteOffset", -8)]),
    ("view_length_huge", [("bufferViews.2.byteLength", 1 << 40)]),
    ("view_length_zero", [("bufferViews.0.byteLength", 0)]),
    ("view_buffer_7", [("bufferViews.0.buffer", 7)]),
    ("view_buffer_missing", [("bufferViews.0.buffer", DELETE)]),
    ("stride_1", [("bufferViews.0.byteStride", 1)]),
    ("stride_2", [("bufferViews.0.byteStride", 2)]),
    ("stride_6", [("bufferViews.0.byteStride", 6)]),
    ("stride_8_lt_elem", [("bufferViews.0.byteStride", 8)]),
    ("stride_256", [("bufferViews.0.byteStride", 256)]),
    ("stride_negative", [("bufferViews.0.byteStride", -12)]),
    ("stride_past_end", [("bufferViews.0.byteStride", 24)]),
    ("buffer_length_huge", [("buffers.0.byteLength", 1 << 40)]),
    ("buffer_length_string", [("buffers.0.byteLength", "big")]),
    ("buffer_uri_outside", [("buffers.0.uri", "../outside.bin")]),
    ("buffer_uri_absolute", [("buffers.0.uri", "/etc/passwd")]),
    ("buffer_uri_http", [("buffers.0.uri", "http://example.invalid/x.bin")]),
    ("buffer_uri_file_scheme", [("buffers.0.uri", "file:///etc/passwd")]),
    ("buffer_uri_missing", [("buffers.0.uri", "missing.bin")]),
    ("buffer_uri_bad_base64", [("buffers.0.uri", "data:application/octet-stream;base64,@@@!")]),
    ("buffer_uri_not_base64", [("buffers.0.uri", "data:text/plain,hello")]),
    ("buffer_uri_number", [("buffers.0.uri", 5)]),
    ("buffer_uri_dotdot_encoded", [("buffers.0.uri", "%2e%2e/%2e%2e/etc/passwd")]),
    ("buffers_not_array", [("buffers", {"0": 1})]),
    ("buffer_uri_nul", [("buffers.0.uri", "level\0.bin")]),     # (was 'embedded null byte')
    ("node_mesh_99", [("nodes.0.mesh", 99)]),
    ("node_mesh_string", [("nodes.0.mesh", "ground")]),
    ("node_child_self", [("nodes.0.children", [0])]),
    ("node_child_99", [("nodes.0.children", [99])]),
    ("node_child_cycle", [("nodes.0.children", [1]), ("nodes.1.children", [0])]),
    ("node_cycle_no_scene", [("nodes.0.children", [1]), ("nodes.1.children", [0]),
                             ("scenes", DELETE), ("scene", DELETE)]),
    # a node listed twice where glTF asks for a set (the scene's said 'node 0 has two
    # parents'), a scene root that is also a child: GLB_EXPECT
    ("scene_node_twice", [("scenes.0.nodes", [0, 0, 1])]),
    ("node_child_twice", [("nodes.1.children", [0, 0]), ("scenes.0.nodes", [1])]),
    ("node_root_is_child", [("nodes.1.children", [0])]),
    ("node_matrix_15", [("nodes.0.matrix", [1.0] * 15)]),
    ("node_matrix_strings", [("nodes.0.matrix", ["1"] * 16)]),
    ("node_rotation_3", [("nodes.1.rotation", [0, 0, 1])]),
    ("node_rotation_zero", [("nodes.1.rotation", [0.0, 0.0, 0.0, 0.0])]),
    ("node_matrix_and_trs", [("nodes.0.matrix", [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                                                 0, 0, 0, 1])]),
    ("node_matrix_projective", [("nodes.0.translation", DELETE),
                                ("nodes.0.matrix", [1.0, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0,
                                                    0, 0, 0, 1])]),
    ("indices_count_35", [("accessors.2.count", 35)]),
    ("normal_count_short", [("accessors.1.count", 3)]),
    ("node_scale_string", [("nodes.0.scale", "big")]),
    ("node_translation_1e12", [("nodes.0.translation", [1e12, 0.0, 0.0])]),
    ("node_scale_1e12", [("nodes.0.scale", [1e12, 1e12, 1e12])]),
    ("node_scale_1e300", [("nodes.0.scale", [1e300, 1e300, 1e300])]),
    ("node_light_9", [("nodes.1.extensions.KHR_lights_punctual.light", 9)]),
    ("scene_5", [("scene", 5)]),
    ("scene_nodes_99", [("scenes.0.nodes", [99])]),
    ("mesh_primitives_object", [("meshes.0.primitives", {"a": 1})]),
    ("attribute_position_99", [("meshes.0.primitives.0.attributes.POSITION", 99)]),
    ("attribute_normal_indices", [("meshes.0.primitives.0.attributes.NORMAL", 2)]),
    ("attributes_list", [("meshes.0.primitives.0.attributes", [0])]),
    ("prim_indices_99", [("meshes.0.primitives.0.indices", 99)]),
    ("prim_indices_positions", [("meshes.0.primitives.0.indices", 0)]),
    ("prim_mode_99", [("meshes.0.primitives.0.mode", 99)]),
    ("prim_mode_points", [("meshes.0.primitives.0.mode", 0)]),
    ("prim_material_99", [("meshes.0.primitives.0.material", 99)]),
    ("material_color_3", [("materials.0.pbrMetallicRoughness.baseColorFactor", [1, 1, 1])]),
    ("indices_normalized", [("accessors.2.normalized", True)]),
    ("ext_required_unknown", [("extensionsRequired", ["EXT_made_up"])]),
    ("ext_required_draco_like", [("extensionsRequired", ["KHR_draco_mesh_compressionX"])]),
    ("ext_required_string", [("extensionsRequired", "KHR_lights_punctual")]),
    ("asset_missing", [("asset", DELETE)]),
    ("asset_version_1", [("asset.version", "1.0")]),
    ("asset_string", [("asset", "2.0")]),
    ("sparse_index_past", [("accessors.0.sparse", {
        "count": 1, "indices": {"bufferView": 2, "componentType": 5125},
        "values": {"bufferView": 0}}), ("accessors.0.count", 2)]),
    ("sparse_count_huge", [("accessors.0.sparse", {
        "count": 1000, "indices": {"bufferView": 2, "componentType": 5125},
        "values": {"bufferView": 0}})]),
    ("sparse_values_missing", [("accessors.0.sparse", {
        "count": 1, "indices": {"bufferView": 2, "componentType": 5125}, "values": {}})]),
    ("sparse_float_indices", [("accessors.0.sparse", {
        "count": 1, "indices": {"bufferView": 2, "componentType": 5126},
        "values": {"bufferView": 0}})]),
    ("sparse_2e9_no_view", [("accessors.0.count", 2_000_000_000),
                            ("accessors.0.bufferView", DELETE),
                            ("accessors.0.sparse", {
                                "count": 1, "indices": {"bufferView": 2, "componentType": 5125},
                                "values": {"bufferView": 0}})]),
]

#: a part of the message of GLB_JSON_EDITS cases whose message was misleading
GLB_EXPECT = {
    "scene_node_twice": "scenes[0].nodes lists node 0 twice",
    "node_child_twice": "nodes[1].children lists node 0 twice",
    "node_root_is_child": "node 0 is a root of the scene and also a child of node 1",
    "node_child_self": "node 0 is its own child",
    "node_child_cycle": "node 0 is a root of the scene and also a child of node 1",
}


#: edits of the binary data (positions are floats 0..35 bytes per vertex; indices at the end)
def _blob_edit(kind: str):
    pos, nrm, idx = scene_arrays()
    ioff = pos.nbytes + nrm.nbytes

    def edit(blob: bytes) -> bytes:
        b = bytearray(blob)
        if kind == "nan_vertex":
            struct.pack_into("<f", b, 4, math.nan)
        elif kind == "inf_vertex":
            struct.pack_into("<f", b, 0, math.inf)
        elif kind == "neg_inf_vertex":
            struct.pack_into("<f", b, 8 + 12 * 5, -math.inf)
        elif kind == "huge_vertex":
            struct.pack_into("<f", b, 0, 1e12)
        elif kind == "huge_vertices_all":
            arr = np.frombuffer(bytes(b[: pos.nbytes]), np.float32) * np.float32(1e12)
            b[: pos.nbytes] = arr.tobytes()
        elif kind == "index_past":
            struct.pack_into("<I", b, ioff + 4, len(pos) + 7)
        elif kind == "index_minus_5":
            struct.pack_into("<I", b, ioff, 0xFFFFFFFB)
        elif kind == "index_max":
            struct.pack_into("<I", b, ioff + 8, 0xFFFFFFFF)
        elif kind == "all_degenerate":
            b[ioff:] = np.zeros(len(idx), np.uint32).tobytes()
        return bytes(b)
    return edit


GLB_BLOB_EDITS = ["nan_vertex", "inf_vertex", "neg_inf_vertex", "huge_vertex", "huge_vertices_all",
                  "index_past", "index_minus_5", "index_max", "all_degenerate"]


def _glb_json_case(name, edits):
    def make(folder: Path):
        doc, blob = good_gltf()
        doc = copy.deepcopy(doc)
        for path, value in edits:
            _set(doc, path, value)
        (folder.parent / "outside.bin").write_bytes(blob)  # exists, but outside the folder
        p = folder / f"{name}.glb"
        p.write_bytes(pack_glb(doc, blob))
        return [p]
    return Case(f"glb_{name}", make)


def _glb_blob_case(kind):
    def make(folder: Path):
        doc, blob = good_gltf()
        p = folder / f"{kind}.glb"
        p.write_bytes(pack_glb(doc, _blob_edit(kind)(blob)))
        return [p]
    return Case(f"glb_{kind}", make)


def _glb_raw_case(name, fn):
    def make(folder: Path):
        p = folder / f"{name}.glb"
        p.write_bytes(fn())
        return [p]
    return Case(f"glb_{name}", make)


def _truncated(n):
    return lambda: good_glb()[:n]


def _glb_raw_cases():
    g = good_glb()
    doc, blob = good_gltf()
    jlen = struct.unpack_from("<I", g, 12)[0]
    raw = {
        "empty": lambda: b"",
        "magic": lambda: b"gLTF" + g[4:],
        "version_1": lambda: g[:4] + struct.pack("<I", 1) + g[8:],
        "length_past_end": lambda: g[:8] + struct.pack("<I", len(g) + 100) + g[12:],
        "chunk_length_huge": lambda: g[:12] + struct.pack("<I", 0x7FFFFFF0) + g[16:],
        "json_not_json": lambda: pack_glb(None, blob, b"{not json"),
        "json_array": lambda: pack_glb(None, blob, b"[1, 2, 3]"),
        "json_latin1": lambda: pack_glb(None, blob, b'{"asset": {"version": "2.0\xe9"}}'),
        "json_deep": lambda: pack_glb(None, blob, b"[" * 100000 + b"]" * 100000),
        "no_json_chunk": lambda: b"glTF" + struct.pack("<II", 2, 20 + len(blob))
        + struct.pack("<II", len(blob), 0x004E4942) + blob,
        "no_bin_chunk": lambda: pack_glb(doc, None),
        "bin_short": lambda: pack_glb(doc, blob[: len(blob) // 2]),
        "garbage": lambda: bytes(range(256)) * 64,
        "placements_20M": _placements_glb,
    }
    cases = [_glb_raw_case(k, v) for k, v in raw.items()]
    for n in (11, 12, 19, 20, 20 + jlen // 2, 20 + jlen, 28 + jlen, len(g) - 1):
        cases.append(_glb_raw_case(f"truncated_{n}", _truncated(n)))
    return cases


def _compressed(kind: str, doc_edit=None, blob_edit=None):
    """A case of the good GLB compressed (kind "meshopt" or "draco", tests/tools/compress_glb.py)
    with its JSON or its compressed bytes then edited."""
    def make(folder: Path):
        from compress_glb import draco_glb, meshopt_glb, read_glb

        doc, blob = read_glb((meshopt_glb if kind == "meshopt" else draco_glb)(good_glb()))
        if doc_edit:
            doc_edit(doc)
        p = folder / f"{kind}.glb"
        p.write_bytes(pack_glb(doc, blob_edit(blob) if blob_edit else blob))
        return [p]
    return make


def _mo(doc, j=0):
    return doc["bufferViews"][j]["extensions"]["EXT_meshopt_compression"]


def _dr(doc):
    return doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]


def _point_cloud(doc: dict) -> None:
    """The Draco stream replaced by a point cloud's (no triangles): in a data: URI."""
    import DracoPy

    data = DracoPy.encode(scene_arrays()[0])
    doc["buffers"].append({"byteLength": len(data), "uri": "data:application/octet-stream;"
                           f"base64,{base64.b64encode(data).decode()}"})
    doc["bufferViews"][0] = {"buffer": 1, "byteLength": len(data)}


def _compressed_cases():
    """Compressed geometry (EXT_meshopt_compression, KHR_draco_mesh_compression) broken."""
    mo = {
        "stream_garbled": (None, lambda b: bytes(x ^ 0x5A for x in b)),
        "stream_zeroed": (None, lambda b: bytes(len(b))),
        "count_off_by_one": (lambda d: _mo(d).update(count=_mo(d)["count"] + 1), None),
        "count_huge": (lambda d: (_mo(d).update(count=2_000_000_000),
                                  d["bufferViews"][0].update(byteLength=24_000_000_000),
                                  d["buffers"][1].update(byteLength=24_000_000_100)), None),
        "mode_quads": (lambda d: _mo(d).update(mode="QUADS"), None),
        "filter_unknown": (lambda d: _mo(d).update(filter="WAVELET"), None),
        "stride_6": (lambda d: _mo(d).update(byteStride=6, count=_mo(d)["count"] * 2), None),
        "indices_stride_8": (lambda d: _mo(d, 2).update(byteStride=8), None),
        "source_past_buffer": (lambda d: _mo(d).update(byteOffset=10**6), None),
        "source_buffer_missing": (lambda d: _mo(d).update(buffer=5), None),
        "ext_not_object": (lambda d: d["bufferViews"][0]["extensions"].update(
            EXT_meshopt_compression=[1, 2]), None),
        "plain_view_on_placeholder": (lambda d: d["bufferViews"][0].pop("extensions"), None),
    }
    dr = {
        "stream_garbled": (None, lambda b: bytes(x ^ 0x5A for x in b)),
        "stream_truncated": (None, lambda b: b[: len(b) // 3] + bytes(len(b) - len(b) // 3)),
        "no_position": (lambda d: _dr(d).update(attributes={}), None),
        "position_id_7": (lambda d: _dr(d).update(attributes={"POSITION": 7}), None),
        "position_id_text": (lambda d: _dr(d).update(attributes={"POSITION": "zero"}), None),
        "view_missing": (lambda d: _dr(d).update(bufferView=9), None),
        "point_cloud": (_point_cloud, None),
        # placements are bounded by the accessors' counts: the decoded data must match them
        "counts_understated": (lambda d: d["accessors"][0].update(count=3), None),
    }
    return ([Case(f"glb_meshopt_{k}", _compressed("meshopt", *v)) for k, v in mo.items()]
            + [Case(f"glb_draco_{k}", _compressed("draco", *v)) for k, v in dr.items()])


def _placements_glb(nodes: int = 10_000, side: int = 32) -> bytes:
    """A 2,048-triangle grid placed `nodes` times (20.5 M triangles from a 0.4 MB file)."""
    g = np.arange(side + 1)
    pos = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2) / side * 4.0 - 2.0
    pos = np.c_[pos[:, 0], np.zeros(len(pos)), pos[:, 1]].astype(np.float32)
    q = (np.arange(side)[:, None] * (side + 1) + np.arange(side)[None, :]).reshape(-1)
    idx = np.c_[q, q + 1, q + side + 2, q, q + side + 2, q + side + 1].astype(np.uint32)
    blob = pos.tobytes() + idx.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(nodes))}],
           "nodes": [{"mesh": 0, "translation": [5.0 * (i % 100), 0.0, 5.0 * (i // 100)]}
                     for i in range(nodes)],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"byteLength": len(blob)}],
           "bufferViews": [{"buffer": 0, "byteLength": pos.nbytes},
                           {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos),
                          "type": "VEC3", "min": [-2, 0, -2], "max": [2, 0, 2]},
                         {"bufferView": 1, "componentType": 5125, "count": idx.size,
                          "type": "SCALAR"}]}
    return pack_glb(doc, blob)


def _write(path: Path, data: bytes) -> list:
    path.write_bytes(data)
    return [path]


def _gltf_cases():
    """A .gltf with an external .bin and a data: buffer, mutated."""
    def base(folder: Path, uri="scene.bin", write_bin=True, edit=None):
        doc, blob = good_gltf()
        doc = copy.deepcopy(doc)
        doc["buffers"][0]["uri"] = uri
        if write_bin:
            (folder / "scene.bin").write_bytes(blob)
        if edit:
            edit(doc, blob)
        p = folder / "scene.gltf"
        p.write_text(json.dumps(doc))
        return [p]

    def dataurl(text):
        return lambda f: base(f, uri=text, write_bin=False)

    _, blob = good_gltf()
    b64 = base64.b64encode(blob).decode()
    cases = {
        "bin_missing": lambda f: base(f, write_bin=False),
        "bin_outside": lambda f: (f.parent.joinpath("o.bin").write_bytes(blob),
                                  base(f, uri="../o.bin", write_bin=False))[1],
        "bin_subdir_escape": lambda f: base(f, uri="sub/../../o.bin", write_bin=False),
        "bin_short": lambda f: (base(f), (f / "scene.bin").write_bytes(blob[:40]))[0],
        "bin_is_folder": lambda f: ((f / "dir.bin").mkdir(), base(f, uri="dir.bin"))[1],
        "bin_link_loop": lambda f: ((f / "loop.bin").symlink_to(f / "loop.bin"),
                                    base(f, uri="loop.bin", write_bin=False))[1],
        "data_bad_base64": dataurl("data:application/octet-stream;base64," + b64[:-3] + "*=="),
        "data_short": dataurl("data:application/octet-stream;base64," + b64[:40]),
        "data_no_comma": dataurl("data:application/octet-stream;base64"),
        "not_utf8": lambda f: _write(f / "x.gltf", b'{"asset": \xff\xfe}'),
        "not_json": lambda f: _write(f / "y.gltf", b"asset: 2.0"),
        "json_number": lambda f: _write(f / "z.gltf", b"42"),
    }
    return [Case(f"gltf_{k}", v) for k, v in cases.items()]


# --------------------------------------------------------------------------- OBJ / STL / PLY
GOOD_OBJ = ("v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 3 2\nf 1 4 3\n")
#: GOOD_OBJ's vertices
_GOOD_FLOOR = [[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]]


def _text_case(cid, name, data: bytes):
    def make(folder: Path):
        p = folder / name
        p.write_bytes(data)
        return [p]
    return Case(cid, make)


def _stl_binary(tris: np.ndarray, count=None) -> bytes:
    tris = np.asarray(tris, np.float32).reshape(-1, 3, 3)
    n = len(tris) if count is None else count
    body = b"".join(struct.pack("<3f", 0, 1, 0) + t.tobytes() + b"\0\0" for t in tris)
    return b"\0" * 80 + struct.pack("<I", n) + body


def _ply(vertices, faces, fmt="ascii", nverts=None, extra_header=b"", element="face",
         index="int") -> bytes:
    """A PLY of `vertices` and the lists `faces` (any lengths) of an `element` (face or
    tristrips) whose items are of PLY type `index` (int or float)."""
    v = np.asarray(vertices, np.float32)
    head = (b"ply\nformat " + (b"ascii" if fmt == "ascii" else b"binary_little_endian")
            + b" 1.0\n" + extra_header + b"element vertex %d\nproperty float x\n"
            b"property float y\nproperty float z\nelement %s %d\n"
            b"property list uchar %s vertex_indices\nend_header\n"
            % (len(v) if nverts is None else nverts, element.encode(), len(faces),
               index.encode()))
    if fmt == "ascii":
        body = "".join(f"{a} {b} {c}\n" for a, b, c in v.tolist())
        body += "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces)
        return head + body.encode()
    item = {"int": "i", "float": "f"}[index]
    body = v.tobytes() + b"".join(struct.pack(f"<B{len(f)}{item}", len(f), *f) for f in faces)
    return head + body


def _mesh_cases():
    floor = [[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]]
    tri = np.array([[[-2, 0, -2], [2, 0, 2], [2, 0, -2]], [[-2, 0, -2], [-2, 0, 2], [2, 0, 2]]])
    c = [
        _text_case("obj_binary_garbage", "g.obj", b"\x00\xff\xfe v 1 2\nf 9 9 9\n\x00"),
        _text_case("obj_empty", "e.obj", b""),
        _text_case("obj_only_vertices", "v.obj", b"v 0 0 0\nv 1 0 0\nv 0 0 1\n"),
        _text_case("obj_nan_vertex", "n.obj", GOOD_OBJ.replace("v 2 0 2", "v nan 0 2").encode()),
        _text_case("obj_inf_vertex", "i.obj", GOOD_OBJ.replace("v 2 0 2", "v inf 0 2").encode()),
        _text_case("obj_huge_coords", "h.obj",
                   GOOD_OBJ.replace("v 2 0 2", "v 1e12 0 1e12").encode()),
        _text_case("obj_all_huge", "ah.obj", GOOD_OBJ.replace("2", "2e12").encode()),
        _text_case("obj_overflow_coords", "o.obj",
                   GOOD_OBJ.replace("v 2 0 2", "v 1e999 0 2").encode()),
        _text_case("obj_words", "w.obj", b"hello world\nthis is not a mesh\n"),
        _text_case("obj_face_zero", "z.obj", (GOOD_OBJ + "f 0 1 2\n").encode()),
        _text_case("obj_face_relative_past", "r.obj", (GOOD_OBJ + "f -9 -8 -7\n").encode()),
        _text_case("obj_face_past", "p.obj", (GOOD_OBJ + "f 1 2 99\n").encode()),
        _text_case("obj_face_word", "fw.obj", (GOOD_OBJ + "f 1 two 3\n").encode()),
        _text_case("obj_vertex_2d", "v2.obj", GOOD_OBJ.replace("v 2 0 2", "v 2 0").encode()),
        _text_case("obj_degenerate", "d.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
        _text_case("obj_steep", "s.obj", b"v 0 0 0\nv 1 0 0\nv 1 10 0.1\nv 0 10 0.1\n"
                                         b"f 1 2 3\nf 1 3 4\n"),
        _text_case("stl_empty", "e.stl", b""),
        _text_case("stl_binary_truncated", "t.stl", _stl_binary(tri, count=1000)),
        _text_case("stl_binary_solid_header_truncated", "s.stl",
                   b"solid binary" + _stl_binary(tri, count=1000)[12:]),
        _text_case("stl_binary_nan", "n.stl", _stl_binary(np.where(tri == 2, np.nan, tri))),
        _text_case("stl_binary_inf", "i.stl", _stl_binary(np.where(tri == 2, np.inf, tri))),
        _text_case("stl_binary_huge", "h.stl", _stl_binary(tri * 1e12)),
        _text_case("stl_binary_zero_tris", "z.stl", _stl_binary(tri[:0])),
        _text_case("stl_ascii_garbage", "a.stl", b"solid x\nfacet normal banana\nendsolid\n"),
        _text_case("stl_ascii_nan", "an.stl", b"solid x\nfacet normal 0 1 0\nouter loop\n"
                   b"vertex nan 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid x\n"),
        # vertex lines of 2 and 4 numbers (trimesh read the 9 numbers of a facet in a row: a
        # wrong triangle), a word for a number
        _text_case("stl_ascii_vertex_2_numbers", "v2.stl", _stl_ascii(("x", "x")).replace(
            b"vertex -2 0 2\n", b"vertex -2 0\n", 1).replace(b"vertex 2 0 2\n", b"vertex 2 0 2 2\n", 1)),
        _text_case("stl_ascii_vertex_4_numbers", "v4.stl", _stl_ascii(("x", "x")).replace(
            b"vertex -2 0 -2\n", b"vertex -2 0 -2 1\n", 1)),
        _text_case("stl_ascii_vertex_word", "vw.stl", _stl_ascii(("x", "x")).replace(
            b"vertex 2 0 2\n", b"vertex 2 zero 2\n", 1)),
        _text_case("stl_count_2e9", "c.stl", b"\0" * 80 + struct.pack("<I", 2_000_000_000)
                   + b"\0" * 50),
        _text_case("ply_empty", "e.ply", b""),
        _text_case("ply_bad_header", "b.ply", b"ply\nformat banana 1.0\nend_header\n"),
        _text_case("ply_no_end_header", "n.ply", b"ply\nformat ascii 1.0\nelement vertex 3\n"),
        _text_case("ply_nan", "nan.ply", _ply([[0, 0, 0], [1, 0, 0], [np.nan, 0, 1]], [[0, 2, 1]])),
        _text_case("ply_index_past", "ip.ply", _ply(floor, [[0, 2, 1], [0, 3, 9]])),
        _text_case("ply_index_negative", "in.ply", _ply(floor, [[0, 2, 1], [0, -5, 2]])),
        _text_case("ply_binary_index_past", "bp.ply", _ply(floor, [[0, 2, 1], [0, 3, 99]],
                                                         fmt="binary")),
        _text_case("ply_binary_vertex_2e9", "bv.ply", _ply(floor, [[0, 2, 1]], fmt="binary",
                                                         nverts=2_000_000_000)),
        _text_case("ply_ascii_vertex_2e9", "av.ply", _ply(floor, [[0, 2, 1]],
                                                        nverts=2_000_000_000)),
        _text_case("ply_ascii_faces_missing", "fm.ply",
                   _ply(floor, [[0, 2, 1], [0, 3, 2]]).rsplit(b"3 ", 1)[0]),
        _text_case("ply_ascii_list_overlong", "lo.ply",
                   _ply(floor, [[0, 2, 1], [0, 3, 2]]).replace(b"\n3 0 2 1", b"\n255 0 2 1")),
        _text_case("ply_ascii_extra_values", "ev.ply", _ply(floor, [[0, 2, 1]]) + b"1 2 3 4\n"),
        _text_case("ply_ascii_vertex_short", "vs.ply",
                   _ply(floor, [[0, 2, 1]]).replace(b"\n2.0 0.0 2.0", b"\n2.0 0.0")),
        _text_case("ply_huge", "hg.ply", _ply(np.array(floor) * 1e12, [[0, 2, 1], [0, 3, 2]])),
        # a face list declared float: 2.5 was cut to 2 (a whole 2.0 loads: GOOD_UNUSUAL)
        _text_case("ply_face_float_index", "ff.ply", _ply(floor, [[0, 2, 1], [0, 3, 2.5]],
                                                        index="float")),
        _text_case("ply_binary_face_float_index", "bf.ply", _ply(
            floor, [[0, 2, 1], [0, 3, 2.5]], fmt="binary", index="float")),
        _text_case("ply_face_float_index_huge", "fh.ply", _ply(floor, [[0, 2, 1], [0, 3, 1e30]],
                                                             index="float")),
        _text_case("ply_face_float_index_nan", "fn.ply", _ply(floor, [[0, 2, 1], [0, 3, "nan"]],
                                                            index="float")),
        # a binary face list whose lengths are floats (trimesh: "'(' was never closed")
        _text_case("ply_binary_list_length_float", "lf.ply", _ply(
            floor, [[0, 2, 1], [0, 3, 2]], fmt="binary").replace(b"list uchar", b"list float")),
        # a face list declared int holding 2.5 as text (trimesh read it as 2)
        _text_case("ply_ascii_int_list_holds_2p5", "fi.ply",
                   _ply(floor, [[0, 2, 1], [0, 3, 2.5]])),
        _text_case("ply_ascii_int_list_holds_word", "fw.ply",
                   _ply(floor, [[0, 2, 1], [0, 3, "two"]])),
        # triangle strips: an index past the vertices, a negative one other than -1 (restart)
        _text_case("ply_tristrips_index_past", "tp.ply", _ply(floor, [[0, 1, 3, 9]],
                                                            element="tristrips")),
        _text_case("ply_binary_tristrips_index_minus_2", "tm.ply", _ply(
            floor, [[0, 1, 3, -2, 2]], fmt="binary", element="tristrips")),
        _text_case("ply_tristrips_float_index", "tf.ply", _ply(
            floor, [[0, 1, 3, 2.5]], element="tristrips", index="float")),
    ]
    return c


#: valid files written the way some tools write them; each holds GOOD_OBJ's floor
GOOD_UNUSUAL = {
    "tabs.obj": b"v\t-2e0\t0.0E+00\t-2.\nv\t+2.0e+0\t-0\t-20E-1\nv 2 0 .2e1\n"
                b"v  -2  0  2  \n\tf\t1\t3\t2\nf 1 4 3 \n",
    "indented.obj": b"".join(b"  " + line + b"\n" for line in GOOD_OBJ.encode().splitlines()),
    "crlf_tabs.obj": GOOD_OBJ.replace(" ", "\t").replace("\n", "\r\n").encode(),
    "trailing_comments.obj": b"".join(line + b"\t# corner " + str(i).encode() + b"\n"
                                      for i, line in enumerate(GOOD_OBJ.encode().splitlines())),
    # classic Mac OS line ends (a lone CR): trimesh read one line and refused it
    "cr_only.obj": GOOD_OBJ.replace("\n", "\r").encode(),
    # the format's line continuation (a backslash before the line break); a comment's
    # backslash continues nothing
    "continued.obj": b"# saved in C:\\levels\\\n" + GOOD_OBJ.replace(
        "v 2 0 2", "v 2 \\\n0 \\\r\n2").replace("f 1 4 3", "f 1 \\\n4 3").encode(),
    # a PLY's triangles as strips (old Stanford files; -1 restarts a strip), a face list
    # declared float of whole numbers
    "tristrips.ply": _ply(_GOOD_FLOOR, [[0, 2, 1, -1, 0, 3, 2]], element="tristrips"),
    "tristrips_binary.ply": _ply(_GOOD_FLOOR, [[0, 2, 1, -1, 0, 3, 2]], fmt="binary",
                                 element="tristrips"),
    "face_float.ply": _ply(_GOOD_FLOOR, [[0.0, 2.0, 1.0], [0.0, 3.0, 2.0]], index="float"),
    "face_float_binary.ply": _ply(_GOOD_FLOOR, [[0, 2, 1], [0, 3, 2]], fmt="binary",
                                  index="float"),
}

def _gltf_data_uri(payload=lambda b64: b64, pad: int = 0, bom: bool = False) -> bytes:
    """The good scene as a .gltf whose buffer is a data: URI (`pad` unused bytes after the
    scene's; the base64 text passed through `payload`), with a UTF-8 byte order mark."""
    doc, blob = good_gltf()
    doc = copy.deepcopy(doc)
    blob += b"\0" * pad
    doc["buffers"][0] = {"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                         + payload(base64.b64encode(blob).decode())}
    return (b"\xef\xbb\xbf" if bom else b"") + json.dumps(doc).encode()


def _glb_bom() -> bytes:
    doc, blob = good_gltf()
    return pack_glb(None, blob, b"\xef\xbb\xbf" + json.dumps(doc).encode())


#: valid glTF written the way some tools write them; each holds good_glb()'s scene. A byte
#: order mark before the JSON was refused ('Unexpected UTF-8 BOM'); base64 broken into lines
#: or without its '=' padding (which browsers and three.js decode) was refused as not base64
GOOD_UNUSUAL_GLTF = {
    "bom.gltf": _gltf_data_uri(bom=True),
    "bom.glb": _glb_bom(),
    "base64_lines.gltf": _gltf_data_uri(
        lambda t: "\r\n".join(t[i:i + 76] for i in range(0, len(t), 76))),
    "base64_unpadded.gltf": _gltf_data_uri(lambda t: t.rstrip("="), pad=1),
}

def _stl_ascii(*solids: tuple[str, str]) -> bytes:
    """An ASCII STL of the 4 x 4 m floor (2 facets) per (solid name, endsolid name)."""
    facets = ("facet normal 0 1 0\nouter loop\nvertex -2 0 -2\nvertex 2 0 2\nvertex 2 0 -2\n"
              "endloop\nendfacet\nfacet normal 0 1 0\nouter loop\nvertex -2 0 -2\n"
              "vertex -2 0 2\nvertex 2 0 2\nendloop\nendfacet\n")
    return "".join(f"solid {a}\n{facets}endsolid {b}\n" for a, b in solids).encode()


#: valid ASCII STLs that were refused or misnamed: each the floor once per solid, and the
#: meshes' names. Solid names with the words trimesh's reader searches the text for
#: (`solid vertex_paint_test` was refused, 'unmatched data'; a name with "endsolid" said
#: '`endsolid` precedes `solid`'; a solid after `endsolid floor_solid` was named
#: geometry_1); lines ending in a lone CR (classic Mac OS: 'cut short')
GOOD_ASCII_STL = {
    "cr_only.stl": (_stl_ascii(("floor", "floor")).replace(b"\n", b"\r"), ["floor"]),
    "vertex.stl": (_stl_ascii(("vertex_paint_test", "vertex_paint_test")), ["vertex_paint_test"]),
    "vertex_numbers.stl": (_stl_ascii(("vertex 1 2 3", "vertex 1 2 3")), ["vertex_1_2_3"]),
    "endsolid.stl": (_stl_ascii(("a endsolid b", "a endsolid b")), ["a_endsolid_b"]),
    "words.stl": (_stl_ascii(("Facet Normal Outer Loop EndLoop EndFacet VERTEX", "x")),
                  ["Facet_Normal_Outer_Loop_EndLoop_EndFacet_VERTEX"]),
    "two_solids.stl": (_stl_ascii(("a", "floor_solid"), ("b", "b")), ["a", "b"]),
}

GOOD_LATIN1 = {
    "latin1.obj": b"# Fl\xe4che f\xfcr den Tausendf\xfc\xdfler, \xa9 2026\n" + GOOD_OBJ.encode(),
    "cp1252.obj": b"# caf\xe9 \x93quoted\x94\n" + GOOD_OBJ.encode(),
    "utf16bom.obj": b"\xef\xbb\xbf# \xc3\xa9t\xc3\xa9\n" + GOOD_OBJ.encode(),
    "latin1.stl": (b"solid sol \xe9t\xe9\nfacet normal 0 1 0\nouter loop\nvertex -2 0 -2\n"
                   b"vertex 2 0 2\nvertex 2 0 -2\nendloop\nendfacet\nfacet normal 0 1 0\n"
                   b"outer loop\nvertex -2 0 -2\nvertex -2 0 2\nvertex 2 0 2\nendloop\n"
                   b"endfacet\nendsolid sol \xe9t\xe9\n"),
    "latin1.ply": _ply([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], [[0, 2, 1], [0, 3, 2]],
                       extra_header=b"comment cr\xe9\xe9 par baker\n"),
    "latin1_binary.ply": _ply([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]],
                              [[0, 2, 1], [0, 3, 2]], fmt="binary",
                              extra_header=b"comment cr\xe9\xe9 par baker\n"),
}


# --------------------------------------------------------------------------- USD
USD_MESH = """def Mesh "floor"
{{
    int[] faceVertexCounts = {counts}
    int[] faceVertexIndices = {indices}
    point3f[] points = {points}
}}
"""
USD_HEAD = '#usda 1.0\n(\n    upAxis = "Y"\n    metersPerUnit = {mpu}\n{extra})\n\n'
USD_POINTS = "[(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)]"


def usd_text(counts="[3, 3]", indices="[0, 2, 1, 0, 3, 2]", points=USD_POINTS, mpu="1",
             extra="", body=None) -> str:
    return USD_HEAD.format(mpu=mpu, extra=extra) + (
        body if body is not None else USD_MESH.format(counts=counts, indices=indices,
                                                      points=points))


def deep_usd_text(depth: int) -> str:
    """The floor's mesh at the bottom of `depth` Xforms, each in the one before."""
    return usd_text(body="".join(f'def Xform "x{i}"\n{{\n' for i in range(depth)) + USD_MESH.format(
        counts="[3, 3]", indices="[0, 2, 1, 0, 3, 2]", points=USD_POINTS) + "}\n" * depth)


#: a file in a case's dict that is a symbolic link to itself
LOOP = object()


def _usd_case(cid, make_files):
    def make(folder: Path):
        files = make_files()
        for name, text in files.items():
            target = folder / name
            target.parent.mkdir(parents=True, exist_ok=True)
            if text is None:        # a FIFO: opening it would wait for a writer
                os.mkfifo(target)
            elif text is LOOP:      # a symbolic link to itself
                target.symlink_to(target)
            elif isinstance(text, bytes):
                target.write_bytes(text)
            else:
                target.write_text(text)
        (folder.parent / "outside.usda").write_text(usd_text())
        return [folder / "level.usda" if "level.usda" in files else folder / next(iter(files))]
    return Case(f"usd_{cid}", make)


def _usd_cases():
    good = usd_text()
    ref = 'def Xform "x" (\n    prepend references = @{}@\n)\n{{\n}}\n'
    pay = 'def Xform "x" (\n    prepend payload = @{}@\n)\n{{\n}}\n'
    cases = {
        "sublayer_missing": lambda: {"level.usda": usd_text(extra="    subLayers = [@missing.usda@]\n")},
        "sublayer_outside": lambda: {"level.usda": usd_text(extra="    subLayers = [@../outside.usda@]\n")},
        "sublayer_absolute": lambda: {"level.usda": usd_text(extra="    subLayers = [@/etc/hosts@]\n")},
        "sublayer_nested_missing": lambda: {
            "level.usda": usd_text(extra="    subLayers = [@a.usda@]\n"),
            "a.usda": usd_text(extra="    subLayers = [@gone.usda@]\n")},
        "sublayer_nested_outside": lambda: {
            "level.usda": usd_text(extra="    subLayers = [@sub/a.usda@]\n"),
            "sub/a.usda": usd_text(extra="    subLayers = [@../../outside.usda@]\n")},
        "sublayer_corrupt": lambda: {"level.usda": usd_text(extra="    subLayers = [@a.usda@]\n"),
                                     "a.usda": "#usda 1.0\ndef Mesh \"x\" {{{"},
        "reference_outside": lambda: {"level.usda": good + ref.format("../outside.usda")},
        "reference_missing": lambda: {"level.usda": good + ref.format("nothere.usda")},
        "reference_http": lambda: {"level.usda": good + ref.format("http://example.invalid/a.usda")},
        "payload_outside": lambda: {"level.usda": good + pay.format("../outside.usda")},
        "payload_missing": lambda: {"level.usda": good + pay.format("gone.usdc")},
        "reference_bad_prim": lambda: {"level.usda": good + ref.format("a.usda").replace(
            "@a.usda@", "@a.usda@</nope>"), "a.usda": usd_text()},
        "reference_not_usd": lambda: {"level.usda": good + ref.format("notes.txt"),
                                      "notes.txt": "hello"},
        "variant_reference_outside": lambda: {"level.usda": good + (
            'def Xform "x" (\n    variants = {\n        string v = "b"\n    }\n'
            '    prepend variantSets = "v"\n)\n{\n    variantSet "v" = {\n'
            '        "b" (prepend references = @../outside.usda@) {\n        }\n    }\n}\n')},
        "self_reference_cycle": lambda: {"level.usda": good + ref.format("level.usda").replace(
            "@level.usda@", "@level.usda@</x>")},
        "face_index_past": lambda: {"level.usda": usd_text(indices="[0, 2, 1, 0, 3, 9]")},
        "face_index_negative": lambda: {"level.usda": usd_text(indices="[0, 2, 1, 0, -5, 2]")},
        "face_counts_mismatch": lambda: {"level.usda": usd_text(counts="[3, 4]")},
        "face_counts_negative": lambda: {"level.usda": usd_text(counts="[-3, 9]")},
        "points_nan": lambda: {"level.usda": usd_text(points=USD_POINTS.replace("(2, 0, 2)", "(nan, 0, 2)"))},
        "points_inf": lambda: {"level.usda": usd_text(points=USD_POINTS.replace("(2, 0, 2)", "(inf, 0, 2)"))},
        "points_huge": lambda: {"level.usda": usd_text(points=USD_POINTS.replace("2", "2e12"))},
        "mpu_zero": lambda: {"level.usda": usd_text(mpu="0")},
        "mpu_negative": lambda: {"level.usda": usd_text(mpu="-1")},
        "mpu_huge": lambda: {"level.usda": usd_text(mpu="1e15")},
        "syntax_error": lambda: {"level.usda": "#usda 1.0\ndef Mesh \"x\" {\n  int[] = \n"},
        "empty": lambda: {"level.usda": ""},
        "no_meshes": lambda: {"level.usda": usd_text(body='def Xform "x"\n{\n}\n')},
        "crate_garbage": lambda: {"level.usdc": b"PXR-USDC" + bytes(range(256)) * 8},
        "usd_text_garbage": lambda: {"level.usd": b"\x00\x01\x02 not usd at all"},
        # a section's start past any file: USD's C++ code printed 'failed call to
        # posix_madvise(...)' on stderr itself, above the error line
        "crate_section_start": lambda: {"level.usdc": crate_section_flipped()},
        # prims 60,000 deep (over load.MAX_USDA_DEPTH): USD's C++ code recurses per level,
        # and 20,000 deep crashed the process (SIGSEGV) on the main thread's stack
        "prims_60000_deep": lambda: {"level.usda": deep_usd_text(60_000)},
        # a light's exposure past a float (it said "(34, 'Numerical result out of range')")
        "light_exposure_1e30": lambda: {"level.usda": good + (
            'def DistantLight "sun"\n{\n    float inputs:exposure = 1e30\n}\n')},
        # a unit that shrinks the level to a point (it said 'no triangle faces')
        "mpu_tiny": lambda: {"level.usda": usd_text(mpu="1e-300")},
        # a sublayer that is a FIFO or a loop of links (they said 'does not exist', 'Symlink
        # loop from ...')
        "sublayer_fifo": lambda: {"level.usda": usd_text(extra="    subLayers = [@p.usda@]\n"),
                                  "p.usda": None},
        "sublayer_link_loop": lambda: {"level.usda": usd_text(
            extra="    subLayers = [@l.usda@]\n"), "l.usda": LOOP},
        # a prim named in Latin-1 (USD takes UTF-8): USD's error message could not be decoded
        # (UnicodeDecodeError in str() of pxr's exception: a traceback)
        "prim_name_latin1": lambda: {"level.usda": usd_text().encode().replace(
            b'"floor"', b'"fl\xe9or"')},
    }
    def inside(sub):
        return usd_text(extra=f"    subLayers = [@{sub}@]\n")

    cases.update({
        "usdz_sublayer_outside": lambda: {"level.usdz": usdz({"level.usda": inside(
            "../outside.usda")})},
        "usdz_sublayer_missing": lambda: {"level.usdz": usdz({"level.usda": inside(
            "missing.usda")})},
        "usdz_sublayer_corrupt": lambda: {"level.usdz": usdz({
            "level.usda": inside("a.usda"), "a.usda": "#usda 1.0\ndef Mesh \"x\" {{{"})},
        "usdz_empty_zip": lambda: {"level.usdz": usdz({})},
        "usdz_not_zip": lambda: {"level.usdz": b"PK\x03\x04" + bytes(range(256)) * 4},
        "usdz_text_inside_only": lambda: {"level.usdz": usdz({"notes.txt": "hello"})},
    })
    return [_usd_case(k, v) for k, v in cases.items()]


def usd_crate(text: str) -> bytes:
    """The USD layer `text` as a crate (.usdc) file's bytes."""
    import tempfile

    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(text)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.usdc"
        layer.Export(str(p))
        return p.read_bytes()


def crate_section_flipped() -> bytes:
    """The good level as a crate whose first section's start has its high byte flipped (the
    table of contents: a count, then 16-byte names each with an int64 start and size)."""
    b = bytearray(usd_crate(usd_text()))
    toc = struct.unpack_from("<q", b, 16)[0]
    b[toc + 8 + 16 + 7] ^= 0xFF
    return bytes(b)


def usdz(files: dict[str, str]) -> bytes:
    """A .usdz package (an uncompressed zip, each file's data 64-byte aligned) of text files,
    the first the root layer."""
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for name, text in files.items():
            info = zipfile.ZipInfo(name)
            header = 30 + len(name.encode())
            pad = -(buf.tell() + header + 4) % 64
            info.extra = struct.pack("<HH", 0x1986, pad) + bytes(pad)
            z.writestr(info, text)
    return buf.getvalue()


# --------------------------------------------------------------------------- rig files
def _rig_case(cid, text_fn):
    def make(folder: Path):
        p = folder / "rig.toml"
        data = text_fn()
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        return ["--rig", p]
    return Case(f"rig_{cid}", make)


def _replace_key(text: str, section: str, key: str, value: str) -> str:
    """The rig text with `key = value` in [section] (replaced, or added at the section's top)."""
    lines = text.splitlines()
    out, cur, done = [], None, False
    for ln in lines:
        s = ln.strip()
        if s.startswith("[") and not s.startswith("[["):
            if cur == section and not done:
                out.append(f"{key} = {value}")
                done = True
            cur = s.split("]")[0][1:].strip()
            out.append(ln)
            continue
        if cur == section and not done and s.split("=")[0].strip() == key and "=" in s \
                and not s.startswith("#"):
            out.append(f"{key} = {value}")
            done = True
            # a multi-line array value: drop its continuation lines
            if s.count("[") > s.count("]"):
                cur = "__skip__"
            continue
        if cur == "__skip__":
            if "]" in s:
                cur = section
            continue
        out.append(ln)
    if not done:
        out.append(f"[{section}]" if cur != section else "")
        out.append(f"{key} = {value}")
    return "\n".join(out) + "\n"


def _schema_rig_cases():
    """For every declared rig key: a value of the wrong type, each bound crossed, NaN."""
    from baker.schema import SECTIONS, _base

    base = DEFAULT_RIG.read_text()
    cases = []
    for sec, model in SECTIONS.items():
        for key, info in model.model_fields.items():
            t = _base(info.annotation)
            lo = hi = None
            lo_strict = hi_strict = False
            for m in info.metadata:
                if getattr(m, "gt", None) is not None:
                    lo, lo_strict = m.gt, True
                if getattr(m, "ge", None) is not None:
                    lo = m.ge
                if getattr(m, "lt", None) is not None:
                    hi, hi_strict = m.lt, True
                if getattr(m, "le", None) is not None:
                    hi = m.le
            wrong = '"x"' if t is not str else "5"
            vals = {"type": wrong}
            if t in (int, float):
                if lo is not None:
                    vals["below"] = repr(lo if lo_strict else (lo - 1 if t is int else lo - 0.5))
                if hi is not None:
                    vals["above"] = repr(hi if hi_strict else (hi + 1 if t is int else hi * 2 + 1))
                if t is float:
                    vals["nan"] = "nan"
                if t is int:
                    vals["fraction"] = "4.5"
            elif t is bool:
                vals["int"] = "1"
            else:
                vals["table"] = "{ a = 1 }"
            for kind, v in vals.items():
                cases.append(_rig_case(f"{sec}_{key}_{kind}",
                                       (lambda s=sec, k=key, v=v: _replace_key(base, s, k, v))))
    return cases


def _structural_rig_cases():
    base = DEFAULT_RIG.read_text()
    rk = _replace_key
    c = {
        "empty": lambda: "",
        "comments_only": lambda: "# nothing here\n",
        "not_toml": lambda: "this is = not = toml\n",
        "not_utf8": lambda: b"[body]\nlength = 0.25 # \xff\xfe\n",
        "binary": lambda: bytes(range(256)),
        "legs_none": lambda: 'legs = "none"\n' + base[:base.index("[legs]")]
        + base[base.index("[behaviour]"):],
        "body_number": lambda: "body = 5\n",
        "colors_string": lambda: 'colors = "red"\n' + base.replace("[colors]", "[colorz]"),
        "unknown_key": lambda: rk(base, "locomotion", "max_sped", "0.8"),
        "unknown_section": lambda: base + "\n[wandr]\nradius = 3\n",
        "body_missing": lambda: base.split("[body]")[0] + "[colors]\nbody = [0.1, 0.1, 0.1]\n",
        "segments_missing": lambda: base.replace("segments = 21", ""),
        "segments_x": lambda: rk(base, "body", "segments", '"x"'),
        "length_long": lambda: rk(base, "body", "length", '"long"'),
        "length_inf": lambda: rk(base, "body", "length", "inf"),
        "length_1e-300": lambda: rk(base, "body", "length", "1e-300"),   # a grid of 1e286 cells
        "length_denormal": lambda: rk(base, "body", "length", "5e-324"),
        "cell_size_1e-30": lambda: rk(base, "navigation", "cell_size", "1e-30"),
        "max_speed_list": lambda: rk(base, "locomotion", "max_speed", "[1, 2]"),
        "curve_ragged": lambda: rk(base, "cobra", "curve", "[[0.0, 0.0], [0.5, 0.1, 0.2], [1.0, 1.0]]"),
        "curve_flat": lambda: rk(base, "cobra", "curve", "[0.0, 0.5, 1.0]"),
        "curve_decreasing": lambda: rk(base, "cobra", "curve", "[[0.0, 0.0], [0.9, 0.1], [0.5, 1.0]]"),
        "curve_out_of_01": lambda: rk(base, "cobra", "curve", "[[0.0, 0.0], [1.0, 5.0]]"),
        "color_2": lambda: rk(base, "colors", "body", "[0.1, 0.2]"),
        "color_4": lambda: rk(base, "colors", "legs", "[0.1, 0.2, 0.3, 1.0]"),
        "color_range": lambda: rk(base, "colors", "body", "[0.1, 2.0, 0.3]"),
        "color_strings": lambda: rk(base, "prey", "color", '["r", "g", "b"]'),
        "color_nested": lambda: rk(base, "prey", "color", "[[0.1], [0.2], [0.3]]"),
        "width_profile_short": lambda: rk(base, "body", "width_profile", "[0.04, 0.04, 0.04]"),
        "width_profile_negative": lambda: rk(base, "body", "width_profile", "[-0.04]" ),
        "width_profile_strings": lambda: rk(base, "body", "width_profile", '["a", "b", "c"]'),
        "stride_order": lambda: rk(rk(base, "legs", "stride_min", "0.3"), "legs", "stride_max", "0.1"),
        "detection_far": lambda: rk(base, "behaviour", "detection_range", '"far"'),
        "decision_zero": lambda: rk(base, "behaviour", "decision_interval", "0"),
        "ramp_negative": lambda: rk(base, "cobra", "ramp_time", "-0.4"),
        "slither_1e9": lambda: rk(base, "locomotion", "slither_amplitude", "1e9"),
        "roll_4_7": lambda: rk(base, "behaviour", "shade_roll_max", "4.7"),
        "prey_radius_negative": lambda: rk(base, "prey", "radius", "-0.05"),
        "feed_negative": lambda: rk(base, "behaviour", "feed_time", "-1.0"),
        "name_number": lambda: "name = 5\n" + base.split("\n", 2)[2],
        "huge_file": lambda: base + "# " + "x" * (2 << 20) + "\n",
        "array_of_tables": lambda: base + "\n[[legs2]]\na = 1\n",
        "nested_deep": lambda: "[body]\nlength = 0.25\nx = " + "[" * 5000 + "]" * 5000 + "\n",
    }
    return [_rig_case(k, v) for k, v in c.items()]


# --------------------------------------------------------------------------- batch jobs
BATCH_HEAD = '[defaults]\nenvironment = "scene.glb"\nseconds = 1\n'


def _batch_case(cid, text, *extra, setup=None, jobs_name="jobs.toml"):
    """`baker batch` of a jobs file beside the good scene (the first item "batch": see
    test_bad_inputs.bake_args); `setup(folder)` adds what the file names."""
    def make(folder: Path):
        (folder / "scene.glb").write_bytes(good_glb())
        if setup:
            setup(folder)
        p = folder / jobs_name
        p.write_text(text)
        return ["batch", p, *(x(folder) if callable(x) else x for x in extra)]
    return Case(f"batch_{cid}", make)


def _loop(name):
    """A symbolic link `name` in the folder that points at itself."""
    def setup(folder: Path):
        (folder / name).symlink_to(folder / name)
    return setup


def _batch_cases():
    """Paths pathlib cannot resolve (it raised RuntimeError or ValueError: tracebacks)."""
    job = BATCH_HEAD + "[[job]]\n"
    return [
        _batch_case("env_unknown_user", job + 'environment = "~nosuchuser_baker/x.glb"\n'),
        _batch_case("rig_unknown_user", job + 'rig = "~nosuchuser_baker/rig.toml"\n'),
        _batch_case("env_nul", job + 'environment = "level\\u0000.glb"\n'),
        _batch_case("rig_nul", job + 'rig = "rig\\u0000.toml"\n'),
        _batch_case("matrix_env_nul",
                    job + '[job.matrix]\nenvironment = ["scene.glb", "a\\u0000.glb"]\n'),
        _batch_case("env_link_loop", job + 'environment = "loop.glb"\n', setup=_loop("loop.glb")),
        _batch_case("rig_link_loop", job + 'rig = "loop.toml"\n', setup=_loop("loop.toml")),
        _batch_case("out_link_loop", job, "--out", lambda f: f / "loop" / "o", setup=_loop("loop")),
        _batch_case("cache_dir_unknown_user", job, "--cache-dir", "~nosuchuser_baker/cache"),
        _batch_case("out_empty", job, "--out", ""),      # (baked into the working folder)
        # the batch's lock file a folder, or a link (it was IsADirectoryError, ELOOP)
        _batch_case("lock_is_folder", job, "--out", lambda f: f / "bo",
                    setup=lambda f: (f / "bo" / ".baker-batch.lock").mkdir(parents=True)),
        _batch_case("lock_link_loop", job, "--out", lambda f: f / "bo",
                    setup=lambda f: ((f / "bo").mkdir(), _loop("bo/.baker-batch.lock")(f))),
        # a job named after its level, written into the level's folder: over the level
        _batch_case("out_over_environment", BATCH_HEAD + '[[job]]\nname = "{environment}"\n',
                    "--out", lambda f: f),
        _batch_case("cache_dir_link_loop", job, "--cache-dir", lambda f: f / "loop",
                    setup=_loop("loop")),
        # a job's JSON report over its rig (r.json), or over the jobs file itself (jobs.json
        # holding TOML), --out their folder: written over them
        _batch_case("out_over_rig", BATCH_HEAD + '[[job]]\nname = "r"\nrig = "r.json"\n',
                    "--out", lambda f: f, setup=lambda f: _copy_rig(f / "r.json")),
        _batch_case("out_over_jobs_file", job + 'name = "jobs"\n', "--out", lambda f: f,
                    jobs_name="jobs.json"),
        # a FIFO where the manifest goes (it was renamed over)
        _batch_case("manifest_fifo", job, "--out", lambda f: f / "bo",
                    setup=lambda f: ((f / "bo").mkdir(), os.mkfifo(f / "bo" / "manifest.json"))),
    ]


def _rig_path_cases():
    return [
        Case("rig_missing", lambda f: ["--rig", f / "nope.toml"]),
        Case("rig_folder", lambda f: ((f / "dir.toml").mkdir(), ["--rig", f / "dir.toml"])[1]),
    ]


# --------------------------------------------------------------------------- options
OPTION_CASES = {
    "seconds": ["nan", "inf", "-inf", "0", "-3", "1e9", "abc", "1e400"],
    "fps": ["0", "-30", "7", "1000", "abc", "nan", "30.5", "99999999999999999999"],
    "seed": ["-1", "abc", "1e30", "99999999999999999999999"],
    "prey": ["-1", "17", "abc", "1000000"],
    "creatures": ["0", "-1", "1001", "abc", "2.5", "nan", "99999999999999999999"],
    "sun": ["1e308,0,0", "nan,1,0", "inf,1,0", "0,-1,0", "0,0,0", "1,2", "a,b,c", "1,1e300,1",
            "1,2,3,4", ""],
    "sun-path": ["nan,30", "inf,30", "90,nan", "90,0", "90,91", "abc", "90", "1e308,30",
                 "90,30;nan,40", "90,30;270", ";;", "90,-inf", "90,30;", "90,30;;270,40",
                 ";".join(["90,30"] * 20_000)],    # (refused as if its form were wrong)
    "scale": ["0", "nan", "inf", "-1", "1e6", "abc"],
    # 0.0036 m (39 M columns) left this list in issue 15: the slimmer build's budget (10 GB)
    # fits the default limit, so the bake runs (lazily) instead of being refused
    "cell-size": ["0", "-1", "nan", "inf", "abc", "1e-5", "1e-300"],
    "agent-radius": ["nan", "0", "-1", "inf", "1e9"],
    "agent-height": ["nan", "0", "-0.5", "inf"],
    "step-height": ["-1", "nan", "inf"],
    "max-slope": ["90", "0", "nan", "-5", "1e9"],
    "max-memory": ["0", "-1", "nan", "inf", "abc", "10"],
    "format": ["fbx"],
    "behaviour": ["sleep"],
    "cobra": ["sometimes"],
    "nav-build": ["partial"],
}

NAVMESH_OPTION_CASES = [
    ("from_nan", ["--from", "nan,0,0", "--to", "0,0,0"]),
    ("to_inf", ["--from", "0,0,0", "--to", "inf,0,0"]),
    ("from_1e308", ["--from", "1e308,0,0", "--to", "0,0,0"]),
    ("from_only", ["--from", "0,0,0"]),
    ("from_short", ["--from", "0,0", "--to", "1,0,0"]),
    ("cell_tiny", ["--cell-size", "0.0005"]),
    ("cell_nan", ["--cell-size", "nan"]),
    ("memory_tiny", ["--max-memory", "50"]),
]


def _option_cases():
    cases = []
    for opt, values in OPTION_CASES.items():
        for i, v in enumerate(values):
            cases.append(Case(f"opt_{opt}_{i}_{v[:12]}", (lambda f, o=opt, v=v: [f"--{o}", v])))
    # two options that both set the sun (the sun path won; the report kept --sun's)
    cases.append(Case("opt_sun_and_sun_path", lambda f: ["--sun", "0,1,0",
                                                         "--sun-path", "90,30;270,30"]))
    # a device as the output prefix: /dev/null.glb, .usd and .json were written beside it
    cases.append(Case("opt_out_device", lambda f: ["--out", "/dev/null"]))
    # the output named as the level it reads (the bake was written over the level)
    cases.append(Case("opt_out_over_environment", lambda f: [
        (f / "level.glb").write_bytes(good_glb()) and f / "level.glb", "--out", f / "level"]))
    # the output named as the rig it reads (a rig file r.json or r.usd, --out r: written over)
    for ext in ("json", "usd"):
        cases.append(Case(f"opt_out_over_rig_{ext}", lambda f, e=ext: [
            "--rig", _copy_rig(f / f"r.{e}"), "--out", f / "r"]))
    # an output that is a FIFO (the bake was renamed over it)
    cases.append(Case("opt_out_glb_fifo", lambda f: [
        os.mkfifo(f / "q.glb"), "--out", f / "q"][1:]))
    # an output name holding a byte that is not UTF-8 (Linux allows it; USD takes UTF-8
    # paths: a UnicodeEncodeError traceback once the bake was done)
    cases.append(Case("opt_out_not_utf8", lambda f: [
        (f / "level.glb").write_bytes(good_glb()) and f / "level.glb",
        "--out", f / os.fsdecode(b"c\xff")]))
    # a tolerance under what the stored values can hold: refused after the bake, naming it
    # (the line said neither the option nor where)
    cases.append(Case("opt_tolerance_1e-300", lambda f: [
        (f / "level.glb").write_bytes(good_glb()) and f / "level.glb", "--tolerance", "1e-300"]))
    for name, args in NAVMESH_OPTION_CASES:
        cases.append(Case(f"opt_navmesh_{name}", (lambda f, a=args: ["navmesh", *a])))
    # a --png that is a FIFO (the map was renamed over it)
    cases.append(Case("opt_navmesh_png_fifo", lambda f: [
        os.mkfifo(f / "m.png"), "navmesh", "--png", f / "m.png"][1:]))
    return cases


def _copy_rig(path: Path) -> Path:
    path.write_bytes(DEFAULT_RIG.read_bytes())
    return path


# --------------------------------------------------------------------------- skins and morphs
def skinned_gltf():
    """(doc, bin) of the good scene skinned and morphed (environment/gltf_pose.py): every vertex
    on joint 0 ("bone", 1 m up; "bone2" its child), inverse bind matrices of identity, and a
    morph target lifting it 0.5 m at mesh weight 1. Accessors 3.. are JOINTS_0, WEIGHTS_0, the
    inverse bind matrices and the target, appended to buffer 0 in that order."""
    doc, blob = good_gltf()
    doc = copy.deepcopy(doc)
    n = len(scene_arrays()[0])
    parts = [(np.tile(np.uint8([0, 1, 0, 0]), (n, 1)), "VEC4", 5121),
             (np.tile(np.float32([1, 0, 0, 0]), (n, 1)), "VEC4", 5126),
             (np.tile(np.eye(4, dtype=np.float32), (2, 1, 1)), "MAT4", 5126),
             (np.tile(np.float32([0, 0.5, 0]), (n, 1)), "VEC3", 5126)]
    for a, kind, ctype in parts:
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes})
        doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": ctype,
                                 "count": len(a), "type": kind})
        blob += a.tobytes()
    doc["accessors"][6].update(min=[0, 0.5, 0], max=[0, 0.5, 0])
    doc["buffers"][0]["byteLength"] = len(blob)
    prim = doc["meshes"][0]["primitives"][0]
    prim["attributes"].update(JOINTS_0=3, WEIGHTS_0=4)
    prim["targets"] = [{"POSITION": 6}]
    doc["meshes"][0]["weights"] = [1.0]
    doc["nodes"] += [{"name": "bone", "translation": [0.0, 1.0, 0.0], "children": [3]},
                     {"name": "bone2", "translation": [0.0, 0.5, 0.0]}]
    doc["scenes"][0]["nodes"].append(2)
    doc["nodes"][0]["skin"] = 0
    doc["skins"] = [{"joints": [2, 3], "inverseBindMatrices": 5}]
    return doc, blob


def _acc_float(doc, blob, acc: int, i: int, value: float, fmt: str = "<f") -> None:
    """Write value as the i-th component of an accessor's data (tightly packed)."""
    a = doc["accessors"][acc]
    struct.pack_into(fmt, blob, doc["bufferViews"][a["bufferView"]]["byteOffset"]
                     + i * struct.calcsize(fmt), value)


#: edits of skinned_gltf (doc, bytearray blob) -> None, and a part of each refusal's message
SKIN_EDITS = {
    "skin_weight_nan": lambda d, b: _acc_float(d, b, 4, 0, math.nan),
    "skin_weight_inf": lambda d, b: _acc_float(d, b, 4, 5, math.inf),
    "skin_weight_negative": lambda d, b: _acc_float(d, b, 4, 13, -0.5),
    "skin_joint_past": lambda d, b: _acc_float(d, b, 3, 8, 2, "<B"),
    "skin_joint_255": lambda d, b: _acc_float(d, b, 3, 47, 255, "<B"),
    "skin_ibm_nan": lambda d, b: _acc_float(d, b, 5, 17, math.nan),
    "skin_ibm_short": lambda d, b: d["accessors"][5].update(count=1),
    "skin_ibm_vec4": lambda d, b: d["accessors"][5].update(type="VEC4"),
    "skin_joints_empty": lambda d, b: d["skins"][0].update(joints=[]),
    "skin_joints_past": lambda d, b: d["skins"][0].update(joints=[2, 99]),
    "skin_joints_text": lambda d, b: d["skins"][0].update(joints="bone"),
    "skin_index_past": lambda d, b: d["nodes"][0].update(skin=5),
    "skin_joints_vec3": lambda d, b: d["accessors"][3].update(type="VEC3"),
    "skin_weights_bytes": lambda d, b: d["accessors"][4].update(componentType=5121),
    "skin_joint_cycle": lambda d, b: d["nodes"][3].update(children=[2]),
    "morph_weight_nan": lambda d, b: d["meshes"][0].update(weights=[math.nan]),
    "morph_weights_text": lambda d, b: d["nodes"][0].update(weights="heavy"),
    "morph_target_nan": lambda d, b: _acc_float(d, b, 6, 4, math.nan),
    "morph_target_count": lambda d, b: d["accessors"][6].update(count=6),
    "morph_target_scalar": lambda d, b: d["meshes"][0]["primitives"][0].update(
        targets=[{"POSITION": 2}]),
    "morph_targets_object": lambda d, b: d["meshes"][0]["primitives"][0].update(
        targets={"POSITION": 6}),
    "morph_target_past": lambda d, b: d["meshes"][0]["primitives"][0].update(
        targets=[{"POSITION": 99}]),
}
SKIN_EXPECT = {
    "skin_weight_nan": "WEIGHTS_0 holds a non-finite weight",
    "skin_weight_inf": "WEIGHTS_0 holds a non-finite weight",
    "skin_weight_negative": "WEIGHTS_0 holds a negative weight",
    "skin_joint_past": "names joint 2; its skin (skins[0]) has 2 joints",
    "skin_joint_255": "names joint 255",
    "skin_ibm_nan": "inverseBindMatrices holds a non-finite number",
    "skin_ibm_short": "holds 1 matrices for 2 joints",
    "skin_ibm_vec4": "must be a MAT4 accessor of floats",
    "skin_joints_empty": "non-empty array of node indices",
    "skin_joints_past": "skins[0].joints[1] = 99 is not an index into nodes",
    "skin_joints_text": "non-empty array of node indices",
    "skin_index_past": "nodes[0].skin = 5 is not an index into skins",
    "skin_joints_vec3": "JOINTS_0 must be a VEC4 accessor",
    "skin_weights_bytes": "WEIGHTS_0 must be a VEC4 accessor of floats or normalized",
    "skin_joint_cycle": "node 2 is a root of the scene and also a child of node 3",
    "morph_weight_nan": "weights must be an array of finite numbers",
    "morph_weights_text": "weights must be an array of finite numbers",
    "morph_target_nan": "targets[0].POSITION (accessors[6]) holds a non-finite number",
    "morph_target_count": "targets[0].POSITION has 6 elements, POSITION 12",
    "morph_target_scalar": "targets[0].POSITION must be a VEC3 accessor",
    "morph_targets_object": "targets must be an array of objects",
    "morph_target_past": "is not an index into accessors",
}


def _skin_case(key):
    def make(folder: Path):
        doc, blob = skinned_gltf()
        b = bytearray(blob)
        SKIN_EDITS[key](doc, b)
        p = folder / f"{key}.glb"
        p.write_bytes(pack_glb(doc, bytes(b)))
        return [p]
    return Case(f"glb_{key}", make)


def _morph_terms_glb(targets: int = 2000, vertices: int = 80_000) -> bytes:
    """One zero-filled 80,000-vertex accessor (no bufferView) as a mesh's positions and as each of
    its 2,000 morph targets, all at weight 1: 160 M vertex x target terms from a 60 kB file."""
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0},
                                       "targets": [{"POSITION": 0}] * targets}],
                       "weights": [1.0] * targets}],
           "accessors": [{"componentType": 5126, "count": vertices // 3 * 3, "type": "VEC3"}]}
    return pack_glb(doc, None)


def _skin_cases():
    return ([_skin_case(k) for k in SKIN_EDITS]
            + [_glb_raw_case("morph_terms_160M", _morph_terms_glb)])


# --------------------------------------------------------------------------- all
def all_cases() -> list[Case]:
    cases = ([_glb_json_case(n, e) for n, e in GLB_JSON_EDITS]
             + [_glb_blob_case(k) for k in GLB_BLOB_EDITS]
             + _glb_raw_cases() + _compressed_cases() + _skin_cases() + _gltf_cases()
             + _mesh_cases() + _usd_cases()
             + _schema_rig_cases() + _structural_rig_cases() + _rig_path_cases()
             + _option_cases() + _batch_cases())
    ids = [c.id for c in cases]
    assert len(ids) == len(set(ids)), "duplicate case ids"
    return cases
