"""The glTF extensions that change a level's geometry, as game pipelines write them:

- `EXT_meshopt_compression` (and its ratified twin `KHR_meshopt_compression`) bufferViews,
  decoded with meshoptimizer's codec (the `meshopt` package), every filter;
- `KHR_draco_mesh_compression` primitives, decoded with Google's Draco (`DracoPy`);
- `EXT_mesh_gpu_instancing` nodes: a mesh placed many times (trees, rocks, props), each
  instance's translation, rotation and scale read here and applied by the loader.

gltfpack, gltf-transform and most engines' exporters write them, so real levels often arrive
compressed and instanced. Both codecs are C++ behind the Python bindings and release the GIL.

Every field is checked before a byte is decoded, and the decoded size is bounded by the file's
(a small file cannot ask for gigabytes); a corrupt stream is an `EnvironmentLoadError` naming
the bufferView or primitive.
"""

from __future__ import annotations

import numpy as np

from baker.errors import EnvironmentLoadError

MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
DRACO = "KHR_draco_mesh_compression"
INSTANCING = "EXT_mesh_gpu_instancing"
_INSTANCE_TYPES = {"TRANSLATION": ("VEC3", (5126,)), "SCALE": ("VEC3", (5126,)),
                   "ROTATION": ("VEC4", (5126, 5120, 5122))}
_MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
_FILTERS = ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR")
#: a decoded bufferView holds at most this many times the file's bytes, plus the slack
#: (meshoptimizer's codec rarely gains more than 10x; Draco's about 20x)
MAX_GAIN = 256
_SLACK = 1 << 20


def _extension(obj: dict, names) -> dict | None:
    ext = obj.get("extensions")
    if not isinstance(ext, dict):
        return None
    for name in (names,) if isinstance(names, str) else names:
        if name in ext:
            return ext[name]
    return None


def meshopt_of(view: dict) -> dict | None:
    """A bufferView's meshopt extension object, or None."""
    return _extension(view, MESHOPT)


def is_fallback(buffer: dict) -> bool:
    """Whether a buffer is a meshopt fallback: a placeholder whose bytes only the compressed
    bufferViews give (it may have no data at all)."""
    ext = _extension(buffer, MESHOPT)
    return isinstance(ext, dict) and ext.get("fallback") is True


def check_meshopt(d, where: str, view: dict, ext, sizes: list[int], file_size: int) -> None:
    """Check a compressed bufferView's extension against the buffers (sizes) and the file.
    d is the document checker (`load._Doc`)."""
    if not isinstance(ext, dict):
        d.fail(f"{where}.extensions.EXT_meshopt_compression must be an object")
    w = f"{where}.extensions.EXT_meshopt_compression"
    b = d.index(ext, "buffer", w, "buffers", required=True)
    off = d.integer(ext, "byteOffset", w, default=0)
    length = d.integer(ext, "byteLength", w, lo=1, default=0)
    if off + length > sizes[b]:
        d.fail(f"{w} (bytes {off}..{off + length}) runs past buffers[{b}] ({sizes[b]} bytes)")
    stride = d.integer(ext, "byteStride", w, lo=1, hi=256, default=0)
    count = d.integer(ext, "count", w, lo=1, hi=2**32, default=0)
    mode, filt = ext.get("mode"), ext.get("filter", "NONE")
    if mode not in _MODES:
        d.fail(f"{w}.mode = {str(mode)[:30]}; expected one of {', '.join(_MODES)}")
    if filt not in _FILTERS:
        d.fail(f"{w}.filter = {str(filt)[:30]}; expected one of {', '.join(_FILTERS)}")
    if mode == "ATTRIBUTES" and stride % 4:
        d.fail(f"{w}.byteStride = {stride}; attributes need a multiple of 4")
    if mode != "ATTRIBUTES" and (stride not in (2, 4) or filt != "NONE"):
        d.fail(f"{w}: {mode.lower()} need a byteStride of 2 or 4 and no filter")
    if mode == "TRIANGLES" and count % 3:
        d.fail(f"{w}.count = {count} is not a multiple of 3 for triangles")
    if count * stride != view.get("byteLength"):
        d.fail(f"{w} decodes to {count * stride} bytes, not the bufferView's byteLength "
               f"({view.get('byteLength')})")
    if count * stride > MAX_GAIN * max(file_size, length) + _SLACK:
        d.fail(f"{w} decodes to {count * stride:,} bytes from {length:,}, far more than the "
               f"file's {file_size:,} bytes could hold")


def decode_meshopt(source: bytes, ext: dict, where: str) -> bytes:
    """A checked compressed bufferView's bytes (count * byteStride), filters undone."""
    import meshopt

    off = ext.get("byteOffset", 0)
    data = np.frombuffer(source, np.uint8, count=ext["byteLength"], offset=off)
    count, stride, mode = ext["count"], ext["byteStride"], ext["mode"]
    filt = ext.get("filter", "NONE")
    try:
        out = meshopt.decode_gltf_buffer(data, count, stride, mode,
                                         None if filt == "NONE" else filt)
    except (ValueError, RuntimeError) as e:
        raise EnvironmentLoadError(f"corrupt glTF: {where} does not decode as meshopt "
                                   f"{mode.lower()} ({str(e)[:80]})") from None
    out = np.ascontiguousarray(out)
    if out.nbytes != count * stride:
        raise EnvironmentLoadError(f"corrupt glTF: {where} decodes to {out.nbytes} bytes, "
                                   f"not {count * stride}")
    return out.tobytes()


