"""Load an environment file into an `Environment`: triangle meshes (metres, +Y up) with their
base colours, plus the sun. World vertices are computed in float64 (node transforms included),
then a local origin is chosen (`choose_origin`: 0 on every axis whose range holds the world
origin, else the bounds' centre rounded to whole metres), subtracted in float64 and only then
rounded to float32, so a level 10 km from the origin is as precise as one at the origin.

Formats
-------
- glTF 2.0 (.gltf, .glb): read directly (JSON + buffers) so base colours keep full float
  precision and `KHR_lights_punctual` directional lights can be found. Node transforms
  (matrix or TRS) are applied. glTF is always +Y up, metres. Compressed geometry
  (EXT_/KHR_meshopt_compression bufferViews, KHR_draco_mesh_compression primitives) is decoded
  by environment/gltf_ext.py, which also reads EXT_mesh_gpu_instancing (a mesh placed many
  times). Skinned and morphed meshes are posed as engines draw them with no animation playing
  (environment/gltf_pose.py: the joints' node transforms, the default morph weights).
- OBJ, PLY, STL: read with trimesh as a scene; scene-graph transforms are applied. Assumed to be
  metres, +Y up. Concave polygons are ear-cut (geometry/polygons.py: trimesh fans every
  polygon): an OBJ's before trimesh reads it, a PLY's from the faces trimesh keeps as read.
  A PLY's `tristrips` element is read as triangle strips (environment/ply.py: -1 restarts a
  strip); a list of float indices loads only when they are whole.
  OBJ `Kd` (through trimesh's material) is taken as a linear colour; PLY vertex or face
  colours (sRGB bytes) are averaged and converted to linear.
- USD (.usd, .usda, .usdc, .usdz): every visible `UsdGeom.Mesh` of default or render purpose
  (proxy only on a stage of nothing else) is triangulated
  (a fan for a convex face, ear clipping for a concave one: geometry/polygons.py; a
  `UsdGeom.PointInstancer` places its prototypes' meshes at its visible instances),
  moved to world space with `ComputeLocalToWorldTransform`, scaled by the stage's
  `metersPerUnit` and rotated to +Y up when the stage is Z up. The colour comes from a bound
  `UsdPreviewSurface` diffuseColor, else the `displayColor` primvar. The sun is a
  `UsdLux.DistantLight`.

Every failure is an `EnvironmentLoadError` with a one-line message naming the file.
"""

from __future__ import annotations

import base64
import bisect
import binascii
import contextlib
import dataclasses
import json
import os
import logging
import math
import mmap
import re
import struct
from pathlib import Path

import numpy as np

from baker.environment import gltf_ext, gltf_pose, native
from baker.environment.model import EnvMesh, Environment, Sun
from baker.errors import EnvironmentLoadError, exception_text
from baker.geometry import polygons
from baker.geometry.transforms import cross, length

log = logging.getLogger(__name__)

#: Toward-the-sun direction used when the file has no directional light (about 17 deg from
#: the zenith).
DEFAULT_SUN_DIRECTION = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])

DEFAULT_COLOR = (0.5, 0.5, 0.5, 1.0)

GLTF_EXTS = {".gltf", ".glb"}
TRIMESH_EXTS = {".obj", ".ply", ".stl"}
USD_EXTS = {".usd", ".usda", ".usdc", ".usdz"}
SUPPORTED_EXTS = GLTF_EXTS | TRIMESH_EXTS | USD_EXTS

_MAX_NAME = 63


# --------------------------------------------------------------------------- public API
#: the native and interchange formats of the tools levels come from, which export glTF
_EXPORT_AS_GLTF = {".fbx", ".blend", ".dae", ".3ds", ".max", ".ma", ".mb", ".umap", ".uasset",
                   ".unity", ".prefab", ".x3d", ".abc", ".3mf", ".ifc", ".skp", ".c4d", ".lwo"}


def load_environment(path: str | Path, sun_override=None, up_axis: str | None = None,
                     units: str | None = None) -> Environment:
    """Read an environment file.

    path         : .glb/.gltf, .obj, .ply, .stl, .usd/.usda/.usdc/.usdz
    sun_override : (3,) float toward the sun (in baker's +Y-up frame), or None to use the
                   file's directional light (or DEFAULT_SUN_DIRECTION when the file has none)
    up_axis      : "y" or "z", the file's up axis when it says otherwise or nothing (OBJ, PLY
                   and STL are read +Y up, glTF is +Y up by definition, USD has its upAxis);
                   None: the file's own. A +Z-up file is turned (x, y, z) -> (x, z, -y).
    units        : a key of UNITS, the length of the file's unit when it says otherwise or
                   nothing (OBJ, PLY and STL are read in metres, glTF is in metres by
                   definition, USD has its metersPerUnit); None: the file's own
    returns      : Environment with one EnvMesh per source mesh primitive (metres, +Y up,
                   float32 vertices relative to the environment's `origin`, chosen by
                   choose_origin from the float64 world bounds) and the sun
    raises       : EnvironmentLoadError for a missing, unsupported, corrupt or empty file
    """
    path = Path(path)
    if path.is_dir():   # (an empty argument is the current directory)
        raise EnvironmentLoadError("the environment path is a directory, not a file (give a "
                                   ".glb, .gltf, .obj, .ply, .stl or .usd file)",
                                   where=str(path))
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTS:
        hint = ("; export the level from its tool as glTF (.glb), OBJ or USD"
                if ext in _EXPORT_AS_GLTF else "")
        raise EnvironmentLoadError(
            f"unsupported environment format '{path.suffix or '(none)'}'; expected one of "
            f"{', '.join(sorted(SUPPORTED_EXTS))}{hint}", where=str(path))
    if not path.exists():
        raise EnvironmentLoadError("environment file not found", where=str(path))
    if not path.is_file():
        raise EnvironmentLoadError("environment path is not a file", where=str(path))

    try:
        with _quiet():
            if ext in USD_EXTS:
                raw, sun = _read_usd(path, up_axis, units)
            else:
                raw, sun = _read_gltf(path) if ext in GLTF_EXTS else _read_trimesh(path)
                if up_axis == "z" or (units or "m") != "m":
                    raw, sun = _reframed(raw, sun, up_axis == "z", UNITS[units or "m"])
        raw = _without_helpers(raw, path)
        total = sum(len(r[2]) for r in raw)
        if total > MAX_TRIANGLES or sum(len(r[1]) for r in raw) > MAX_VERTICES \
                or len(raw) > MAX_MESHES:
            raise EnvironmentLoadError(f"the level has {total:,} triangles in {len(raw):,} "
                                       f"meshes; a bake takes at most {MAX_TRIANGLES:,} "
                                       f"triangles and {MAX_MESHES:,} meshes: keep the part "
                                       "of the level the creature uses")
    except EnvironmentLoadError as exc:
        raise EnvironmentLoadError(exc.what, where=exc.where or str(path)) from None
    except MemoryError:
        raise EnvironmentLoadError("the file needs more memory than is available",
                                   where=str(path)) from None
    except Exception as exc:  # any parser failure is a corrupt file to the user
        msg = _error_text(exc)
        raise EnvironmentLoadError(f"cannot read environment: {msg}", where=str(path)) from None

    kept = []
    names = _unique_names([r[0] for r in raw])
    for name, (_, v, f, n, color, rough, metal) in zip(names, raw):
        v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
        try:
            _check_geometry(v, f, name)
        except EnvironmentLoadError as e:
            raise EnvironmentLoadError(e.what, where=str(path)) from None
        shading = [float(c) for c in color] + [float(rough), float(metal)]
        if not all(math.isfinite(x) for x in shading):
            raise EnvironmentLoadError(f"mesh {name!r}: its material's colour, roughness and "
                                       f"metallic must be finite numbers (got {shading})",
                                       where=str(path))
        cleaned = _clean(v, f, n)
        if cleaned is None:
            log.info("environment %s: dropping mesh %r, it has no usable faces", path, name)
            continue
        kept.append((name, cleaned, color, rough, metal))
    if not kept:
        raise EnvironmentLoadError("environment has no triangle faces", where=str(path))
    if len(kept) > MERGE_ABOVE:
        log.info("environment %s: %d meshes merged into one per material", path, len(kept))
        kept = _merged_by_material(kept)
    world = [v for _, (v, _, _), _, _, _ in kept]
    origin = choose_origin(np.min([v.min(axis=0) for v in world], axis=0),
                           np.max([v.max(axis=0) for v in world], axis=0))
    # world vertices are float64 until here: subtract the origin, then round once to float32
    meshes = [EnvMesh(name=name, vertices=(v - origin).astype(np.float32), faces=f, normals=n,
                      color=tuple(float(c) for c in color),
                      roughness=float(rough), metallic=float(metal))
              for name, (v, f, n), color, rough, metal in kept]
    if np.any(origin != 0):
        log.info("environment %s: local origin at %s m (world)", path, origin.tolist())
    # names may have lost uniqueness only if meshes were dropped: they cannot collide, keep them

    if sun_override is not None:
        sun = Sun(direction=_unit_direction(sun_override, path, "sun override"),
                  **({} if sun is None else {"intensity": sun.intensity, "color": sun.color}))
    elif sun is None:
        sun = Sun(direction=DEFAULT_SUN_DIRECTION.copy())
    if sun.direction[1] <= 0:
        log.warning("environment %s: the sun is at or below the horizon (direction %s)",
                    path, np.round(sun.direction, 3).tolist())

    return Environment(meshes=tuple(meshes), sun=sun, source=str(path),
                       name=sanitize_name(path.stem, fallback="environment"), origin=origin)


def choose_origin(lo, hi) -> np.ndarray:
    """The local origin of a level, chosen from its world bounds.

    lo, hi  : (3,) float64, metres, world min and max corners of every loaded vertex
    returns : (3,) float64, metres, world. Per axis: 0 when the level's range on that axis
              contains 0 (a level built around the world origin keeps its coordinates bit for
              bit), else the centre of the range rounded to a whole number of metres (exact in
              float64, so local = world - origin loses nothing before the float32 rounding).
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    centre = np.floor(0.5 * (lo + hi) + 0.5)
    return np.where((lo <= 0.0) & (hi >= 0.0), 0.0, centre)


def sanitize_name(name: str, fallback: str = "mesh") -> str:
    """A legal node name: [A-Za-z0-9_] only, not starting with a digit, at most 63 bytes."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", str(name or ""))
    s = re.sub(r"_+", "_", s).strip("_") or fallback
    if s[0].isdigit():
        s = "m_" + s
    return s[:_MAX_NAME]


# --------------------------------------------------------------------------- shared helpers
@contextlib.contextmanager
def _quiet():
    """Parsers' own chatter (numpy and Python warnings, trimesh's log) is held back while a
    file is read: a file that loads keeps the warnings as log records at debug level, a file
    that is refused prints only the one error line."""
    import warnings

    trimesh_log = logging.getLogger("trimesh")
    old = trimesh_log.level
    trimesh_log.setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings(record=True) as caught, \
                np.errstate(all="ignore"):
            warnings.simplefilter("always")
            yield
        for w in caught:
            log.debug("while reading: %s", w.message)
    finally:
        trimesh_log.setLevel(old)


def _error_text(exc: Exception) -> str:
    """One short line from a parser exception (pxr's messages carry C++ source locations)."""
    text = " ".join(exception_text(exc).split())
    m = re.search(r"in file \S+ : (.*?)(?= Error in '|$)", text)
    if m:
        text = m.group(1).strip().strip("'")
    if isinstance(exc, KeyError) and text:   # (a PLY without an x property said only 'x')
        text = f"{text} is missing or unknown"
    return text[:200] or type(exc).__name__


def _merged_by_material(kept: list) -> list:
    """kept's meshes (name, (v, f, n), colour, roughness, metalness) merged into one per
    material, in the order each material first appears, named after its first mesh: a level
    of thousands of objects exports as a handful of meshes."""
    groups: dict = {}
    for entry in kept:
        key = (tuple(float(c) for c in entry[2]), float(entry[3]), float(entry[4]))
        groups.setdefault(key, []).append(entry)
    out = []
    for (color, rough, metal), entries in groups.items():
        vs = [e[1][0] for e in entries]
        starts = np.cumsum([0] + [len(v) for v in vs[:-1]])
        faces = np.concatenate([e[1][1] + k for e, k in zip(entries, starts)])
        ns = [e[1][2] for e in entries]
        n = None if any(x is None for x in ns) else np.concatenate(ns)
        name = entries[0][0] if len(entries) == 1 else f"{entries[0][0]}_merged"
        out.append((name, (np.concatenate(vs), faces, n), color, rough, metal))
    names = _unique_names([e[0] for e in out])
    return [(nm, *e[1:]) for nm, e in zip(names, out)]


#: meshes that engines' naming conventions mark as helpers rather than level geometry: Godot's
#: import suffixes for meshes it does not draw (collision only, navigation, occluders, not
#: imported), Unreal's collision-hull prefixes, and a mesh named navmesh (a navigation overlay
#: drawn over the floors, as three-pathfinding's levels have: the creature walked on it, a
#: tenth of a metre over the floor)
HELPER_NAME = re.compile(r"(-(colonly|convcolonly|navmesh|occonly|noimp)$)|(^u(cx|bx|cp|sp)_)"
                         r"|(^nav_?mesh([-_. ]?\d*)$)", re.IGNORECASE)


