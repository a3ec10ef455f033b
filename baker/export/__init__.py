"""Writers: glTF (GLB), USD and (elsewhere) the JSON report. The only code that writes files.

This module holds the small helpers the writers share: JSON-safe extras, node names, normals and
the sun light orientation.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import PurePath

import numpy as np



#: types jsonable returns as they are
_PLAIN = frozenset({str, int, bool, type(None)})


def jsonable(obj):
    """Plain-Python copy of `obj` for JSON: numpy scalars/arrays, tuples, paths, dataclasses.

    Non-finite floats become None (JSON has no NaN). Dict keys become strings.
    """
    kind = type(obj)
    if kind in _PLAIN:                      # fast paths: a report's long lists of ints
        return obj
    if kind is list:
        return [v if type(v) in _PLAIN else jsonable(v) for v in obj]
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        items = sorted(obj, key=repr) if isinstance(obj, (set, frozenset)) else obj
        return [jsonable(v) for v in items]
    if isinstance(obj, PurePath):
        return str(obj)
    if hasattr(obj, "__dataclass_fields__"):
        return {k: jsonable(getattr(obj, k)) for k in obj.__dataclass_fields__}
    return str(obj)


_BAD = re.compile(r"[^A-Za-z0-9_]")


def safe_name(name: str, taken: set[str], fallback: str = "node") -> str:
    """`name` reduced to [A-Za-z0-9_], at most 63 bytes, made unique against `taken` (updated
    with the name and its lower-case form, so names stay unique also without regard to case)."""
    base = _BAD.sub("_", str(name)) or fallback
    if base[0].isdigit():
        base = "_" + base
    base = base[:56]
    out, k = base, 1
    while out in taken or out.lower() in taken:
        out = f"{base}_{k}"
        k += 1
    taken.update((out, out.lower()))
    return out


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) float32 unit area-weighted vertex normals; isolated/degenerate vertices get +Y."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = np.zeros_like(v)
    if len(f):
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        for c in range(3):
            np.add.at(n, f[:, c], fn)
    return unit_normals(n)


def unit_normals(n: np.ndarray) -> np.ndarray:
    """Normalize to float32 unit length; zero/non-finite rows become +Y."""
    n = np.asarray(n, dtype=np.float64)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    good = np.isfinite(length) & (length > 1e-30)
    out = np.where(good, n / np.where(good, length, 1.0), np.array([0.0, 1.0, 0.0]))
    return out.astype(np.float32)


def checked_mesh(name: str, vertices, faces, normals):
    """Validate a static mesh for writing: (vertices (n, 3) float32, faces (m, 3) int64,
    unit vertex normals (n, 3) float32, computed when missing or malformed).
    ExportError names the mesh when it is empty, out of range or non-finite."""
    from baker.errors import ExportError

    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not len(v) or not len(f):
        raise ExportError(f"mesh {name!r} has no vertices or no faces")
    if f.min() < 0 or f.max() >= len(v):
        raise ExportError(f"mesh {name!r} has face indices out of range")
    if not np.all(np.isfinite(v)):
        raise ExportError(f"mesh {name!r} has non-finite vertices")
    n = vertex_normals(v, f) if normals is None or np.shape(normals) != v.shape else unit_normals(normals)
    return v, f, n


def environment_parts(env):
    """The environment's non-empty meshes with their base colour as an RGBA tuple (empty
    meshes are skipped with a warning), in file order: (EnvMesh, rgba)."""
    import logging

    for m in env.meshes:
        if len(m.vertices) == 0 or len(m.faces) == 0:
            logging.getLogger(__name__).warning("skipping empty environment mesh %r", m.name)
            continue
        rgba = tuple(float(c) for c in m.color)
        yield m, rgba + (1.0,) * (4 - len(rgba))


def creature_label(i: int, n: int) -> tuple[str, str]:
    """(placement name, joint-name prefix) of creature i of a bake of n creatures.

    Creature 0 is named as a lone creature's (`Centipede`, joints `head`, `trunk_01`, ...), so
    tools that read one creature find it. Creature i >= 1 is `Centipede_<ii>` and its glTF
    joints are `c<ii>_head`, `c<ii>_trunk_01`, ... (ii zero-padded to two digits, or three
    from a thousand creatures on), so every node name in the file stays unique, also without
    regard to case. USD needs no prefix (joints are scoped by their Skeleton prim)."""
    if i == 0:
        return "Centipede", ""
    tag = f"{i:0{max(2, len(str(n - 1)))}d}"
    return f"Centipede_{tag}", f"c{tag}_"