def draco_of(prim: dict) -> dict | None:
    """A primitive's Draco extension object, or None."""
    return _extension(prim, DRACO)


def check_draco(d, where: str, ext) -> None:
    """Check a primitive's Draco extension: its bufferView and its attribute ids."""
    w = f"{where}.extensions.{DRACO}"
    if not isinstance(ext, dict):
        d.fail(f"{w} must be an object")
    d.index(ext, "bufferView", w, "bufferViews", required=True)
    attrs = ext.get("attributes")
    if not isinstance(attrs, dict) or "POSITION" not in attrs:
        d.fail(f"{w}.attributes must map POSITION to a Draco attribute id")
    for name, uid in attrs.items():
        if isinstance(uid, bool) or not isinstance(uid, int) or not 0 <= uid < 2**31:
            d.fail(f"{w}.attributes.{str(name)[:30]} = {str(uid)[:30]}; expected a Draco "
                   "attribute id")


def decode_draco(data: bytes, ext: dict, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A Draco primitive's (positions (n, 3) float64, triangles (m, 3) int64); the triangles
    index the positions (checked)."""
    import DracoPy

    try:
        mesh = DracoPy.decode(bytes(data))
    except Exception as e:  # DracoPy raises its own types and plain ValueErrors
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco data does not decode "
                                   f"({str(e)[:80]})") from None
    faces = getattr(mesh, "faces", None)
    if faces is None:
        raise EnvironmentLoadError(f"{where}'s Draco data is a point cloud, not triangles")
    attr = mesh.get_attribute_by_unique_id(int(ext["attributes"]["POSITION"]))
    if attr is None:
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco data has no attribute "
                                   f"{ext['attributes']['POSITION']} (its POSITION)")
    points = np.asarray(attr["data"], dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco POSITION is not 3D points")
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if faces.size and (faces.min() < 0 or faces.max() >= len(points)):
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco triangles index past its "
                                   f"{len(points)} points")
    return points, faces


def decode_draco_attribute(data: bytes, ext: dict, name: str, where: str,
                           normalized: bool = False) -> np.ndarray:
    """A Draco primitive's attribute `name` (a skinned primitive's JOINTS_n or WEIGHTS_n, which
    gltf-transform and gltfpack compress with the positions): (n, k) int64, or float64 for
    floats and for integers read as normalized (divided by their type's largest value)."""
    import DracoPy

    try:
        mesh = DracoPy.decode(bytes(data))
        attr = mesh.get_attribute_by_unique_id(int(ext["attributes"][name]))
    except Exception as e:  # DracoPy raises its own types and plain ValueErrors
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco data does not decode "
                                   f"({str(e)[:80]})") from None
    if attr is None:
        raise EnvironmentLoadError(f"corrupt glTF: {where}'s Draco data has no attribute "
                                   f"{ext['attributes'][name]} (its {name[:30]})")
    out = np.asarray(attr["data"])
    out = out.reshape(len(out), -1)
    if out.dtype.kind == "f":
        return out.astype(np.float64)
    if normalized:
        return out.astype(np.float64) / np.iinfo(out.dtype).max
    return out.astype(np.int64)


def instancing_of(node: dict) -> dict | None:
    """A node's EXT_mesh_gpu_instancing object, or None."""
    return _extension(node, INSTANCING)


def instance_attributes(ext: dict) -> dict:
    """A checked instancing extension's TRANSLATION, ROTATION and SCALE accessor indices."""
    return {k: v for k, v in ext["attributes"].items() if k in _INSTANCE_TYPES}


def check_instancing(d, where: str, ext, accessors: list) -> None:
    """Check a node's instancing: TRANSLATION, ROTATION and SCALE accessors of the types the
    extension allows, one element per instance in each (other attributes, e.g. _ID, are
    ignored)."""
    w = f"{where}.extensions.{INSTANCING}"
    attrs = ext.get("attributes") if isinstance(ext, dict) else None
    if not isinstance(attrs, dict):
        d.fail(f"{w}.attributes must be an object")
    attrs = {k: v for k, v in attrs.items() if k in _INSTANCE_TYPES}
    if not attrs:
        d.fail(f"{w} has none of TRANSLATION, ROTATION and SCALE")
    counts = set()
    for name, (kind, types) in _INSTANCE_TYPES.items():
        if name in attrs:
            a = accessors[d.index(attrs, name, f"{w}.attributes", "accessors")]
            if a.get("type") != kind or a.get("componentType") not in types or (
                    a.get("componentType") != 5126 and not a.get("normalized")):
                d.fail(f"{w}.attributes.{name} must be a {kind} accessor of floats"
                       + (" or normalized bytes or shorts" if name == "ROTATION" else ""))
            counts.add(a.get("count"))
    if len(counts) != 1:
        d.fail(f"{w}'s attributes have different counts ({sorted(map(str, counts))})")