def _without_helpers(raw: list, path: Path) -> list:
    """The raw meshes less those HELPER_NAME names (all of them when that is all there is)."""
    helper = [HELPER_NAME.search(str(r[0])) is not None for r in raw]
    kept = [r for r, h in zip(raw, helper) if not h]
    if kept and len(kept) < len(raw):
        left = [str(r[0]) for r, h in zip(raw, helper) if h]
        log.info("environment %s: %d helper mesh(es) left out (%s)", path.name, len(left),
                 ", ".join(left[:5]) + (", ..." if len(left) > 5 else ""))
        return kept
    return raw


def _unique_names(names: list[str]) -> list[str]:
    """Each name sanitized, repeats numbered _2, _3, ... (each base's count kept: linear in
    the names, however many repeat)."""
    out, used, tried = [], set(), {}
    for raw in names:
        base = sanitize_name(raw)
        name, k = base, tried.get(base, 1)
        while name in used:
            k += 1
            suffix = f"_{k}"
            name = base[: _MAX_NAME - len(suffix)] + suffix
        tried[base] = k
        used.add(name)
        out.append(name)
    return out


def _azimuth_rate(light: dict) -> float:
    """[rad/s] a glTF light's turning rate about +Y: its extras' `azimuth_deg_per_s` (a finite
    number, at most 360 deg/s), else 0 (a fixed sun)."""
    extras = light.get("extras")
    rate = extras.get("azimuth_deg_per_s", 0.0) if isinstance(extras, dict) else 0.0
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not math.isfinite(rate):
        return 0.0
    return math.radians(max(-360.0, min(360.0, float(rate))))


def light_direction(world: np.ndarray) -> np.ndarray | None:
    """The unit direction a light node's world matrix (4, 4) turns its +Z to, or None when it
    has none (a zero or non-finite scale). A scale whose square passes a float (1e300) still
    has its direction: the norm overflowed to inf and the direction came out 0 (a traceback
    when the sun was written)."""
    d = world[:3, :3] @ np.array([0.0, 0.0, 1.0])
    n = float(np.linalg.norm(d))
    if math.isinf(n) and np.all(np.isfinite(d)):
        d = d / np.max(np.abs(d))
        n = float(np.linalg.norm(d))
    return d / n if math.isfinite(n) and n > 1e-12 else None


def _unit_direction(d, path, what) -> np.ndarray:
    d = np.asarray(d, dtype=np.float64).reshape(-1)
    n = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
    if d.shape != (3,) or not np.all(np.isfinite(d)) or n < 1e-12:
        raise EnvironmentLoadError(f"{what} must be a finite non-zero 3-vector (file {path})")
    return d / n


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


#: [m] largest |coordinate| of a level vertex (world)
COORD_LIMIT = 1e8


def _check_geometry(v, f, name: str) -> None:
    """Refuse (EnvironmentLoadError) a mesh with non-finite or out-of-range vertices, or face
    indices outside its vertex list. v : (n, 3) float64 world; f : (m, 3) int64."""
    if len(v) and not np.all(np.isfinite(v)):
        bad = int(np.nonzero(~np.all(np.isfinite(v), axis=1))[0][0])
        raise EnvironmentLoadError(f"mesh '{name}' has a non-finite vertex (vertex {bad}: "
                                   f"{v[bad].tolist()})")
    if len(v) and np.abs(v).max() > COORD_LIMIT:
        raise EnvironmentLoadError(
            f"coordinates out of range in mesh '{name}': up to {np.abs(v).max():.9g} m; "
            f"expected within +-{COORD_LIMIT:.9g} m")   # (1e+08 m was 'over' 1e+08 m)
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        bad = int(f.max()) if f.max() >= len(v) else int(f.min())
        raise EnvironmentLoadError(f"mesh '{name}' has a face index {bad} outside its "
                                   f"{len(v)} vertices")


