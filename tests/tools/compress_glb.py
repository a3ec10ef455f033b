"""Compress a GLB's geometry the way gltfpack and gltf-transform do, for the loader's tests:
`meshopt_glb` re-encodes every bufferView with EXT_meshopt_compression (lossless for float
data: the same vertices come back), `draco_glb` every triangle primitive with
KHR_draco_mesh_compression (quantized: the vertices come back within the quantization step).
"""

from __future__ import annotations

import copy
import json
import struct

import numpy as np

from bad_inputs import pack_glb

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
              5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def read_glb(data: bytes) -> tuple[dict, bytes]:
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    off = 20 + n
    blob = data[off + 8: off + 8 + struct.unpack_from("<I", data, off)[0]] if off < len(data) \
        else b""
    return doc, blob


def _view_modes(doc) -> dict[int, tuple[str, int]]:
    """Each bufferView's (meshopt mode, byteStride): TRIANGLES for a view read whole as the
    indices of triangle lists, else ATTRIBUTES rows of the accessors' element size."""
    modes = {}
    tri_indices = {p["indices"] for m in doc["meshes"] for p in m["primitives"]
                   if "indices" in p and p.get("mode", 4) == 4}
    for k, a in enumerate(doc["accessors"]):
        j = a.get("bufferView")
        if j is None:
            continue
        size = np.dtype(_COMPONENT[a["componentType"]]).itemsize
        elem = size * _NCOMP[a["type"]]
        whole = a.get("byteOffset", 0) == 0 and a["count"] * elem == \
            doc["bufferViews"][j]["byteLength"]
        if k in tri_indices and whole and size in (2, 4):
            modes[j] = ("TRIANGLES", size)
        else:
            modes[j] = ("ATTRIBUTES", doc["bufferViews"][j].get("byteStride") or elem)
    return modes


def meshopt_glb(data: bytes, name: str = "EXT_meshopt_compression") -> bytes:
    """The GLB with every bufferView compressed: buffer 0 holds the compressed streams,
    buffer 1 is the fallback placeholder (no data) the views point into."""
    import meshopt

    doc, blob = read_glb(data)
    out = copy.deepcopy(doc)
    packed = bytearray()
    fallback = 0
    for j, bv in enumerate(doc["bufferViews"]):
        raw = np.frombuffer(blob, np.uint8, bv["byteLength"], bv.get("byteOffset", 0))
        mode, stride = _view_modes(doc).get(j, ("ATTRIBUTES", 4))
        count = bv["byteLength"] // stride
        if mode == "TRIANGLES":
            enc = meshopt.encode_index_buffer(raw.view(np.uint16 if stride == 2 else np.uint32))
        else:
            enc = meshopt.encode_vertex_buffer(raw.reshape(count, stride))
        ext = {"buffer": 0, "byteOffset": len(packed), "byteLength": len(enc),
               "byteStride": stride, "count": count, "mode": mode}
        packed += enc + b"\0" * (-len(enc) % 4)
        out["bufferViews"][j] = {**bv, "buffer": 1, "byteOffset": fallback,
                                 "extensions": {name: ext}}
        fallback += bv["byteLength"] + (-bv["byteLength"] % 4)
    out["buffers"] = [{"byteLength": len(packed)},
                      {"byteLength": fallback, "extensions": {name: {"fallback": True}}}]
    for key in ("extensionsUsed", "extensionsRequired"):
        out[key] = sorted(set(out.get(key, [])) | {name})
    return pack_glb(out, bytes(packed))


def draco_glb(data: bytes, bits: int = 16) -> bytes:
    """The GLB with every triangle primitive Draco-compressed (positions and triangles only;
    other attributes dropped), its accessors left without bufferViews."""
    import DracoPy

    doc, blob = read_glb(data)

    def accessor(k):
        a = doc["accessors"][k]
        bv = doc["bufferViews"][a["bufferView"]]
        n = a["count"] * _NCOMP[a["type"]]
        return np.frombuffer(blob, _COMPONENT[a["componentType"]], n,
                             bv.get("byteOffset", 0) + a.get("byteOffset", 0))

    out = copy.deepcopy(doc)
    out["accessors"], out["bufferViews"], packed = [], [], bytearray()
    for m, mesh in enumerate(doc["meshes"]):
        for p, prim in enumerate(mesh["primitives"]):
            pos = accessor(prim["attributes"]["POSITION"]).reshape(-1, 3)
            faces = accessor(prim["indices"]).reshape(-1, 3)
            enc = DracoPy.encode(pos, faces, quantization_bits=bits, preserve_order=True)
            dec = DracoPy.decode(enc)
            out["bufferViews"].append({"buffer": 0, "byteOffset": len(packed),
                                       "byteLength": len(enc)})
            packed += enc + b"\0" * (-len(enc) % 4)
            k = len(out["accessors"])
            out["accessors"] += [
                {"componentType": 5126, "count": len(dec.points), "type": "VEC3",
                 "min": dec.points.min(0).tolist(), "max": dec.points.max(0).tolist()},
                {"componentType": 5125, "count": int(dec.faces.size), "type": "SCALAR"}]
            out["meshes"][m]["primitives"][p] = {
                "attributes": {"POSITION": k}, "indices": k + 1,
                **{key: prim[key] for key in ("material", "mode") if key in prim},
                "extensions": {"KHR_draco_mesh_compression": {
                    "bufferView": len(out["bufferViews"]) - 1, "attributes": {"POSITION": 0}}}}
    out["buffers"] = [{"byteLength": len(packed)}]
    for key in ("extensionsUsed", "extensionsRequired"):
        out[key] = sorted(set(out.get(key, [])) | {"KHR_draco_mesh_compression"})
    return pack_glb(out, bytes(packed))