def _clean(v, f, n):
    """Drop faces of zero area and unused vertices (indices and vertices were checked by
    _check_geometry). Returns (vertices float64 world, faces uint32, normals float32|None)
    or None."""
    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0 or len(v) == 0:
        return None
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    if len(f):
        tri = v[f]
        area2 = length(cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
        scale = max(float(np.ptp(v[_used(f, len(v))], axis=0).max()), 1e-9)
        f = f[area2 > (scale * 1e-9) ** 2]
    if len(f) == 0:
        return None
    used = _used(f, len(v))
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    nv = v[used]
    nf = remap[f].astype(np.uint32)
    nn = None
    if n is not None:
        n = np.asarray(n, dtype=np.float64).reshape(-1, 3)
        if len(n) == len(v):
            n = n[used]
            size = np.linalg.norm(n, axis=1, keepdims=True)
            if np.all(np.isfinite(n)) and np.all(size > 1e-8):
                nn = (n / size).astype(np.float32)
    return nv, nf, nn


def _used(f: np.ndarray, nv: int) -> np.ndarray:
    """The sorted indices of the nv vertices that faces f use (np.unique(f), by a mask)."""
    mask = np.zeros(nv, dtype=bool)
    mask[f.reshape(-1)] = True
    return np.flatnonzero(mask)


def _fix_winding(f: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Reverse triangle winding when the 3x3 part of m mirrors space."""
    if np.linalg.det(m[:3, :3]) < 0:
        return f[:, ::-1].copy()
    return f


#: a +Z-up frame to baker's +Y-up one: (x, y, z) -> (x, z, -y)
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
#: --units: metres per unit
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "km": 1000.0, "in": 0.0254, "ft": 0.3048}


def _reframed(raw: list, sun: Sun | None, z_up: bool, metres: float
              ) -> tuple[list, Sun | None]:
    """Raw meshes and the sun read from a file in units of `metres` metres, +Z up when z_up,
    put in metres and +Y up (a rotation and a uniform scale: windings keep)."""
    turn = Z_UP_TO_Y_UP if z_up else np.eye(3)
    m = np.eye(4)
    m[:3, :3] = turn * metres
    turned = [(name, _transform_points(m, v), f, None if n is None else n @ turn.T,
               *rest) for name, v, f, n, *rest in raw]
    if sun is not None:
        sun = dataclasses.replace(sun, direction=turn @ sun.direction)
    return turned, sun


def _placed(mats: np.ndarray, points: np.ndarray, faces: np.ndarray, normals):
    """A mesh placed by each of mats (k, 4, 4): (vertices (k n, 3), triangles (k m, 3), normals
    or None), the copies one after another, each copy's winding kept facing out."""
    vs, fs, ns = [], [], []
    for k, m in enumerate(mats):
        vs.append(_transform_points(m, points))
        fs.append(_fix_winding(faces, m) + k * len(points))
        ns.append(None if normals is None else _transform_normals(m, normals))
    n = None if any(x is None for x in ns) else np.concatenate(ns)
    return np.concatenate(vs), np.concatenate(fs), n


def check_placed(copies: int, triangles: int, vertices: int, path) -> None:
    """Refuse a mesh placed so often that its copies pass MAX_TRIANGLES or MAX_VERTICES."""
    if copies * triangles > MAX_TRIANGLES or copies * vertices > MAX_VERTICES:
        raise EnvironmentLoadError(
            f"the level places a {triangles:,}-triangle, {vertices:,}-vertex mesh {copies:,} "
            f"times: more than the {MAX_TRIANGLES:,} triangles and {MAX_VERTICES:,} vertices "
            "a bake takes", where=str(path))


def _transform_points(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """m: (4, 4) column-vector convention; v: (n, 3)."""
    return v @ m[:3, :3].T + m[:3, 3]


def _transform_normals(m: np.ndarray, n: np.ndarray) -> np.ndarray:
    try:
        nm = np.linalg.inv(m[:3, :3]).T
    except np.linalg.LinAlgError:
        return None
    return n @ nm.T


# --------------------------------------------------------------------------- glTF
_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
              5125: np.uint32, 5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_UNSUPPORTED_EXT = {"KHR_draco_mesh_compression", "EXT_meshopt_compression"}


def _parse_glb(data: bytes, path: Path):
    if len(data) < 12 or data[:4] != b"glTF":
        raise EnvironmentLoadError("corrupt GLB: not a binary glTF (bad header)")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise EnvironmentLoadError(f"unsupported glTF version {version} (need 2)")
    if length > len(data):
        raise EnvironmentLoadError(f"corrupt GLB: truncated ({len(data)} of {length} bytes)")
    off, doc, bin_chunk = 12, None, None
    while off + 8 <= length:
        clen, ctype = struct.unpack_from("<II", data, off)
        chunk = data[off + 8: off + 8 + clen]
        if len(chunk) != clen:
            raise EnvironmentLoadError("corrupt GLB: truncated chunk")
        if ctype == 0x4E4F534A and doc is None:    # (a byte order mark is passed over)
            doc = json.loads(chunk.decode("utf-8-sig"))
        elif ctype == 0x004E4942 and bin_chunk is None:
            bin_chunk = chunk
        off += 8 + clen
    if doc is None:
        raise EnvironmentLoadError("corrupt GLB: no JSON chunk")
    return doc, bin_chunk


_COMPONENT_NAMES = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT",
                    5123: "UNSIGNED_SHORT", 5125: "UNSIGNED_INT", 5126: "FLOAT"}
#: required extensions that change nothing this loader reads (shading, textures, lights) or
#: that it implements (quantized attributes are read in any component type; compressed
#: bufferViews and primitives are decoded, environment/gltf_ext.py)
_REQUIRED_OK_PREFIXES = ("KHR_materials_", "KHR_texture_", "EXT_texture_")
_REQUIRED_OK = {"KHR_lights_punctual", "KHR_mesh_quantization", "KHR_materials_variants",
                *gltf_ext.MESHOPT, gltf_ext.DRACO, gltf_ext.INSTANCING}
#: the most triangles a level may place (its meshes times their placements): a level of 20 M
#: triangles needs about 4 GB to navigate (navmesh.budget); beyond it, cut the level down
MAX_TRIANGLES = 20_000_000
#: the most vertices a level may place, likewise (a mesh of few triangles can hold many)
MAX_VERTICES = 20_000_000
#: a level of more meshes than this (an engine's export of every prop) is merged into one mesh
#: per material: the files keep a handful of nodes, and writing them stays quick
MERGE_ABOVE = 1_000
#: the most meshes a level may place (refused beyond: reading each one costs)
MAX_MESHES = 100_000
#: accessors without a bufferView are zero-filled: at most this many bytes + 64x the file
_ZERO_FILL_SLACK = 1 << 20


def _forgiving_base64(payload: str) -> bytes:
    """A data: URI's base64 payload decoded as browsers (and three.js) decode it, WHATWG's
    forgiving-base64: ASCII whitespace (a payload broken into lines) ignored, the '=' padding
    optional. binascii.Error for anything else (another alphabet, a stray '=')."""
    if any(c in payload for c in "\t\n\f\r "):
        payload = re.sub(r"[\t\n\f\r ]+", "", payload)
    if len(payload) % 4 == 0 and payload.endswith("="):
        payload = payload[:-2] if payload.endswith("==") else payload[:-1]
    if len(payload) % 4 == 1:
        raise binascii.Error("a base64 payload cannot be 1 more than a multiple of 4 long")
    return base64.b64decode(payload + "=" * (-len(payload) % 4), validate=True)


class _Doc:
    """Checked access to a glTF JSON document: every index, number and array shape is checked
    against its declaration before use. Errors name the element, e.g. 'accessors[3].count'."""

    def __init__(self, doc, path: Path):
        if not isinstance(doc, dict):
            raise EnvironmentLoadError("corrupt glTF: the JSON is not an object", where=str(path))
        self.doc, self.path = doc, path
        self._checked: set[str] = set()

    def fail(self, what: str):
        raise EnvironmentLoadError(f"corrupt glTF: {what}", where=str(self.path))

    def array(self, name: str) -> list:
        """doc[name], checked once to be an array of objects (an index check asks for it per
        index)."""
        a = self.doc.get(name, [])
        if name not in self._checked:
            if not isinstance(a, list) or not all(isinstance(x, dict) for x in a):
                self.fail(f"'{name}' must be an array of objects")
            self._checked.add(name)
        return a

    def integer(self, obj: dict, key: str, where: str, lo: int = 0, hi: int = 2**53,
                default=None):
        v = obj.get(key, default)
        if v is None and default is None and key not in obj:
            return None
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            self.fail(f"{where}.{key} = {str(v)[:40]}; expected an integer in [{lo}, {hi}]")
        return v

    def index(self, obj: dict, key: str, where: str, target: str, required=False):
        n = len(self.array(target))
        if key not in obj:
            if required:
                self.fail(f"{where}.{key} is missing")
            return None
        v = obj[key]
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < n:
            self.fail(f"{where}.{key} = {str(v)[:40]} is not an index into {target} "
                      f"({n} entries)")
        return v

    def numbers(self, obj: dict, key: str, where: str, n: int, lo: float = -math.inf,
                hi: float = math.inf):
        """obj[key], n finite numbers from lo to hi (n = 0: one number), or None when absent."""
        if key not in obj:
            return None
        v = obj[key]
        vs = [v] if n == 0 else v
        if ((n and (not isinstance(v, list) or len(v) != n))
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in vs)
                or not all(math.isfinite(x) and lo <= x <= hi for x in vs)):
            what = "a finite number" if n == 0 else f"{n} finite numbers"
            bounds = "" if lo == -math.inf else f" from {lo:g} to {hi:g}" if hi < math.inf \
                else f" of at least {lo:g}"
            self.fail(f"{where}.{key} must be {what}{bounds} (got {str(v)[:40]})")
        return v


def _listed_twice(items: list):
    """The first item of a glTF index list that it holds twice, else None (a scene's nodes and
    a node's children are sets: glTF's uniqueItems)."""
    seen = set()
    for x in items:
        if x in seen:
            return x
        seen.add(x)
    return None


def _reached_twice(i: int, first: int, then: int) -> str:
    """What is wrong when the scene walk reaches node i a second time: first as a child of
    node `first`, then of node `then` (-1: as a root of the scene)."""
    if first < 0 and then < 0:
        return f"the scene lists node {i} twice"
    if i in (first, then):
        return f"node {i} is its own child"
    if first < 0 or then < 0:
        return (f"node {i} is a root of the scene and also a child of node "
                f"{max(first, then)} (a root has no parent)")
    if first == then:
        return f"node {first} lists child {i} twice"
    return f"node {i} has two parents, nodes {first} and {then}"


class _GltfReader:
    def __init__(self, doc: dict, bin_chunk: bytes | None, path: Path, file_size: int = 0):
        d = _Doc(doc, path)
        if not isinstance(doc.get("asset"), dict):
            raise EnvironmentLoadError("corrupt glTF: no 'asset' object", where=str(path))
        ver = str(doc["asset"].get("version", ""))
        if not ver.startswith("2"):
            raise EnvironmentLoadError(f"unsupported glTF version '{ver[:20]}' (need 2.x)",
                                       where=str(path))
        req = doc.get("extensionsRequired", [])
        if not isinstance(req, list) or not all(isinstance(x, str) for x in req):
            d.fail("'extensionsRequired' must be an array of names")
        unknown = sorted(x for x in req if x not in _REQUIRED_OK
                         and not x.startswith(_REQUIRED_OK_PREFIXES))
        if unknown:
            raise EnvironmentLoadError(
                f"glTF requires unsupported extension(s) {', '.join(x[:60] for x in unknown)}",
                where=str(path))
        self.doc, self.bin, self.path, self.d = doc, bin_chunk, path, d
        self.file_size = file_size
        self._buffers: dict[int, bytes] = {}
        self._views: dict[int, bytes] = {}
        self._placeholders: set[int] = set()
        self._decoded: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self._poser: gltf_pose.Poser | None = None     # made for the first skinned/morphed mesh
        self._sizes = [self._buffer_size(i, b) for i, b in enumerate(d.array("buffers"))]
        self._check_views()
        self._check_accessors()
        self._check_scene()

    # ------------------------------------------------------------------ checks, no allocation
    def _external(self, uri: str, i: int) -> Path:
        from urllib.parse import unquote, urlparse

        if urlparse(uri).scheme:
            self.d.fail(f"buffers[{i}].uri '{uri[:60]}' is not a relative file path")
        rel = unquote(uri)
        if "\0" in rel:
            self.d.fail(f"buffers[{i}].uri holds a NUL character")
        folder = self.path.parent.resolve()
        try:
            target = (folder / rel).resolve()
        except (RuntimeError, OSError) as e:    # a loop of symbolic links (ELOOP in 3.13)
            raise EnvironmentLoadError(f"buffers[{i}].uri '{uri[:60]}' cannot be resolved: "
                                       f"{_error_text(e)}", where=str(self.path)) from None
        if os.path.isabs(rel) or not target.is_relative_to(folder):
            raise EnvironmentLoadError(f"buffers[{i}].uri '{uri[:60]}' points outside the "
                                       "environment's folder", where=str(self.path))
        if not target.is_file():
            raise EnvironmentLoadError(f"missing external buffer '{uri[:60]}' (buffers[{i}])",
                                       where=str(self.path))
        return target

    def _buffer_size(self, i: int, b: dict) -> int:
        length = self.d.integer(b, "byteLength", f"buffers[{i}]", lo=1, default=0)
        uri = b.get("uri")
        if gltf_ext.is_fallback(b) and (uri is None or self._missing(uri)):
            self._placeholders.add(i)   # a meshopt placeholder: only compressed views read it
            return length
        if uri is None:
            if self.bin is None:
                self.d.fail(f"buffers[{i}] has no uri and the file has no binary chunk")
            actual = len(self.bin)
        elif not isinstance(uri, str):
            self.d.fail(f"buffers[{i}].uri must be a string")
        elif uri.startswith("data:"):
            head, sep, payload = uri.partition(",")
            if not sep or not head.endswith(";base64"):
                self.d.fail(f"buffers[{i}].uri is a data: URI without ';base64,'")
            try:
                data = _forgiving_base64(payload)
            except (binascii.Error, ValueError):
                raise EnvironmentLoadError(f"buffers[{i}].uri is a data: URI that is not valid "
                                           "base64", where=str(self.path)) from None
            self._buffers[i] = data
            actual = len(data)
        else:
            actual = self._external(uri, i).stat().st_size
        if actual < length:
            self.d.fail(f"buffers[{i}] declares {length} bytes but has {actual}")
        return length

    def _check_views(self):
        d = self.d
        for j, bv in enumerate(d.array("bufferViews")):
            w = f"bufferViews[{j}]"
            b = d.index(bv, "buffer", w, "buffers", required=True)
            off = d.integer(bv, "byteOffset", w, default=0)
            length = d.integer(bv, "byteLength", w, lo=1, default=0)
            if off + length > self._sizes[b]:
                d.fail(f"{w} (bytes {off}..{off + length}) runs past buffers[{b}] "
                       f"({self._sizes[b]} bytes)")
            ext = gltf_ext.meshopt_of(bv)
            if ext is not None:
                gltf_ext.check_meshopt(d, w, bv, ext, self._sizes, self.file_size)
            elif self._placeholder(b):
                d.fail(f"{w} reads buffers[{b}], a meshopt fallback that holds no data")
            stride = d.integer(bv, "byteStride", w, lo=4, hi=252)
            if stride is not None and stride % 4:
                d.fail(f"{w}.byteStride = {stride}; expected a multiple of 4 in [4, 252]")

    def _placeholder(self, b: int) -> bool:
        return b in self._placeholders

    def _missing(self, uri) -> bool:
        """Whether a fallback buffer's uri names no file in the environment's folder (a
        decoder never needs it)."""
        if not isinstance(uri, str) or uri.startswith("data:"):
            return False
        try:
            self._external(uri, -1)
        except EnvironmentLoadError:
            return True
        return False

    def _span(self, w: str, view: int, offset: int, count: int, elem: int, ctype: int):
        """Check that count elements of elem bytes at offset fit in bufferViews[view]."""
        d = self.d
        bv = self.doc["bufferViews"][view]
        stride = bv.get("byteStride") or elem
        if stride < elem:
            d.fail(f"bufferViews[{view}].byteStride = {stride} is smaller than {w}'s element "
                   f"({elem} bytes)")
        if offset % np.dtype(_COMPONENT[ctype]).itemsize:
            d.fail(f"{w}.byteOffset = {offset} is not a multiple of its component size")
        end = offset + stride * (count - 1) + elem
        if end > bv.get("byteLength", 0):
            d.fail(f"{w} needs {end} bytes of bufferViews[{view}], which has "
                   f"{bv.get('byteLength', 0)}")

    def _component(self, obj, w, key="componentType", allowed=None):
        ct = obj.get("componentType") if key == "componentType" else obj.get(key)
        allowed = allowed or _COMPONENT
        if isinstance(ct, bool) or ct not in allowed:
            names = ", ".join(f"{k} ({_COMPONENT_NAMES[k]})" for k in allowed)
            self.d.fail(f"{w}.componentType = {str(ct)[:20]}; expected one of {names}")
        return ct

    def _check_accessors(self):
        d = self.d
        for k, a in enumerate(d.array("accessors")):
            w = f"accessors[{k}]"
            ct = self._component(a, w)
            if a.get("type") not in _NCOMP:
                d.fail(f"{w}.type = {str(a.get('type'))[:20]}; expected one of "
                       f"{', '.join(_NCOMP)}")
            count = d.integer(a, "count", w, lo=1, hi=2**32, default=0)
            elem = np.dtype(_COMPONENT[ct]).itemsize * _NCOMP[a["type"]]
            off = d.integer(a, "byteOffset", w, default=0)
            view = d.index(a, "bufferView", w, "bufferViews")
            if view is not None:
                self._span(w, view, off, count, elem, ct)
            elif count * elem > 64 * max(self.file_size, 1) + _ZERO_FILL_SLACK:
                d.fail(f"{w} declares {count:,} elements ({count * elem:,} bytes) with no "
                       f"bufferView, far more than the file's {self.file_size:,} bytes")
            sp = a.get("sparse")
            if sp is not None:
                if not isinstance(sp, dict) or not isinstance(sp.get("indices"), dict) \
                        or not isinstance(sp.get("values"), dict):
                    d.fail(f"{w}.sparse must have indices and values objects")
                n = d.integer(sp, "count", f"{w}.sparse", lo=1, hi=count, default=0)
                ii, vv = sp["indices"], sp["values"]
                ict = self._component(ii, f"{w}.sparse.indices",
                                      allowed={5121: 1, 5123: 1, 5125: 1})
                iview = d.index(ii, "bufferView", f"{w}.sparse.indices", "bufferViews",
                                required=True)
                self._span(f"{w}.sparse.indices", iview,
                           d.integer(ii, "byteOffset", f"{w}.sparse.indices", default=0), n,
                           np.dtype(_COMPONENT[ict]).itemsize, ict)
                vview = d.index(vv, "bufferView", f"{w}.sparse.values", "bufferViews",
                                required=True)
                self._span(f"{w}.sparse.values", vview,
                           d.integer(vv, "byteOffset", f"{w}.sparse.values", default=0), n,
                           elem, ct)

    def _check_scene(self):
        d = self.d
        acc = self.doc.get("accessors", [])
        nmat = len(d.array("materials"))
        for m, mesh in enumerate(d.array("meshes")):
            prims = mesh.get("primitives", [])
            if not isinstance(prims, list) or not all(isinstance(p, dict) for p in prims):
                d.fail(f"meshes[{m}].primitives must be an array of objects")
            for pi, prim in enumerate(prims):
                w = f"meshes[{m}].primitives[{pi}]"
                draco = gltf_ext.draco_of(prim)
                if draco is not None:
                    gltf_ext.check_draco(d, w, draco)
                attrs = prim.get("attributes", {})
                if not isinstance(attrs, dict):
                    d.fail(f"{w}.attributes must be an object")
                for name in attrs:
                    d.index(attrs, name, f"{w}.attributes", "accessors")
                if "POSITION" in attrs:
                    pa = acc[attrs["POSITION"]]
                    if pa["type"] != "VEC3":
                        d.fail(f"{w}.attributes.POSITION must be a VEC3 accessor")
                    for name in attrs:      # one value of every attribute per vertex
                        if acc[attrs[name]].get("count") != pa.get("count"):
                            d.fail(f"{w}.attributes.{name} has {acc[attrs[name]].get('count')} "
                                   f"elements, POSITION {pa.get('count')}")
                if "NORMAL" in attrs and acc[attrs["NORMAL"]]["type"] != "VEC3":
                    d.fail(f"{w}.attributes.NORMAL must be a VEC3 accessor")
                i = d.index(prim, "indices", w, "accessors")
                if i is not None:
                    ia = acc[i]
                    if ia["type"] != "SCALAR" or ia["componentType"] not in (5121, 5123, 5125) \
                            or ia.get("normalized"):
                        d.fail(f"{w}.indices must be a SCALAR accessor of unsigned integers "
                               "(componentType 5121, 5123 or 5125), not normalized")
                mode = d.integer(prim, "mode", w, lo=0, hi=6, default=4)
                corners = acc[i].get("count") if i is not None else (
                    acc[attrs["POSITION"]].get("count") if "POSITION" in attrs else 0)
                if mode == 4 and isinstance(corners, int) and corners % 3:
                    d.fail(f"{w} lists {corners} triangle corners, not a multiple of 3")
                if "material" in prim:
                    if isinstance(prim["material"], bool) or not isinstance(prim["material"], int) \
                            or not 0 <= prim["material"] < nmat:
                        d.fail(f"{w}.material is not an index into materials ({nmat} entries)")
        for mi, mat in enumerate(d.array("materials")):
            pbr = mat.get("pbrMetallicRoughness", {})
            if not isinstance(pbr, dict):
                d.fail(f"materials[{mi}].pbrMetallicRoughness must be an object")
            for key, n in (("baseColorFactor", 4), ("roughnessFactor", 0), ("metallicFactor", 0)):
                d.numbers(pbr, key, f"materials[{mi}].pbrMetallicRoughness", n)
        lights = self.doc.get("extensions", {})
        lights = lights.get("KHR_lights_punctual", {}) if isinstance(lights, dict) else {}
        lights = lights.get("lights", []) if isinstance(lights, dict) else []
        if not isinstance(lights, list) or not all(isinstance(x, dict) for x in lights):
            d.fail("KHR_lights_punctual.lights must be an array of objects")
        for li, light in enumerate(lights):
            # KHR_lights_punctual's ranges: the writers store the sun's as read
            d.numbers(light, "color", f"KHR_lights_punctual.lights[{li}]", 3, lo=0.0, hi=1.0)
            d.numbers(light, "intensity", f"KHR_lights_punctual.lights[{li}]", 0, lo=0.0)
        for ni, node in enumerate(d.array("nodes")):
            w = f"nodes[{ni}]"
            d.index(node, "mesh", w, "meshes")
            kids = node.get("children", [])
            if not isinstance(kids, list):
                d.fail(f"{w}.children must be an array")
            for c in kids:
                d.index({"c": c}, "c", f"{w}.children", "nodes")
            twice = _listed_twice(kids)
            if twice is not None:
                d.fail(f"{w}.children lists node {twice} twice")
            d.numbers(node, "matrix", w, 16)
            d.numbers(node, "translation", w, 3)
            d.numbers(node, "rotation", w, 4)
            d.numbers(node, "scale", w, 3)
            if "matrix" in node:
                if any(k in node for k in ("translation", "rotation", "scale")):
                    d.fail(f"{w} has both a matrix and translation, rotation or scale")
                if list(map(float, node["matrix"][3::4])) != [0.0, 0.0, 0.0, 1.0]:
                    d.fail(f"{w}.matrix is not an affine transform (its last row is not "
                           "0, 0, 0, 1)")
            if "rotation" in node and not math.fsum(x * x for x in node["rotation"]) > 1e-12:
                d.fail(f"{w}.rotation is a zero quaternion, not a rotation")
            inst = gltf_ext.instancing_of(node)
            if inst is not None:
                gltf_ext.check_instancing(d, w, inst, self.doc.get("accessors", []))
            ext = node.get("extensions", {})
            ref = ext.get("KHR_lights_punctual") if isinstance(ext, dict) else None
            if ref is not None:
                if not isinstance(ref, dict) or isinstance(ref.get("light"), bool) \
                        or not isinstance(ref.get("light"), int) \
                        or not 0 <= ref["light"] < len(lights):
                    d.fail(f"{w}.extensions.KHR_lights_punctual.light is not an index into "
                           f"the lights ({len(lights)} entries)")
        scenes = d.array("scenes")
        for si, sc in enumerate(scenes):
            roots = sc.get("nodes", [])
            if not isinstance(roots, list):
                d.fail(f"scenes[{si}].nodes must be an array")
            for r in roots:
                d.index({"n": r}, "n", f"scenes[{si}].nodes", "nodes")
            twice = _listed_twice(roots)
            if twice is not None:   # (it said 'node 0 has two parents')
                d.fail(f"scenes[{si}].nodes lists node {twice} twice")
        if scenes:
            d.index(self.doc, "scene", "document", "scenes") if "scene" in self.doc else None
        gltf_pose.check(d, self.doc)        # skins, morph targets and weights

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            uri = self.doc["buffers"][i].get("uri")
            if uri is None:
                data = self.bin
            else:       # mapped: only the bytes the views use are read
                with open(self._external(uri, i), "rb") as f:
                    size = os.fstat(f.fileno()).st_size
                    data = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
                if len(data) < self._sizes[i]:
                    self.d.fail(f"buffers[{i}] is shorter than declared")
            self._buffers[i] = data
        return self._buffers[i]

    def view(self, j: int) -> bytes:
        """bufferViews[j]'s bytes (byteLength of them), decoded when compressed (meshopt)."""
        if j not in self._views:
            bv = self.doc["bufferViews"][j]
            ext = gltf_ext.meshopt_of(bv)
            if ext is not None:
                data = gltf_ext.decode_meshopt(self.buffer(ext["buffer"]), ext,
                                               f"bufferViews[{j}]")
            else:
                off = bv.get("byteOffset", 0)
                data = memoryview(self.buffer(bv["buffer"]))[off: off + bv["byteLength"]]
            if len(data) < bv["byteLength"]:
                raise EnvironmentLoadError(f"corrupt glTF: bufferViews[{j}] is shorter than "
                                           "declared", where=str(self.path))
            self._views[j] = data
        return self._views[j]

    def accessor(self, i: int) -> np.ndarray:
        """Accessor data as a (count, ncomp) float64 or int64 array, normalization applied."""
        a = self.doc["accessors"][i]
        dtype = np.dtype(_COMPONENT[a["componentType"]]).newbyteorder("<")
        ncomp = _NCOMP[a["type"]]
        count = int(a["count"])
        if "bufferView" in a:
            bv = self.doc["bufferViews"][a["bufferView"]]
            buf = self.view(a["bufferView"])
            start = a.get("byteOffset", 0)
            elem = dtype.itemsize * ncomp
            stride = bv.get("byteStride") or elem
            end = start + stride * (count - 1) + elem if count else start
            if end > len(buf):
                raise EnvironmentLoadError(f"corrupt glTF {self.path}: accessor {i} out of bounds")
            if count == 0:
                out = np.zeros((0, ncomp), dtype=dtype)
            else:
                raw = np.frombuffer(buf, dtype=np.uint8, count=end - start, offset=start)
                rows = np.lib.stride_tricks.as_strided(
                    raw, shape=(count, elem), strides=(stride, 1))
                out = np.ascontiguousarray(rows).view(dtype).reshape(count, ncomp)
        else:
            out = np.zeros((count, ncomp), dtype=dtype)
        out = out.copy()
        sparse = a.get("sparse")
        if sparse:
            n = int(sparse["count"])
            idx_info, val_info = sparse["indices"], sparse["values"]
            idt = np.dtype(_COMPONENT[idx_info["componentType"]]).newbyteorder("<")
            idx = np.frombuffer(self.view(idx_info["bufferView"]), dtype=idt, count=n,
                                offset=idx_info.get("byteOffset", 0))
            vals = np.frombuffer(self.view(val_info["bufferView"]), dtype=dtype, count=n * ncomp,
                                 offset=val_info.get("byteOffset", 0))
            idx = idx.astype(np.int64)
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise EnvironmentLoadError(f"corrupt glTF: accessors[{i}].sparse index "
                                           f"{int(idx.max())} is past its {count} elements",
                                           where=str(self.path))
            out[idx] = vals.reshape(n, ncomp)
        if a.get("normalized") and dtype.kind in "iu":
            info = np.iinfo(dtype)
            return np.maximum(out.astype(np.float64) / info.max, -1.0)
        if dtype.kind == "f":
            return out.astype(np.float64)
        return out.astype(np.int64)

    @staticmethod
    def local_matrix(node: dict) -> np.ndarray:
        if "matrix" in node:
            return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        from scipy.spatial.transform import Rotation

        m = np.eye(4)
        q = np.asarray(node.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
        if np.linalg.norm(q) > 0:
            m[:3, :3] = Rotation.from_quat(q).as_matrix()
        m[:3, :3] = m[:3, :3] * np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
        m[:3, 3] = node.get("translation", [0, 0, 0])
        return m

    def world_nodes(self, matrices: bool = True):
        """Yield (node_index, world_matrix) over the default scene, parents first (the matrix
        None unless `matrices`)."""
        nodes = self.doc.get("nodes", [])
        scenes = self.doc.get("scenes", [])
        if scenes:
            roots = scenes[self.doc.get("scene", 0)].get("nodes", [])
        else:  # no scene: every node without a parent is a root
            children = {c for n in nodes for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
            if nodes and not roots:
                raise EnvironmentLoadError("corrupt glTF: no scene, and every node has a parent "
                                           "(the nodes form a cycle)", where=str(self.path))
        stack = [(r, np.eye(4), -1) for r in reversed(roots)]
        came = {}       # node -> the node whose child it was reached as (-1: a scene root)
        while stack:
            i, parent, by = stack.pop()
            if i in came:
                raise EnvironmentLoadError(f"corrupt glTF: {_reached_twice(i, came[i], by)}",
                                           where=str(self.path))
            came[i] = by
            world = parent @ self.local_matrix(nodes[i]) if matrices else None
            yield i, world
            for c in reversed(nodes[i].get("children", [])):
                stack.append((c, world, i))

    def material(self, idx):
        if idx is None:
            return DEFAULT_COLOR, 1.0, 0.0
        mat = self.doc["materials"][idx]
        pbr = mat.get("pbrMetallicRoughness", {})
        color = tuple(float(c) for c in pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]))
        return color, float(pbr.get("roughnessFactor", 1.0)), float(pbr.get("metallicFactor", 1.0))

    def triangles(self, prim: dict):
        """(faces (m, 3) int64) for a primitive, or None for points/lines."""
        mode = prim.get("mode", 4)
        nverts = self.doc["accessors"][prim["attributes"]["POSITION"]]["count"]
        idx = (self.accessor(prim["indices"]).reshape(-1) if "indices" in prim
               else np.arange(nverts, dtype=np.int64))
        if mode == 4:
            return idx[: len(idx) // 3 * 3].reshape(-1, 3)
        if mode == 5:  # strip
            if len(idx) < 3:
                return np.zeros((0, 3), np.int64)
            k = np.arange(len(idx) - 2)
            even = (k % 2) == 0
            a, b, c = idx[k], idx[k + 1], idx[k + 2]
            return np.stack([a, np.where(even, b, c), np.where(even, c, b)], axis=1)
        if mode == 6:  # fan
            if len(idx) < 3:
                return np.zeros((0, 3), np.int64)
            k = np.arange(1, len(idx) - 1)
            return np.stack([np.full_like(k, idx[0]), idx[k], idx[k + 1]], axis=1)
        return None

    def instances(self, node: dict, world: np.ndarray) -> np.ndarray:
        """The node's world matrices (k, 4, 4): one, or with EXT_mesh_gpu_instancing one per
        instance (world @ the instance's translation, rotation and scale)."""
        ext = gltf_ext.instancing_of(node)
        if ext is None:
            return world[None]
        attrs = gltf_ext.instance_attributes(ext)
        mats = np.tile(np.eye(4), (self._placements(node), 1, 1))
        if "ROTATION" in attrs:
            from scipy.spatial.transform import Rotation

            q = self.accessor(attrs["ROTATION"])
            if not np.all(np.einsum("ij,ij->i", q, q) > 1e-12):
                raise EnvironmentLoadError("corrupt glTF: EXT_mesh_gpu_instancing has a zero "
                                           "rotation", where=str(self.path))
            mats[:, :3, :3] = Rotation.from_quat(q).as_matrix()
        if "SCALE" in attrs:
            mats[:, :3, :3] *= self.accessor(attrs["SCALE"])[:, None, :]
        if "TRANSLATION" in attrs:
            mats[:, :3, 3] = self.accessor(attrs["TRANSLATION"])
        return world @ mats

    def _placements(self, node: dict) -> int:
        """How many times a node places its mesh: 1, or its EXT_mesh_gpu_instancing count."""
        ext = gltf_ext.instancing_of(node)
        if ext is None:
            return 1
        return self.doc["accessors"][next(iter(gltf_ext.instance_attributes(ext).values()))][
            "count"]

    def _primitive(self, mi: int, pi: int, prim: dict):
        """A primitive's local (points, triangles, normals or None), or None for points and
        lines."""
        draco = gltf_ext.draco_of(prim)
        if draco is not None and prim.get("mode", 4) in (4, 5, 6):
            if (mi, pi) not in self._decoded:       # once, however often the mesh is placed
                w = f"meshes[{mi}].primitives[{pi}]"
                points, faces = gltf_ext.decode_draco(self.view(draco["bufferView"]), draco, w)
                self._check_decoded(prim, len(points), faces.size, w)
                self._decoded[(mi, pi)] = points, faces
            points, faces = self._decoded[(mi, pi)]
            return points, faces, None
        faces = self.triangles(prim)
        if faces is None:
            return None
        attrs = prim["attributes"]
        normals = self.accessor(attrs["NORMAL"]) if "NORMAL" in attrs else None
        return self.accessor(attrs["POSITION"]), faces, normals

    def _check_decoded(self, prim: dict, points: int, corners: int, where: str) -> None:
        """A Draco primitive must decode to what its accessors declare (the placement bounds
        were counted from them)."""
        acc = self.doc["accessors"]
        declared = (acc[prim["attributes"]["POSITION"]]["count"],
                    acc[prim["indices"]]["count"] if "indices" in prim else corners)
        if (points, corners) != declared:
            raise EnvironmentLoadError(
                f"corrupt glTF: {where}'s Draco data decodes to {points:,} points and {corners:,} "
                f"triangle corners; its accessors declare {declared[0]:,} and {declared[1]:,}",
                where=str(self.path))

    def _mesh_entries(self, node: dict, world: np.ndarray) -> list:
        """The raw entries (name, world vertices, triangles, normals, colour, roughness,
        metalness) of a node's mesh, every instance of it in one entry per primitive."""
        mats = self.instances(node, world)
        mesh = self.doc["meshes"][node["mesh"]]
        base = node.get("name") or mesh.get("name") or f"mesh_{node['mesh']}"
        prims = mesh.get("primitives", [])
        out = []
        for pi, prim in enumerate(prims):
            if "POSITION" not in prim.get("attributes", {}):
                continue
            got = self._primitive(node["mesh"], pi, prim)
            if got is None:
                continue
            points, faces, normals = got      # (sizes checked by _check_size before reading)
            place = mats
            if gltf_pose.needs_pose(node, mesh):    # skinned or morphed: as engines draw it
                self._poser = self._poser or gltf_pose.Poser(self)
                points, normals, skinned = self._poser.pose(
                    node, mesh, prim, points, normals, f"meshes[{node['mesh']}].primitives[{pi}]")
                if skinned:                 # the joints placed it: the node's transform is not used
                    place = self.instances(node, np.eye(4))
            color, rough, metal = self.material(prim.get("material"))
            out.append((base if len(prims) == 1 else f"{base}_{pi}",
                        *_placed(place, points, faces, normals), color, rough, metal))
        return out

    def _mesh_size(self, mi: int) -> tuple[int, int]:
        """meshes[mi]'s (triangles, vertices), from its accessors' counts (no data read)."""
        acc, tris, verts = self.doc["accessors"], 0, 0
        for prim in self.doc["meshes"][mi].get("primitives", []):
            attrs = prim.get("attributes", {})
            if "POSITION" not in attrs or prim.get("mode", 4) not in (4, 5, 6):
                continue
            c = acc[prim["indices"] if "indices" in prim else attrs["POSITION"]]["count"]
            tris += c // 3 if prim.get("mode", 4) == 4 else max(c - 2, 0)
            verts += acc[attrs["POSITION"]]["count"]
        return tris, verts

    def _check_size(self) -> None:
        """Refuse a scene whose placed meshes add up to more than MAX_TRIANGLES, before any
        of them is read (a small file can place a big mesh thousands of times)."""
        nodes, per_mesh = self.doc.get("nodes", []), {}
        total = vertices = placements = 0
        for ni, _ in self.world_nodes(matrices=False):
            node = nodes[ni]
            if "mesh" in node:
                mi = node["mesh"]
                if mi not in per_mesh:
                    per_mesh[mi] = self._mesh_size(mi)
                k = self._placements(node)
                placements += k
                total += per_mesh[mi][0] * k
                vertices += per_mesh[mi][1] * k
        if total > MAX_TRIANGLES or vertices > MAX_VERTICES or placements > MAX_MESHES:
            raise EnvironmentLoadError(
                f"the level places {total:,} triangles and {vertices:,} vertices ({placements:,} "
                f"mesh placements); a bake takes at most {MAX_TRIANGLES:,} triangles, "
                f"{MAX_VERTICES:,} vertices and {MAX_MESHES:,} placements: keep the part of the "
                "level the creature uses", where=str(self.path))

    def read(self):
        self._check_size()
        doc = self.doc
        nodes = doc.get("nodes", [])
        lights = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
        raw, suns = [], []
        for ni, world in self.world_nodes():
            node = nodes[ni]
            light_ref = node.get("extensions", {}).get("KHR_lights_punctual")
            if light_ref is not None:
                light = lights[light_ref["light"]]
                if light.get("type") == "directional":
                    d = light_direction(world)
                    if d is not None:
                        suns.append(Sun(direction=d,
                                        intensity=float(light.get("intensity", 1.0)),
                                        color=tuple(float(c) for c in
                                                    light.get("color", [1.0, 1.0, 1.0])),
                                        azimuth_rate=_azimuth_rate(light)))
            if "mesh" in node:
                raw += self._mesh_entries(node, world)
        sun = max(suns, key=lambda s: s.intensity) if suns else None
        return raw, sun


def _read_gltf(path: Path):
    data = path.read_bytes()
    if path.suffix.lower() == ".glb" or data[:4] == b"glTF":
        doc, bin_chunk = _parse_glb(data, path)
    else:
        try:
            doc, bin_chunk = json.loads(data.decode("utf-8-sig")), None    # (a BOM passed)
        except (UnicodeDecodeError, ValueError) as e:
            raise EnvironmentLoadError(f"corrupt glTF: not UTF-8 JSON ({_error_text(e)})",
                                       where=str(path)) from None
    return _GltfReader(doc, bin_chunk, path, file_size=len(data)).read()


# --------------------------------------------------------------------------- OBJ / PLY / STL
def _trimesh_color(geom) -> tuple[float, float, float, float]:
    vis = getattr(geom, "visual", None)
    if vis is None:
        return DEFAULT_COLOR
    if vis.kind == "texture":
        mat = getattr(vis, "material", None)
        c = getattr(mat, "baseColorFactor", None)
        if c is None:
            c = getattr(mat, "diffuse", None)
        if c is not None:
            c = np.asarray(c, dtype=np.float64).reshape(-1)
            if c.max() > 1.0:  # trimesh stores material colours as bytes
                c = c / 255.0
            if len(c) == 3:
                c = np.append(c, 1.0)
            return tuple(float(x) for x in np.clip(c[:4], 0, 1))
        return DEFAULT_COLOR
    if vis.kind in ("vertex", "face") and getattr(vis, "defined", False):
        cols = vis.vertex_colors if vis.kind == "vertex" else vis.face_colors
        return _linear_colour(np.asarray(cols, dtype=np.float64).mean(axis=0))
    return DEFAULT_COLOR


def _linear_colour(rgba) -> tuple[float, float, float, float]:
    """An sRGB colour of bytes (r, g, b, a) as linear RGB and alpha from 0 to 1."""
    mean = np.asarray(rgba, dtype=np.float64) / 255.0
    rgb = _srgb_to_linear(mean[:3])
    return (float(rgb[0]), float(rgb[1]), float(rgb[2]), float(mean[3]))


def _to_utf8(data: bytes) -> bytes:
    """Text in any common encoding as UTF-8: UTF-8 (with or without a BOM) as it is, else
    Latin-1 (every byte is a character; the numbers and keywords these formats need are ASCII)."""
    if data.startswith(b"\xef\xbb\xbf"):
        return data[3:]
    try:
        data.decode("utf-8")
        return data
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")


def _text_as_utf8(path: Path, data: bytes) -> bytes:
    """The file's bytes with its text parts re-encoded as UTF-8 (trimesh decodes text as
    UTF-8): a whole OBJ or ASCII STL, the header of a PLY (and its body when ASCII)."""
    ext = path.suffix.lower()
    if ext == ".obj":
        return _to_utf8(data)
    if ext == ".stl":
        if _binary_stl_size(data, len(data)):
            return data
        if data.lstrip()[:5].lower() == b"solid":
            return _to_utf8(data)
        # (a binary STL whose size is not its count's was refused unread: _check_stl_size)
        raise EnvironmentLoadError("corrupt STL: neither ASCII ('solid ...') nor binary")
    if ext == ".ply":
        end = data.find(b"end_header")
        if end < 0:
            return data
        nl = data.find(b"\n", end)
        cut = len(data) if nl < 0 else nl + 1
        header = data[:cut]
        if b"format ascii" in header:
            return _to_utf8(data)
        return _to_utf8(header) + data[cut:]
    return data


#: an OBJ's material library or texture over this size is read as missing (the bake takes only
#: the materials' colours)
MAX_SIDE_FILE_BYTES = 256 << 20


def _folder_resolver(path: Path):
    """trimesh resolver for the files an OBJ refers to (material libraries, textures): only
    inside the environment's folder (trimesh's own rule), material text re-encoded as UTF-8."""
    from trimesh.resolvers import FilePathResolver

    class _Resolver(FilePathResolver):
        def get(self, name: str):
            # trimesh reads the first of these that exists: a FIFO, a device or a folder is
            # never read (a FIFO's open blocks until a writer comes) but missing
            for candidate in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
                try:
                    found = self.absolute(candidate)
                except ValueError:
                    continue
                if found.exists():
                    if not found.is_file():
                        raise FileNotFoundError(name)
                    if found.stat().st_size > MAX_SIDE_FILE_BYTES:   # read as missing
                        log.warning("environment %s: %s is over %d MB; read as missing",
                                    path, found.name, MAX_SIDE_FILE_BYTES >> 20)
                        raise FileNotFoundError(name)
                    break
            data = super().get(name)
            return _to_utf8(data) if str(name).lower().endswith(".mtl") else data

    return _Resolver(str(path))


_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]+(.*)$", re.M)
_OBJ_VERTEX = re.compile(rb"^[ \t]*v[ \t]+(.*)$", re.M)


#: a backslash ending a line, before the line break (the statement goes on on the next line)
_OBJ_CONTINUED = re.compile(rb"\\[ \t]*\r?\n")


def _obj_lines(data: bytes) -> bytes:
    """An OBJ's lines as the format writes them, as the rest of the reading takes them: a
    line ended by a lone carriage return (classic Mac OS) ended by a line feed, and a line
    ending in a backslash joined to the next (the format's continuation: `v 1 2 \\` then
    `3`), an empty line left in its place so that line numbers stay. A comment's backslash
    continues nothing (a Windows path at the end of a comment: it is dropped, trimesh would
    join the next line to the comment). A CR-only file was read as one line and refused, and
    a continued vertex as one of two coordinates."""
    if b"\r" in data:
        data = re.sub(rb"\r(?!\n)", b"\n", data)
    if not _OBJ_CONTINUED.search(data):
        return data
    out, parts = [], []             # the lines done; the parts of the statement read
    for line in data.split(b"\n"):
        body = line.rstrip(b" \t\r")
        if body.endswith(b"\\"):
            if (parts or [line])[0].lstrip().startswith(b"#"):
                line = body[:-1]        # (trimesh would join the next line to the comment)
            else:
                parts.append(body[:-1])
                continue
        out.append(b" ".join(parts + [line]))
        out.extend([b""] * len(parts))
        parts = []
    if parts:
        out.append(b" ".join(parts))
        out.extend([b""] * (len(parts) - 1))
    return b"\n".join(out)


#: a comment after the fields of a geometry statement ("v 1 2 3 # top")
_OBJ_TRAILING_COMMENT = re.compile(rb"^((?:v|vt|vn|vp|f|l|p) [^#\n]*?) *#[^\n]*$", re.M)


def _obj_spaces(data: bytes) -> bytes:
    """An OBJ's whitespace and comments as trimesh reads them: tabs (which the format allows
    between fields) as spaces, no indentation (trimesh skips an indented `f` line and reads
    tabbed `v` lines wrong), no comment after a statement's fields (trimesh reads it as
    numbers)."""
    if b"\t" in data:
        data = data.replace(b"\t", b" ")
    if re.search(rb"^ ", data, re.M):
        data = re.sub(rb"^ +", b"", data, flags=re.M)
    if b"#" in data:
        data = _OBJ_TRAILING_COMMENT.sub(rb"\1", data)
    return data


def _check_obj(data: bytes) -> None:
    """OBJ structure trimesh lets through silently: a vertex with fewer than 3 coordinates, a
    face index of 0 (OBJ counts from 1) or beyond the vertex list (negative: relative)."""
    starts = []                     # where each vertex is defined
    for m in _OBJ_VERTEX.finditer(data):
        starts.append(m.start())
        if len(m.group(1).split(b"#", 1)[0].split()) < 3:
            line = data.count(b"\n", 0, m.start()) + 1
            raise EnvironmentLoadError(f"OBJ line {line}: a vertex needs 3 coordinates")
    nverts = len(starts)
    for m in _OBJ_FACE.finditer(data):
        for tok in m.group(1).split(b"#", 1)[0].split():
            head = tok.split(b"/", 1)[0]
            try:
                k = int(head)
            except ValueError:
                line = data.count(b"\n", 0, m.start()) + 1
                raise EnvironmentLoadError(
                    f"OBJ line {line}: face index '{head[:20].decode('latin-1')}' is not an "
                    "integer") from None
            before = nverts if k > 0 else bisect.bisect_left(starts, m.start())
            if k == 0 or abs(k) > before:
                line = data.count(b"\n", 0, m.start()) + 1
                raise EnvironmentLoadError(
                    f"OBJ line {line}: face index {k} outside the {before} vertices " + (
                        "(OBJ indices count from 1)" if k >= 0 else
                        "defined before it (a negative index counts back from the last)"))


#: a face with a negative (relative) index
_OBJ_RELATIVE = re.compile(rb"^f [^\n]*[ /]-[0-9]", re.M)
#: the statements a face's v/vt/vn indices count
_OBJ_KINDS = (b"v", b"vt", b"vn")


def _obj_absolute(data: bytes) -> bytes:
    """An OBJ (as _obj_spaces leaves it) with its negative face indices made absolute. OBJ
    counts -1 as the last vertex (texture coordinate, normal) defined before the face; trimesh
    counts from the end of the file, so a file whose objects each end in `f -3 -2 -1` read as
    one triangle, the last object's, placed once per object."""
    if not _OBJ_RELATIVE.search(data):
        return data
    counts = dict.fromkeys(_OBJ_KINDS, 0)
    lines = data.split(b"\n")
    for i, line in enumerate(lines):
        key = line.split(b" ", 1)[0]
        if key in counts:
            counts[key] += 1
        elif key == b"f" and b"-" in line:
            body = line.rstrip(b"\r")
            fields = [b"/".join(_obj_index(c, counts[kind])
                                for c, kind in zip(tok.split(b"/"), _OBJ_KINDS))
                      for tok in body.split(b" ")[1:] if tok]
            lines[i] = b"f " + b" ".join(fields) + line[len(body):]
    return b"\n".join(lines)


#: a face of four or more corners, its fields (group 1) and line end (group 2)
_OBJ_POLYGON = re.compile(rb"^f +([^ \r\n]+ +[^ \r\n]+ +[^ \r\n]+ +[^ \r\n][^\r\n]*?) *(\r?)$",
                          re.M)
#: a vertex's position (the first three numbers of a `v` statement)
_OBJ_POSITION = re.compile(rb"^v +([^ \r\n]+ +[^ \r\n]+ +[^ \r\n]+)", re.M)


def _obj_cut(data: bytes) -> bytes:
    """An OBJ (as _obj_absolute leaves it) with each concave polygon written as the triangles
    geometry.polygons cuts it into, on lines of their own in its place: trimesh fans every
    polygon from its first corner, which covers a concave one wrongly (an L-shaped floor got a
    triangle over its notch, wound the other way). Convex polygons stay as they are."""
    bodies = [b for b, _ in _OBJ_POLYGON.findall(data)]
    if not bodies:
        return data
    # each polygon's corner count, vertex numbers (before any '/') and the positions, each
    # parsed in one call
    text = re.sub(rb"  +", b" ", b"\n".join(bodies))
    chars = np.frombuffer(text, dtype=np.uint8)
    gaps = np.cumsum(chars == 32)[np.flatnonzero(chars == 10)]
    counts = np.diff(np.concatenate([[0], gaps, [np.count_nonzero(chars == 32)]])) + 1
    try:
        idx = np.array(re.sub(rb"/[^ \n]*", b"", text).split(), dtype=np.int64) - 1
        points = np.array(b" ".join(_OBJ_POSITION.findall(data)).split(),
                          dtype=np.float64).reshape(-1, 3)
    except ValueError:
        return data                     # not numbers: trimesh's reading says so
    if len(idx) != counts.sum() or idx.min() < 0 or idx.max() >= len(points):
        return data
    bent = set(np.flatnonzero(polygons.concave(points, counts, idx)).tolist())
    if not bent:
        return data
    starts = np.cumsum(counts) - counts
    out, at = [], 0
    for k, m in enumerate(_OBJ_POLYGON.finditer(data)):
        if k not in bent:
            continue
        corners = idx[starts[k]:starts[k] + counts[k]]
        tri = polygons.triangulate(points, counts[k:k + 1], corners, np.ones(1, bool))
        token = dict(zip(corners.tolist(), m.group(1).split()))
        out += [data[at:m.start()], b"\n".join(
            b"f " + b" ".join(token[v] for v in t) + m.group(2) for t in tri.tolist())]
        at = m.end()
    return b"".join(out + [data[at:]])


def _obj_index(field: bytes, defined: int) -> bytes:
    """A face's index field made absolute (`defined`: how many of its kind come before)."""
    return str(defined + int(field) + 1).encode() if field.startswith(b"-") else field


def _obj_split(data: bytes) -> bool:
    """Whether an OBJ's objects (`o`) are read as meshes of their own, as Blender imports them
    (trimesh merges them into the first's: a `navmesh` or UCX_ object was walked on): when it
    has 2 to MERGE_ABOVE of them (more are merged again, by material), or a helper among
    more (HELPER_NAME; trimesh takes about half a millisecond an object)."""
    names = re.findall(rb"(?m)^[ \t]*o[ \t]+([^\r\n]*)", data)
    if len(names) < 2:
        return False
    return len(names) <= MERGE_ABOVE or any(
        HELPER_NAME.search(n.strip().decode("utf-8", "replace")) for n in names)


def _ply_lists(geom, element: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(counts (m,) int64, items (sum counts,) of the type the file declares) of a PLY mesh's
    `element` list (vertex_indices or vertex_index) as trimesh read it (it keeps the file's
    elements in metadata['_ply_raw']); None when there is none (or the mesh is no PLY)."""
    raw = (getattr(geom, "metadata", None) or {}).get("_ply_raw", {}).get(element, {})
    rows = raw.get("data") if isinstance(raw, dict) else None
    names = (rows.dtype.names or ()) if isinstance(rows, np.ndarray) else tuple(rows or ())
    key = next((k for k in ("vertex_indices", "vertex_index") if k in names), None)
    if key is None:
        return None
    lists = rows[key]
    if isinstance(lists, np.ndarray) and lists.dtype.names:     # binary: (count, items)
        lists = lists[lists.dtype.names[-1]]
    if len(lists) == 0:
        return None
    try:
        if isinstance(lists, np.ndarray) and lists.dtype != object and lists.ndim == 2:
            counts = np.full(len(lists), lists.shape[1], dtype=np.int64)
            return counts, lists.reshape(-1)
        counts = np.array([len(x) for x in lists], dtype=np.int64)
        return counts, np.concatenate([np.asarray(x).reshape(-1) for x in lists])
    except (TypeError, ValueError):
        return None


def _ply_strips(geom) -> np.ndarray | None:
    """The triangles (T, 3) of a PLY mesh's `tristrips` element (environment.ply), None when
    it has none; its face and strip lists checked (a float list's 2.5 was cut to 2)."""
    from baker.environment import ply

    n = len(getattr(geom, "vertices", ()))
    face = _ply_lists(geom, "face")
    if face is not None and face[1].dtype.kind == "f":
        ply.list_indices("face", *face, n)
    strips = _ply_lists(geom, "tristrips")
    if strips is None:
        return None
    return ply.strip_triangles(strips[0], ply.list_indices("tristrips", *strips, n, strips=True))


def _ply_cut(geom) -> np.ndarray | None:
    """A PLY mesh's faces (T, 3) triangulated afresh (geometry.polygons) when the file has a
    concave polygon, which trimesh fans from its first corner; None otherwise (and for any
    other mesh). trimesh keeps the file's faces as read in metadata['_ply_raw']."""
    lists = _ply_lists(geom, "face")
    if lists is None:
        return None
    counts, flat = lists
    if flat.dtype.kind not in "iuf":
        return None
    flat = flat.astype(np.int64)        # (a float list's were checked whole: _ply_strips)
    points = np.asarray(geom.vertices, dtype=np.float64)
    if counts.max() < 4 or counts.min() < 3 or flat.min() < 0 or flat.max() >= len(points):
        return None
    bent = polygons.concave(points, counts, flat)
    return polygons.triangulate(points, counts, flat, bent) if bent.any() else None


def _ragged_ply(path: Path, data: bytes) -> tuple:
    """The raw mesh entry of a binary PLY whose faces vary in size (environment.ply reads it;
    trimesh cannot), triangulated by geometry.polygons, its vertices merged as trimesh merges
    a mesh it loads."""
    import trimesh

    from baker.environment import ply

    v, counts, flat, rgba = ply.read(data)       # (indices checked inside the vertices)
    keep = np.repeat(counts >= 3, counts)
    counts, flat = counts[counts >= 3], flat[keep]
    faces = polygons.triangulate(v, counts, flat) if len(counts) else np.zeros((0, 3), np.int64)
    _check_geometry(v, faces, path.stem)
    geom = trimesh.Trimesh(v, faces, process=False)
    geom.process()
    color = DEFAULT_COLOR if rgba is None else _linear_colour(rgba)
    return (path.stem, np.asarray(geom.vertices, dtype=np.float64),
            np.asarray(geom.faces, dtype=np.int64), None, color, 1.0, 0.0)


def _binary_ply_ragged(data: bytes) -> bool:
    """Whether a PLY is binary with a `tristrips` element (strips vary in length) or with list
    rows of more than one length (faces of mixed sizes: environment.ply.uniform_lists). trimesh
    reads every row's list as the first's: such files are read by environment.ply. (A mix whose
    sizes add up to as many bytes as uniform rows did not fail in trimesh: its faces were read
    misaligned, silently where the misread indices fell within the vertices.)"""
    from baker.environment import ply

    end = data.find(b"end_header")
    header = data[:max(end, 0)]
    if b"format binary" not in header:
        return False
    return (re.search(rb"(?m)^element[ \t]+tristrips\b", header) is not None
            or not ply.uniform_lists(data))


def _check_ascii_ply(data: bytes) -> None:
    """A PLY's header must end (end_header); an ASCII PLY's body must hold exactly the values
    its header declares (trimesh reads a short or overlong body without a word)."""
    end = data.find(b"end_header")
    if end < 0:
        raise EnvironmentLoadError("corrupt PLY: its header has no end_header line (the file is "
                                   "cut short, or not a PLY)")
    if b"format ascii" not in data[:end]:
        return
    nl = data.find(b"\n", end)
    header, body = data[:end], (b"" if nl < 0 else data[nl + 1:])
    elements: list[tuple[str, int, list]] = []  # name, count, [list item type or None]
    for line in header.splitlines():
        w = line.split()
        if len(w) >= 3 and w[0] == b"element":
            try:
                n = int(w[2])
            except ValueError:
                raise EnvironmentLoadError(f"PLY element {w[1][:20].decode('latin-1')} has "
                                           "a count that is not an integer") from None
            elements.append((w[1].decode("latin-1")[:20], n, []))
        elif len(w) >= 2 and w[0] == b"property" and elements:
            elements[-1][2].append(w[3] if w[1] == b"list" and len(w) >= 4 else None)
    tokens = body.split()
    i = 0
    for name, count, props in elements:
        if count < 0 or count > len(tokens):
            raise EnvironmentLoadError(f"PLY declares {count:,} {name} elements but its body "
                                       f"has only {len(tokens):,} values")
        if not any(t is not None for t in props):
            i += count * len(props)
        else:
            for row in range(count):
                for item in props:
                    if i >= len(tokens):
                        raise EnvironmentLoadError(
                            f"PLY body ends inside the {name} elements (truncated)")
                    if item is not None:
                        try:
                            n = int(tokens[i])
                        except ValueError:
                            raise EnvironmentLoadError(
                                f"PLY {name} list length '{tokens[i][:20].decode('latin-1')}' "
                                "is not an integer") from None
                        if item not in _PLY_FLOATS:
                            _ply_whole(tokens[i + 1:i + 1 + max(n, 0)], name, row)
                        i += 1 + max(n, 0)
                    else:
                        i += 1
        if i > len(tokens):
            raise EnvironmentLoadError(f"PLY body ends inside the {name} elements (truncated)")
    if i != len(tokens):
        raise EnvironmentLoadError(f"PLY body has {len(tokens) - i:,} values more than its "
                                   "header declares")


_PLY_FLOATS = (b"float", b"float32", b"double", b"float64")


def _ply_whole(items: list, name: str, row: int) -> None:
    """The items of an ASCII PLY list declared of an integer type must be written as integers
    (trimesh read '2.5' as 2, silently)."""
    for t in items:
        if not t.lstrip(b"+-").isdigit():
            raise EnvironmentLoadError(
                f"PLY {name} row {row} has '{t[:20].decode('latin-1')}' in a list of integers")


def _ascii_stl_head(head: bytes) -> bool:
    """Whether an STL's first 84 bytes look like text: 'solid ...' and no NUL (a binary
    header may say "solid" too)."""
    return head.lstrip()[:5].lower() == b"solid" and b"\0" not in head


def _binary_stl_size(head: bytes, size: int) -> bool:
    """Whether a file of `size` bytes starting with `head` (at least its first 84 bytes) has
    a binary STL's size: 84 + 50 times its header's triangle count."""
    return len(head) >= 84 and size == 84 + 50 * struct.unpack_from("<I", head, 80)[0]


def _check_stl_size(path: Path) -> None:
    """A binary STL whose size is not its header's triangle count's, refused from its first
    84 bytes and its size (before a sparse 4 GB file is read whole)."""
    with open(path, "rb") as f:
        head = f.read(84)
        size = os.fstat(f.fileno()).st_size
    if len(head) < 84 or _ascii_stl_head(head):
        return          # short or ASCII
    (n,) = struct.unpack_from("<I", head, 80)
    if size != 84 + 50 * n:
        raise EnvironmentLoadError(
            f"corrupt binary STL: its header says {n:,} triangles ({84 + 50 * n:,} bytes) but "
            f"the file has {size:,} bytes")


def _ascii_stl(data: bytes) -> bool:
    """Whether an STL file's bytes are ASCII STL (a binary one's header may say "solid")."""
    return _ascii_stl_head(data[:84]) and not _binary_stl_size(data, len(data))


def _stl_line_ends(data: bytes) -> bytes:
    """An ASCII STL whose lines end in a lone CR (classic Mac OS) with LF line ends (it was
    refused as cut short: no line started with endsolid); other files as they are."""
    return re.sub(rb"\r(?!\n)", b"\n", data) if b"\r" in data else data


#: a number in an ASCII STL (nan and inf too: the geometry check names them)
_STL_NUMBER = rb"[-+]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|nan|inf(?:inity)?)"
#: a `vertex` line without exactly three numbers
_STL_BAD_VERTEX = re.compile(rb"(?im)^[ \t]*vertex\b(?![ \t]+%s[ \t]+%s[ \t]+%s[ \t]*\r?$)"
                             rb"([^\r\n]{0,60})" % ((_STL_NUMBER,) * 3))


def _check_ascii_stl(data: bytes) -> None:
    """An ASCII STL must end (endsolid), each facet hold 3 vertices (trimesh read a cut-off
    file as no faces and refused a facet of 2 or 4 with 'cannot reshape array') and each
    vertex line 3 numbers (trimesh read the numbers of all in a row: lines of 2, 3 and 4
    numbers made a wrong triangle)."""
    if not re.search(rb"(?im)^[ \t]*endsolid", data):
        raise EnvironmentLoadError("corrupt ASCII STL: cut short (no endsolid line)")
    bad = _STL_BAD_VERTEX.search(data)
    if bad:
        line = data.count(b"\n", 0, bad.start()) + 1
        raise EnvironmentLoadError(f"corrupt ASCII STL: line {line} is 'vertex"
                                   f"{bad[1].decode('utf-8', 'replace').rstrip()}' (a vertex "
                                   "is 3 numbers)")
    ends = np.array([m.start() for m in re.finditer(rb"(?im)^[ \t]*endfacet\b", data)],
                    np.int64)
    verts = np.array([m.start() for m in re.finditer(rb"(?im)^[ \t]*vertex\b", data)],
                     np.int64)
    per = np.diff(np.concatenate([[0], np.searchsorted(verts, ends)]))
    bad = np.flatnonzero(per != 3)
    if len(bad):
        raise EnvironmentLoadError(f"corrupt ASCII STL: facet {int(bad[0]) + 1} has "
                                   f"{int(per[bad[0]])} vertices (a facet is a triangle: 3)")


#: a control byte put inside the keywords of an ASCII STL solid's name so that trimesh's reader
#: does not take them for its own, and taken out of the names it reads (a file that holds this
#: byte already is read as it is)
_STL_MARK = b"\x1f"


def _stl_hide_keywords(data: bytes) -> bytes:
    """An ASCII STL with the words trimesh's reader searches the whole text for ("vertex",
    "normal", "solid", so "endsolid") broken by _STL_MARK where they appear in a `solid` or
    `endsolid` line's name: `solid vertex_paint` was read as a vertex, `solid a endsolid` as
    the solid's end, `endsolid floor_solid` as the next solid's start (which lost its name)."""
    if _STL_MARK in data:
        return data
    words = re.compile(rb"(?i)vertex|normal|solid")

    def hide(m):
        return m.group(1) + words.sub(lambda w: w[0][:3] + _STL_MARK + w[0][3:], m.group(2))

    return re.sub(rb"(?im)^([ \t]*(?:end)?solid)([^\r\n]*)", hide, data)


def _read_trimesh(path: Path):
    import io

    import trimesh

    if path.suffix.lower() == ".stl":
        _check_stl_size(path)
    data = path.read_bytes()
    # an ASCII STL (a binary one's header may say "solid" too), told once
    stl_text = path.suffix.lower() == ".stl" and _ascii_stl(data)
    if stl_text:
        data = _stl_line_ends(data)
        _check_ascii_stl(data)
    if path.suffix.lower() == ".obj" and b"\x00" in data[: 1 << 16]:
        raise EnvironmentLoadError("corrupt OBJ: binary data in a text format", where=str(path))
    if path.suffix.lower() == ".obj":
        data = _obj_lines(data)
        _check_obj(data)
    if path.suffix.lower() == ".ply":
        _check_ascii_ply(data)
    data = _text_as_utf8(path, data)
    if path.suffix.lower() == ".obj":
        data = _obj_cut(_obj_absolute(_obj_spaces(data)))
    if stl_text:
        data = _stl_hide_keywords(data)
    if path.suffix.lower() == ".ply" and _binary_ply_ragged(data):
        return [_ragged_ply(path, data)], None      # lists vary in length: trimesh cannot
    try:
        split = {"split_objects": True} if path.suffix.lower() == ".obj" and _obj_split(
            data) else {}
        scene = trimesh.load_scene(io.BytesIO(data), file_type=path.suffix.lower()[1:],
                                   resolver=_folder_resolver(path), process=False, **split)
    except ValueError as exc:
        if path.suffix.lower() != ".ply" or "unexpected length" not in str(exc):
            raise
        return [_ragged_ply(path, data)], None      # trimesh takes every row's list as the first's
    raw = []
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry[geom_name]
        faces, strips = getattr(geom, "faces", None), _ply_strips(geom)
        if strips is not None:  # (a PLY of strips alone is a PointCloud to trimesh)
            faces = strips if faces is None else np.concatenate(
                [np.asarray(faces, dtype=np.int64).reshape(-1, 3), strips])
        if faces is None or len(faces) == 0:  # PointCloud, Path3D, empty mesh
            continue
        _check_geometry(np.asarray(geom.vertices, dtype=np.float64),
                        np.asarray(faces, dtype=np.int64),
                        str(geom_name).replace(_STL_MARK.decode(), ""))
        color, cut = None, _ply_cut(geom)
        if cut is not None:
            faces = cut if strips is None else np.concatenate([cut, strips])
        if cut is not None or strips is not None:   # a new mesh: the file's face colours do
            color = _trimesh_color(geom)            # not fit its faces
            geom = trimesh.Trimesh(geom.vertices, faces, process=False)
        geom.process()  # merge vertices as trimesh does on load (solids are found by them)
        m = np.asarray(transform, dtype=np.float64)
        v = _transform_points(m, np.asarray(geom.vertices, dtype=np.float64))
        f = _fix_winding(np.asarray(geom.faces, dtype=np.int64), m)
        name = node if node != path.name else (geom_name if geom_name != path.name else path.stem)
        name = name.replace(_STL_MARK.decode(), "")
        raw.append((name, v, f, None, color or _trimesh_color(geom), 1.0, 0.0))
    return raw, None


# --------------------------------------------------------------------------- USD
def _usd_matrix(gf_matrix) -> np.ndarray:
    """Gf.Matrix4d (row-vector convention) -> (4, 4) column-vector numpy matrix."""
    return np.array(gf_matrix, dtype=np.float64).reshape(4, 4).T


def _usd_light(light, time, path) -> tuple[float, tuple[float, float, float]]:
    """(intensity x 2^exposure, linear RGB colour) of a UsdLux light: a finite intensity of at
    least 0 and colour components from 0 to 1 (the ranges the glTF writer stores; a brighter
    colour is clamped to 1), else a one-line error naming the light."""
    inten = light.GetIntensityAttr().Get(time)
    expo = light.GetExposureAttr().Get(time) or 0.0
    col = light.GetColorAttr().Get(time)
    try:
        inten = float(inten if inten is not None else 1.0) * 2.0 ** float(expo)
    except OverflowError:   # (an exposure of 1e30 said 'Numerical result out of range')
        inten = math.inf
    color = tuple(float(c) for c in col) if col is not None else (1.0, 1.0, 1.0)
    if not (math.isfinite(inten) and inten >= 0.0) or not all(
            math.isfinite(c) and c >= 0.0 for c in color):
        raise EnvironmentLoadError(
            f"light {light.GetPath()}: intensity {inten:g} and colour {color} must be finite, "
            "at least 0", where=str(path))
    return inten, tuple(min(c, 1.0) for c in color)


def _usd_color(prim, mesh, time):
    """A mesh's (base colour RGBA, roughness, metalness) from its bound UsdPreviewSurface, else
    its displayColor; a value of the wrong type or shape (a float diffuseColor, a float[]
    displayColor) counts as unauthored: the colour is cosmetic, the level still loads."""
    try:
        return _usd_color_authored(prim, mesh, time)
    except (TypeError, ValueError, IndexError):
        log.info("USD mesh %s: its colour is not a colour; the default is used", prim.GetPath())
        return DEFAULT_COLOR, 1.0, 0.0


def _usd_color_authored(prim, mesh, time):
    from pxr import UsdShade

    rough, metal = 1.0, 0.0
    try:
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    except Exception:  # pragma: no cover - malformed binding
        material = None
    if material:
        output = material.GetSurfaceOutput()
        source = output.GetConnectedSources()[0] if output else []
        for src in source:
            shader = UsdShade.Shader(src.source.GetPrim())
            if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
                continue
            diff = shader.GetInput("diffuseColor")
            opac = shader.GetInput("opacity")
            r_in, m_in = shader.GetInput("roughness"), shader.GetInput("metallic")
            if r_in and r_in.Get() is not None:
                rough = float(r_in.Get())
            if m_in and m_in.Get() is not None:
                metal = float(m_in.Get())
            if diff and not diff.HasConnectedSource() and diff.Get() is not None:
                c = [float(x) for x in diff.Get()]
                a = float(opac.Get()) if opac and opac.Get() is not None else 1.0
                return (c[0], c[1], c[2], a), rough, metal
    pv = mesh.GetDisplayColorPrimvar()
    if pv and pv.HasValue():
        vals = pv.ComputeFlattened(time)
        if vals is not None and len(vals):
            c = np.asarray(vals, dtype=np.float64).reshape(-1, 3).mean(axis=0)
            alpha = 1.0
            op = mesh.GetDisplayOpacityPrimvar()
            if op and op.HasValue():
                ov = op.ComputeFlattened(time)
                if ov is not None and len(ov):
                    alpha = float(np.mean(np.asarray(ov, dtype=np.float64)))
            return (float(c[0]), float(c[1]), float(c[2]), alpha), rough, metal
    return DEFAULT_COLOR, rough, metal


def _usd_triangles(points: np.ndarray, counts: np.ndarray, indices: np.ndarray,
                   holes: np.ndarray, left_handed: bool) -> np.ndarray:
    """A UsdGeom.Mesh's faces as triangles (geometry.polygons: concave ones ear-cut), holes and
    faces of fewer than 3 corners left out, wound counter-clockwise."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if len(counts) == 0 or counts.sum() != len(indices) or np.any(counts < 0):
        raise ValueError("faceVertexCounts do not match faceVertexIndices")
    keep = counts >= 3
    if len(holes):
        h = np.asarray(holes, dtype=np.int64)
        keep[h[(h >= 0) & (h < len(counts))]] = False
    corners = np.repeat(keep, counts)
    counts, indices = counts[keep], indices[corners]
    if len(indices) and (indices.min() < 0 or indices.max() >= len(points)):
        tris = polygons.fan(counts, indices)   # out of range: refused by _check_geometry
    else:
        tris = polygons.triangulate(points, counts, indices)
    return tris[:, ::-1] if left_handed else tris


#: most layers (sublayers, references, payloads) a USD environment may compose
_MAX_USD_LAYERS = 1000


#: the deepest nesting of braces a text USD layer may have (prims in prims: a real scene's
#: tree is tens deep). USD's C++ code recurses once per level: on Linux's 8 MB main-thread
#: stack a layer 18,500 prims deep crashed the process (SIGSEGV) listing its dependencies,
#: 20,000-30,000 deep computing transforms, 100,000 deep parsing it. The level is read on a
#: thread of USD_STACK_BYTES (8 times that: some 150,000 levels), so this keeps a margin of 3
MAX_USDA_DEPTH = 50_000


def usda_depth(path: Path, chunk: int = 1 << 24) -> int:
    """The deepest nesting of `{` in a text USD layer (0 for a crate or another file), read
    in chunks (braces in strings count too: an over-estimate)."""
    depth = deepest = 0
    try:
        with open(path, "rb") as f:
            if f.read(5) != b"#usda":
                return 0
            while data := f.read(chunk):
                b = np.frombuffer(data, dtype=np.uint8)
                step = (b == ord("{")).astype(np.int32) - (b == ord("}"))
                if not step.any():
                    continue
                run = np.cumsum(step, dtype=np.int64) + depth
                deepest = max(deepest, int(run.max()))
                depth = int(run[-1])
    except OSError:
        return 0        # (Sdf says what it cannot open)
    return deepest


def _check_usd_layers(path: Path) -> None:
    """Before the stage is composed: every layer the file brings in (sublayers, references,
    payloads, recursively) must be a file inside the environment's folder that opens, or a
    layer inside a .usdz package that is such a file."""
    folder = path.parent.resolve()
    walk_usd_layers(path, lambda layer, name, dep: _usd_dependency(layer, name, dep, folder,
                                                                   path),
                    lambda text: EnvironmentLoadError(text, where=str(path)))


def walk_usd_layers(path: Path, follow, error, must_open: bool = True) -> None:
    """Walk the layers the USD file at `path` brings in (sublayers, references, payloads,
    recursively) before USD composes them: at most _MAX_USD_LAYERS of them, none nesting
    prims deeper than MAX_USDA_DEPTH, each one opening (unless not `must_open`: one that does
    not is then left to Usd.Stage.Open to say). follow(layer, name, dep) is the absolute path
    of a layer's dependency `dep` to walk next (None: not walked), or raises; error(text) is
    the exception raised here."""
    from pxr import Ar, Sdf

    todo, seen = [str(path.resolve())], set()
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        if len(seen) > _MAX_USD_LAYERS:
            raise error(f"USD composes more than {_MAX_USD_LAYERS} layers")
        outer, inner = Ar.SplitPackageRelativePathInner(p)
        name = Path(outer).name + (f"[{inner}]" if inner else "")
        if not inner and usda_depth(Path(outer)) > MAX_USDA_DEPTH:
            raise error(f"USD layer {name} nests more than {MAX_USDA_DEPTH} levels deep (prims "
                        "in prims)")
        try:
            layer = Sdf.Layer.FindOrOpen(p)
        except Exception:           # pxr's Tf.ErrorException
            if must_open:
                raise
            layer = None
        if layer is None:
            if must_open:
                raise error(f"cannot open USD layer {name}")
            continue
        for dep in layer.GetCompositionAssetDependencies():
            dep = str(dep)
            target = follow(layer, name, dep) if dep else None
            if target is not None:
                todo.append(target)


def _usd_dependency(layer, name: str, dep: str, folder: Path, path: Path) -> str:
    """The checked absolute path of a layer's dependency dep (package-relative inside a .usdz:
    the package is then the file checked)."""
    from pxr import Ar

    if "://" in dep or dep.startswith(("@", "anon:")):
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', which is not a "
                                   "file in the environment's folder", where=str(path))
    target = layer.ComputeAbsolutePath(dep)
    if Ar.IsPackageRelativePath(target) and any(
            part == ".." for part in Ar.SplitPackageRelativePathInner(target)[1].split("/")):
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', outside its .usdz "
                                   "package", where=str(path))
    outer = Path(Ar.SplitPackageRelativePathOuter(target)[0])
    if not outer.is_absolute():     # unresolved: a file a package does not hold
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', which does not "
                                   "exist", where=str(path))
    try:
        outer = outer.resolve()
    except (RuntimeError, OSError):     # a loop of symbolic links (ELOOP in Python 3.13)
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', a loop of "
                                   "symbolic links", where=str(path)) from None
    if not outer.is_relative_to(folder):
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', outside the "
                                   "environment's folder", where=str(path))
    if not outer.is_file():     # (a folder or a FIFO said 'which does not exist')
        raise EnvironmentLoadError(f"USD layer {name} refers to '{dep[:80]}', which "
                                   f"{'is not a file' if outer.exists() else 'does not exist'}",
                                   where=str(path))
    return target if Ar.IsPackageRelativePath(target) else str(outer)


#: the smallest unit a USD level may say it is in (metersPerUnit): a nanometre
MIN_METERS_PER_UNIT = 1e-9


#: the stack of the thread a USD level is read on (parallel.on_own_stack): USD's C++ code
#: recurses once per level of prims in prims, 450 bytes a level where it goes deepest
#: (listing a layer's dependencies), so this holds some 150,000 levels; MAX_USDA_DEPTH keeps
#: well below
USD_STACK_BYTES = 64 << 20


def _read_usd(path: Path, up_axis: str | None = None, units: str | None = None):
    """_read_usd_here on a thread with a known stack (USD_STACK_BYTES), nothing of what USD's
    C++ code prints itself reaching stderr (native.held_stderr: held here, so that a bake
    stopped while the thread reads has its error line on stderr)."""
    from baker.parallel import on_own_stack

    with native.held_stderr(str(path)):
        return on_own_stack(USD_STACK_BYTES, _read_usd_here, path, up_axis, units)


def _read_usd_here(path: Path, up_axis: str | None, units: str | None):
    import importlib

    from baker import signals

    for module in ("pxr.Tf", "pxr.Usd", "pxr.UsdGeom"):     # before the test hook's mark
        importlib.import_module(module)

    signals.mark("read:usd")            # (the test hook: a signal lands in the read from here)
    try:
        return _read_usd_marked(path, up_axis, units)
    finally:
        signals.mark("read:usd:done")


def _read_usd_marked(path: Path, up_axis: str | None, units: str | None):
    import traceback

    from pxr import Tf

    # USD reports problems as diagnostics on stderr: trap them, refuse the file on any
    # composition error or error, and print nothing of USD's own
    try:
        with Tf.DiagnosticTrap() as trap:
            try:
                return _read_usd_trapped(path, trap, up_axis, units)
            finally:
                for w in trap.GetWarnings():
                    log.debug("USD warning while reading %s: %s", path, _usd_diagnostic_text(w))
                trap.Clear()  # nothing of USD's own reaches stderr
    except BaseException as e:
        # the stage and its layers are freed here, on the deep stack, not by whoever keeps the
        # error (USD frees a prim tree recursively too)
        traceback.clear_frames(e.__traceback__)
        raise


def _usd_diagnostic_text(d) -> str:
    text = getattr(d, "commentary", None) or str(d)
    return " ".join(str(text).split())


def _check_usd_arrays(prim, points, counts, indices, holes=()) -> None:
    """A mesh's points must be 3-vectors of numbers and its face counts, indices and hole
    indices integers:
    a layer may author them with another type than the schema's (the attribute then still says
    the schema's type; 'invalid literal for int()' was all a string array gave)."""
    for name, value, kinds, width in (("points", points, "fiu", 3),
                                      ("faceVertexCounts", counts, "iu", 0),
                                      ("faceVertexIndices", indices, "iu", 0),
                                      ("holeIndices", holes, "iu", 0)):
        arr = np.asarray(value)
        if name == "holeIndices" and arr.size == 0:
            continue
        if arr.dtype.kind not in kinds or (arr.ndim != 2 or arr.shape[1] != 3 if width else
                                           arr.ndim != 1):
            want = "3-vectors of numbers" if width else "integers"
            got = {"U": "text", "S": "text", "f": "fractional", "b": "true/false", "i": "integer",
                   "u": "integer"}.get(arr.dtype.kind, arr.dtype.name)
            raise EnvironmentLoadError(f"mesh {prim.GetPath()}: {name} holds {got} values of "
                                       f"shape {tuple(arr.shape)}, not {want}")


def _usd_mesh(prim, time):
    """A UsdGeom.Mesh's local (points (n, 3) float64, triangles, colour, roughness,
    metalness), or None when it has no points or faces."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(prim)
    pts = mesh.GetPointsAttr().Get(time)
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    idx = mesh.GetFaceVertexIndicesAttr().Get(time)
    if pts is None or counts is None or idx is None or len(pts) == 0:
        return None
    holes = mesh.GetHoleIndicesAttr().Get(time)
    _check_usd_arrays(prim, pts, counts, idx, holes if holes is not None else ())
    left = mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    faces = _usd_triangles(pts, np.asarray(counts), np.asarray(idx),
                           np.asarray(holes if holes is not None else [], dtype=np.int64), left)
    return (pts, faces, *_usd_color(prim, mesh, time))


def _usd_point_instances(instancer, cache, fix, time, path, depth: int = 0) -> list:
    """The raw entries of a UsdGeom.PointInstancer: each prototype's meshes placed at every
    visible instance of it (the instance transforms include the prototype root's own), one
    entry per prototype mesh. A prototype's own PointInstancers are expanded the same way
    (nested instancing, at most _MAX_INSTANCER_DEPTH deep); its invisible or guide prims are
    not drawn."""
    if depth > _MAX_INSTANCER_DEPTH:
        raise EnvironmentLoadError(f"USD PointInstancers nest more than {_MAX_INSTANCER_DEPTH} "
                                   "deep", where=str(path))
    xforms = instancer.ComputeInstanceTransformsAtTime(time, time)   # masked ids dropped
    protos = instancer.GetPrototypesRel().GetTargets()
    ids = np.asarray(instancer.GetProtoIndicesAttr().Get(time) or [], dtype=np.int64)
    mask = instancer.ComputeMaskAtTime(time)
    if mask:
        ids = ids[np.asarray(mask, dtype=bool)]
    if xforms is None or len(xforms) != len(ids) or (len(ids) and (
            ids.min() < 0 or ids.max() >= len(protos))):
        raise EnvironmentLoadError(f"USD PointInstancer {instancer.GetPath()} has instances "
                                   "without a prototype", where=str(path))
    inst = np.array([_usd_matrix(x) for x in xforms]).reshape(-1, 4, 4)
    base = fix @ _usd_matrix(cache.GetLocalToWorldTransform(instancer.GetPrim()))
    stage, raw = instancer.GetPrim().GetStage(), []
    for p, target in enumerate(protos):
        root = stage.GetPrimAtPath(target)
        mats = base @ inst[ids == p]
        if not root or not len(mats):
            continue
        # the prototype's meshes, in stage space as defined, then moved to every instance
        mats = mats @ np.linalg.inv(_usd_matrix(cache.GetLocalToWorldTransform(root)))
        for name, pts, faces, color, rough, metal in _usd_prototype(root, cache, time, path,
                                                                    depth):
            check_placed(len(mats), len(faces), len(pts), path)
            raw.append((name, *_placed(mats, pts, faces, None), color, rough, metal))
    return raw


#: the deepest nesting of PointInstancers inside prototypes that is expanded
_MAX_INSTANCER_DEPTH = 8


def _usd_prototype(root, cache, time, path, depth: int) -> list:
    """A PointInstancer prototype's meshes in stage space as defined: (name, points, triangles,
    colour, roughness, metalness) each, its own instancers' placements included. Prototypes
    are often kept under an `over` or `class` parent, hidden from ordinary traversals: only
    the instancer draws them, so undefined and abstract prims are read here."""
    from pxr import Usd, UsdGeom

    out = []
    prims = iter(Usd.PrimRange(root, Usd.TraverseInstanceProxies(Usd.PrimIsActive
                                                                 & Usd.PrimIsLoaded)))
    for prim in prims:
        if prim != root and prim.IsA(UsdGeom.Imageable) and (
                UsdGeom.Imageable(prim).GetVisibilityAttr().Get(time) == UsdGeom.Tokens.invisible
                or UsdGeom.Imageable(prim).GetPurposeAttr().Get() == UsdGeom.Tokens.guide):
            prims.PruneChildren()           # hidden below the root: hidden in every instance
            continue
        if prim.IsA(UsdGeom.PointInstancer):
            for name, v, f, _, color, rough, metal in _usd_point_instances(
                    UsdGeom.PointInstancer(prim), cache, np.eye(4), time, path, depth + 1):
                out.append((name, v, f, color, rough, metal))
            prims.PruneChildren()
            continue
        local = _usd_mesh(prim, time) if prim.IsA(UsdGeom.Mesh) else None
        if local is not None:
            pts, faces, color, rough, metal = local
            world = _usd_matrix(cache.GetLocalToWorldTransform(prim))
            out.append((prim.GetName(), _transform_points(world, pts),
                        _fix_winding(faces, world), color, rough, metal))
    return out


def _usd_inherited(prim, seen: dict, time):
    """(invisible, purpose info) of `prim`, from its parent's in `seen` (prim path -> state;
    a traversal visits parents first), kept there for its children: what Imageable's
    ComputeVisibility and ComputePurpose give, without each walking up to the root (for every
    prim: quadratic in the depth, 5,000 levels took 15 s)."""
    from pxr import UsdGeom

    invisible, info = seen.get(prim.GetPath().GetParentPath(), (False, None))
    img = UsdGeom.Imageable(prim)
    if not invisible and prim.IsA(UsdGeom.Imageable):
        invisible = img.GetVisibilityAttr().Get(time) == UsdGeom.Tokens.invisible
    state = (invisible, img.ComputePurposeInfo(info or UsdGeom.Imageable.PurposeInfo()))
    seen[prim.GetPath()] = state
    return state


def _usd_traverse(stage, fix: np.ndarray, time, path: Path) -> tuple[list, list]:
    """(raw meshes, suns) of a stage's visible prims, stage space moved by `fix` (4, 4). Guide
    prims are not drawn, nor are proxy prims (stand-ins for render geometry) unless the stage
    has nothing else: a final render draws default and render purposes (drawing both would
    lay a proxy's boxes over the level's own surfaces)."""
    from pxr import Usd, UsdGeom, UsdLux

    cache = UsdGeom.XformCache(time)
    raw, proxies, suns, seen = [], [], [], {}
    prims = iter(Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(
        Usd.PrimDefaultPredicate)))
    for prim in prims:
        purpose = None
        invisible, info = _usd_inherited(prim, seen, time)
        if prim.IsA(UsdGeom.Imageable):
            if invisible:
                continue
            purpose = info.purpose
            if purpose == UsdGeom.Tokens.guide:
                continue
        if prim.IsA(UsdLux.DistantLight):
            light = UsdLux.DistantLight(prim)
            world = fix @ _usd_matrix(cache.GetLocalToWorldTransform(prim))
            d = light_direction(world)
            if d is not None:
                inten, color = _usd_light(light, time, path)
                suns.append(Sun(direction=d, intensity=inten, color=color))
            continue
        into = proxies if purpose == UsdGeom.Tokens.proxy else raw
        if prim.IsA(UsdGeom.PointInstancer):   # its prototypes are drawn only where it places them
            into += _usd_point_instances(UsdGeom.PointInstancer(prim), cache, fix, time, path)
            prims.PruneChildren()
            continue
        local = _usd_mesh(prim, time) if prim.IsA(UsdGeom.Mesh) else None
        if local is None:
            continue
        if len(raw) + len(proxies) >= MAX_MESHES:
            raise EnvironmentLoadError(f"the level has more than {MAX_MESHES:,} meshes (with its "
                                       "instances): keep the part of the level the creature "
                                       "uses", where=str(path))
        pts, faces, color, rough, metal = local
        world = fix @ _usd_matrix(cache.GetLocalToWorldTransform(prim))
        into.append((prim.GetName(), *_placed(world[None], pts, faces, None), color, rough,
                     metal))
    return raw or proxies, suns


def _read_usd_trapped(path: Path, trap, up_axis: str | None, units: str | None):
    from pxr import Usd, UsdGeom

    _check_usd_layers(path)
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise EnvironmentLoadError("cannot open USD stage", where=str(path))
    errors = list(stage.GetCompositionErrors())
    if errors:
        raise EnvironmentLoadError(f"USD composition error: {_usd_diagnostic_text(errors[0])}",
                                   where=str(path))
    if trap.HasErrors():
        raise EnvironmentLoadError(
            f"USD error: {_usd_diagnostic_text(trap.GetErrors()[0])}", where=str(path))
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage)) if units is None else UNITS[units]
    if not (math.isfinite(mpu) and mpu >= MIN_METERS_PER_UNIT):
        # (a unit of 1e-300 m shrank the level to a point: 'no triangle faces')
        raise EnvironmentLoadError(f"invalid metersPerUnit {mpu:g}; expected a finite number of "
                                   f"at least {MIN_METERS_PER_UNIT:g} (a nanometre)")
    z_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z if up_axis is None \
        else up_axis == "z"
    # stage space -> baker space (+Y up, metres)
    fix = np.eye(4)
    if z_up:
        fix[:3, :3] = Z_UP_TO_Y_UP
    fix[:3, :3] *= mpu
    raw, suns = _usd_traverse(stage, fix, Usd.TimeCode.EarliestTime(), path)
    if trap.HasErrors():
        raise EnvironmentLoadError(
            f"USD error: {_usd_diagnostic_text(trap.GetErrors()[0])}", where=str(path))
    sun = max(suns, key=lambda s: s.intensity) if suns else None
    return raw, sun
