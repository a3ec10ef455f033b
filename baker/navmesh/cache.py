"""On-disk cache of built navigation surfaces, keyed by the environment's content hash, the agent
parameters, the build bounds, the surface's format version and the entry layout.

An entry (`navsurface-<key>.npz`) holds only what the queries cannot rebuild exactly and fast:
- `cells` and `col_start` come back from the per-column sample counts, and the x and z of
  `positions` from the cells (column centres); each is stored instead when, for some surface,
  the rebuilt array would not be bit-identical to the built one (checked when saving);
- `links` is stored as the offset to the linked sample (-1 - s where there is no link), which
  zlib squeezes to almost nothing (a few hundred kB for 2.2 M samples);
- the other arrays are zlib-compressed (level 1) in their own, narrowest exact dtype, except
  the heights, which do not compress and are stored raw.
The default scene's entry goes from 191 MB (every array raw) to 13.3 MB; the load takes about
0.05-0.1 s more in exchange (inflating, rebuilding; benchmarks/bench_nav_cache.py).

The cache heals itself:
- an entry that cannot be read (truncated, empty, corrupt: zip and zlib checksums, lengths) is
  rebuilt and rewritten, with one warning;
- a folder that cannot be created or written to means the bake goes on without writing to it,
  with one warning per folder and process;
- entries are written atomically (temporary file + rename, baker/atomic.py);
- the folder is bounded (`NavCache.max_bytes`, the CLI's `--cache-max` in MB, default
  DEFAULT_MAX_MB): after a write, the least recently used entries (a hit touches its entry's
  mtime) are deleted until the folder's entries fit. An entry larger than the bound alone is
  not kept.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
import zipfile
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from baker.atomic import atomic_output
from baker.navmesh.query import NavSurface
from baker.navmesh.surface import DIRS, FORMAT_VERSION, NavData

log = logging.getLogger(__name__)

#: Layout of a cache entry (part of the key, so entries of another layout are never read).
LAYOUT = 2
#: Default bound of a cache folder, MB (--cache-max): room for a few dozen entries of the
#: default scene's size (about 13 MB each) or of big-level windows.
DEFAULT_MAX_MB = 1024.0
#: Temporary files older than this (seconds) are left-overs of killed processes and removed
#: when the folder is evicted.
STALE_TMP_S = 3600.0

_PREFIX = "navsurface-"
_SCALARS = ("origin", "shape", "cell_size", "coarse_factor", "agent_radius", "agent_height",
            "step_height", "max_slope")
_NO_LINK = np.int32(-1)
#: errors that mean "this entry is damaged" (not "the cache folder is unusable")
_CORRUPT = (ValueError, KeyError, EOFError, TypeError, IndexError, zipfile.BadZipFile, zlib.error,
            json.JSONDecodeError, UnicodeDecodeError)
_warned: set[str] = set()


@dataclass(frozen=True)
class NavCache:
    """A cache folder and its bound.

    folder    : the folder holding the entries
    max_bytes : [0, inf) bytes; the entries are trimmed, least recently used first, to this
    """

    folder: Path
    max_bytes: int = int(DEFAULT_MAX_MB * 2 ** 20)

    @classmethod
    def of(cls, cache, max_mb: float | None = None) -> "NavCache | None":
        """`cache` (None, a folder or a NavCache) as a NavCache; `max_mb` overrides the bound."""
        if cache is None:
            return None
        if not isinstance(cache, NavCache):
            cache = cls(Path(cache))
        if max_mb is not None:
            cache = cls(cache.folder, int(max(0.0, float(max_mb)) * 2 ** 20))
        return cache


def cache_key(env, agent, bounds=None) -> str:
    """Hex key of (environment content, agent parameters, bounds, format version, layout)."""
    params = {
        "env": env.content_hash,
        "agent": {k: float(v) for k, v in sorted(asdict(agent).items())},
        "bounds": None if bounds is None else np.asarray(bounds, float).round(9).tolist(),
        "version": FORMAT_VERSION,
        "layout": LAYOUT,
    }
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:32]


def cache_path(cache_dir, env, agent, bounds=None) -> Path:
    folder = cache_dir.folder if isinstance(cache_dir, NavCache) else Path(cache_dir)
    return folder / f"{_PREFIX}{cache_key(env, agent, bounds)}.npz"


def _warn_once(key: str, msg: str, *args) -> None:
    if key not in _warned:
        _warned.add(key)
        log.warning(msg, *args)


# ----------------------------------------------------------------------------- encoding
def _narrow_int(a: np.ndarray) -> np.ndarray:
    """`a` in the narrowest signed/unsigned integer dtype that holds it exactly."""
    if a.size == 0:
        return a
    lo, hi = int(a.min()), int(a.max())
    for dt in (np.uint8, np.int8, np.uint16, np.int16, np.int32, np.uint32, np.int64):
        info = np.iinfo(dt)
        if info.min <= lo and hi <= info.max:
            return a.astype(dt, copy=False)
    return a


def _derived_cells(counts: np.ndarray, nz: int) -> np.ndarray:
    """(N, 2) int32 (ix, iz) of every sample from the per-column counts (C,)."""
    col = np.repeat(np.arange(len(counts), dtype=np.int32), counts)
    cells = np.empty((len(col), 2), dtype=np.int32)
    np.floor_divide(col, np.int32(nz), out=cells[:, 0])
    np.subtract(col, cells[:, 0] * np.int32(nz), out=cells[:, 1])
    return cells


def _derived_xz(cells: np.ndarray, origin, cell: float, out: np.ndarray | None = None):
    """Column centres of `cells` as float32 x and z, written into out[:, 0] and out[:, 2]
    (N, 3) float32 when given; the same arithmetic (float64, then rounded) as the build."""
    x0, z0 = origin
    if out is None:
        out = np.empty((len(cells), 3), dtype=np.float32)
    out[:, 0] = x0 + (cells[:, 0] + 0.5) * cell
    out[:, 2] = z0 + (cells[:, 1] + 0.5) * cell
    return out


_NO_LINK16 = np.int16(-32768)


def _link_offsets(links: np.ndarray) -> np.ndarray:
    """links[s, d] - s: (N, 8) int16 with -32768 where there is no link when every offset fits
    (a row of the grid holds fewer than ~32k samples), else int32 with -1 - s there; either way
    links = offsets + s (see _links)."""
    s = np.arange(len(links), dtype=np.int32)[:, None]
    off = np.subtract(links, s, dtype=np.int32)
    none = links < 0
    linked = off[~none]
    if linked.size == 0 or (int(linked.min()) > -32768 and int(linked.max()) < 32768):
        out = off.astype(np.int16)
        out[none] = _NO_LINK16
        return out
    np.copyto(off, np.int32(-1) - s, where=none)
    return off


def _links(off: np.ndarray, first: int = 0) -> np.ndarray:
    """Inverse of _link_offsets for rows first.. of the surface: (n, 8) int32, -1 = none."""
    links = off.astype(np.int32)
    links += np.arange(first, first + len(off), dtype=np.int32)[:, None]
    if off.dtype == np.int16:
        links[off == _NO_LINK16] = -1
    return links


#: Packed arrays stored without deflating (chosen by benchmarks/bench_nav_cache.py: the
#: trade between entry size and load time).
RAW_MEMBERS = frozenset()
#: Raw bytes per compressed chunk; chunks are inflated in parallel when an entry is loaded.
CHUNK = 4 << 20


def _final_dtypes(a: dict) -> dict[str, str]:
    """dtype of every packed array once decoded (the surface's own)."""
    out = {k: str(np.asarray(a[k]).dtype) for k in
           ("normals", "clearance", "component_area", "coarse_indptr", "component", "coarse_of",
            "coarse_rep", "coarse_indices", "cells", "positions", "col_start")}
    out["link_offsets"] = str(np.asarray(a["links"]).dtype)
    out["counts"] = out["col_start"]
    return out


def encode(surface: NavData | NavSurface, raw=None) -> dict[str, np.ndarray]:
    """The entry's members: {name: array}; see the module docstring. Packed arrays are cut
    into chunks of whole rows (about CHUNK raw bytes each), each deflated on its own, so a
    load inflates them in parallel straight into the surface's arrays. Those named in `raw`
    (default RAW_MEMBERS) are stored as they are, in the same chunks."""
    raw = RAW_MEMBERS if raw is None else frozenset(raw)
    a = surface.arrays()
    nx, nz = (int(v) for v in surface.shape)
    counts = np.diff(np.asarray(a["col_start"], dtype=np.int64))
    plain: dict[str, np.ndarray] = {}       # stored raw
    packed: dict[str, np.ndarray] = {}      # deflated
    derived = []
    packed["counts"] = _narrow_int(counts)
    if len(counts) == nx * nz and np.array_equal(_derived_cells(counts, nz), a["cells"]):
        derived.append("cells")
    else:
        packed["cells"] = np.asarray(a["cells"])
    pos = np.asarray(a["positions"], dtype=np.float32)
    xz = _derived_xz(np.asarray(a["cells"]), surface.origin, surface.cell_size)
    if np.array_equal(xz[:, 0], pos[:, 0]) and np.array_equal(xz[:, 2], pos[:, 2]):
        derived.append("positions_xz")
        plain["positions_y"] = np.ascontiguousarray(pos[:, 1])
    else:
        packed["positions"] = pos
    packed["link_offsets"] = _link_offsets(np.asarray(a["links"]))
    for name in ("normals", "clearance", "component_area", "coarse_indptr"):
        packed[name] = np.asarray(a[name])
    for name in ("component", "coarse_of", "coarse_rep", "coarse_indices"):
        packed[name] = _narrow_int(np.asarray(a[name]))
    out: dict[str, np.ndarray] = dict(plain)
    chunks = {}
    for k, v in packed.items():
        v = np.ascontiguousarray(v)
        row = max(1, v.itemsize * (int(np.prod(v.shape[1:])) if v.ndim > 1 else 1))
        step = max(1, CHUNK // row)
        starts = list(range(0, max(len(v), 1), step))
        chunks[k] = [[r0, min(r0 + step, len(v))] for r0 in starts]
        for i, (r0, r1) in enumerate(chunks[k]):
            if k in raw:
                out[f"r_{k}.{i}"] = v[r0:r1]
            else:
                out[f"z_{k}.{i}"] = np.frombuffer(
                    zlib.compress(memoryview(v[r0:r1]).cast("B"), 1), dtype=np.uint8)
    meta = {
        "layout": LAYOUT, "format_version": FORMAT_VERSION, "derived": derived,
        "samples": int(len(pos)),
        "scalars": {k: (list(a[k]) if isinstance(a[k], tuple) else a[k]) for k in _SCALARS},
        "dtypes": _final_dtypes(a),
        "packed": {k: [str(v.dtype), list(v.shape), chunks[k], "raw" if k in raw else "zlib"]
                   for k, v in packed.items()},
    }
    meta["scalars"] = json.loads(json.dumps(meta["scalars"], default=float))
    out["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    return out


def decode(members) -> NavData:
    """A surface's data from an entry's members (a mapping name -> array). Raises ValueError (or
    another of _CORRUPT) when they are inconsistent."""
    meta = json.loads(bytes(members["meta"]).decode())
    if meta.get("layout") != LAYOUT or meta.get("format_version") != FORMAT_VERSION:
        raise ValueError("entry of another layout or format version")
    sc = meta["scalars"]
    nx, nz = (int(v) for v in sc["shape"])
    n = int(meta["samples"])
    dt = meta["dtypes"]
    want = {"counts": (nx * nz,), "link_offsets": (n, len(DIRS)), "normals": (n, 3),
            "clearance": (n,), "component": (n,), "coarse_of": (n,), "cells": (n, 2),
            "positions": (n, 3)}
    arrays: dict[str, np.ndarray] = {}
    tasks = []
    for name, (stored, shape, chunks, codec) in meta["packed"].items():
        shape = tuple(int(v) for v in shape)
        if name in want and shape != want[name]:
            raise ValueError(f"{name}: wrong shape {shape}")
        arrays[name] = np.empty(shape, dtype=np.dtype(dt[name]))
        for i, (r0, r1) in enumerate(chunks):
            key = f"{'r' if codec == 'raw' else 'z'}_{name}.{i}"
            tasks.append((name, np.dtype(stored), int(r0), int(r1), members[key], codec == "raw"))
    covered = {k: 0 for k in arrays}

    def inflate(task):
        name, stored, r0, r1, blob, plain = task
        out = arrays[name]
        if plain:
            if blob.dtype != stored:
                raise ValueError(f"{name}: chunk of the wrong type")
            part = blob.reshape(-1)
        else:
            part = np.frombuffer(zlib.decompress(blob), dtype=stored)
        if part.size != (r1 - r0) * int(np.prod(out.shape[1:])):
            raise ValueError(f"{name}: chunk of the wrong length")
        part = part.reshape((r1 - r0,) + out.shape[1:])
        if name == "link_offsets":
            part = _links(part, r0)
        out[r0:r1] = part
        return name, r1 - r0

    # zlib and numpy release the GIL: inflate the chunks on two threads, biggest first
    tasks.sort(key=lambda t: -t[4].nbytes)
    with ThreadPoolExecutor(max_workers=2) as pool:
        for name, rows in pool.map(inflate, tasks):
            covered[name] += rows
    for name, a in arrays.items():
        if covered[name] != len(a):
            raise ValueError(f"{name}: chunks do not cover the array")
    counts = arrays.pop("counts")
    col_start = np.zeros(nx * nz + 1, dtype=counts.dtype)
    np.cumsum(counts, out=col_start[1:])
    if int(col_start[-1]) != n:
        raise ValueError("counts do not add up to the samples")
    cells = arrays.pop("cells") if "cells" in arrays else _derived_cells(counts, nz)
    if "positions_xz" in meta["derived"]:
        y = np.asarray(members["positions_y"])
        if y.shape != (n,):
            raise ValueError("positions: wrong length")
        positions = _derived_xz(cells, sc["origin"], float(sc["cell_size"]))
        positions[:, 1] = y
    else:
        positions = arrays.pop("positions")
    kw = dict(arrays, positions=positions, cells=cells.astype(np.dtype(dt["cells"]), copy=False),
              col_start=col_start, links=arrays.pop("link_offsets"))
    kw["origin"] = tuple(float(v) for v in sc["origin"])
    kw["shape"] = (nx, nz)
    kw["coarse_factor"] = int(sc["coarse_factor"])
    for k in ("cell_size", "agent_radius", "agent_height", "step_height", "max_slope"):
        kw[k] = float(sc[k])
    return NavData(**{f.name: kw[f.name] for f in fields(NavData)})


# ----------------------------------------------------------------------------- files
def save(surface: NavData | NavSurface, path) -> Path:
    """Write `surface` to `path` (.npz) atomically (temporary file + os.replace). OSError (or
    ExportError) when the folder cannot be created or written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    members = encode(surface)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **members)
    return path


class CorruptEntry(Exception):
    """A cache entry exists but cannot be read back (see load)."""


def load(path, *, strict: bool = False) -> NavSurface | None:
    """Read a surface saved by `save`; None when the file is missing or of another layout or
    format version. A damaged entry (truncated, empty, failing a checksum or a length check)
    gives None with a warning, or CorruptEntry when `strict`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "meta" not in z.files:
                raise ValueError("no meta member")
            meta = json.loads(bytes(z["meta"]).decode())
            if meta.get("layout") != LAYOUT or meta.get("format_version") != FORMAT_VERSION:
                return None
            return NavSurface(decode({k: z[k] for k in z.files}))
    except FileNotFoundError:
        return None
    except IsADirectoryError as exc:
        err = exc
    except _CORRUPT as exc:
        err = exc
    except OSError as exc:
        if not path.exists():
            return None
        err = exc
    if strict:
        raise CorruptEntry(f"{path}: {err}")
    log.warning("navigation cache entry %s is damaged (%s); rebuilding it", path.name,
                str(err).splitlines()[0] if str(err) else type(err).__name__)
    return None


def _entries(folder: Path):
    """(path, size, mtime) of every entry in folder."""
    out = []
    try:
        it = list(os.scandir(folder))
    except OSError:
        return out
    for e in it:
        if e.name.startswith(_PREFIX) and e.name.endswith(".npz"):
            try:
                st = e.stat(follow_symlinks=False)
            except OSError:
                continue
            out.append((Path(e.path), st.st_size, st.st_mtime))
        elif e.name.startswith("." + _PREFIX) and ".tmp" in e.name:
            try:
                if time.time() - e.stat(follow_symlinks=False).st_mtime > STALE_TMP_S:
                    os.unlink(e.path)
            except OSError:
                pass
    return out


def evict(cache: NavCache, keep: Path | None = None) -> list[Path]:
    """Delete the least recently used entries until the folder's entries total at most
    cache.max_bytes (`keep` goes last). Returns the deleted paths."""
    entries = sorted(_entries(cache.folder), key=lambda e: (e[0] == keep, e[2], e[0].name))
    total = sum(e[1] for e in entries)
    gone = []
    for p, size, _ in entries:
        if total <= cache.max_bytes:
            break
        try:
            os.unlink(p)
        except FileNotFoundError:
            pass
        except OSError:
            continue
        total -= size
        gone.append(p)
    if gone:
        log.info("navigation cache: evicted %d entries from %s", len(gone), cache.folder)
    return gone


def _touch(path: Path) -> None:
    try:
        os.utime(path)
    except OSError:
        pass


def store(cache: NavCache, surface: NavSurface, path: Path) -> bool:
    """Save `surface` at `path` in the cache and trim the folder to its bound. False (with one
    warning per folder) when the folder cannot be written: the caller goes on without it."""
    from baker.errors import BakerError

    if cache.max_bytes <= 0:
        return False
    try:
        save(surface, path)
    except (OSError, BakerError) as exc:
        why = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        _warn_once(str(cache.folder), "navigation cache folder %s cannot be written (%s); "
                   "baking without the cache", cache.folder, why)
        return False
    if path.stat().st_size > cache.max_bytes:
        log.info("navigation cache entry %s is larger than the cache bound; not kept", path.name)
    evict(cache, keep=path)
    return True


def load_or_build(env, agent, cache_dir=None, *, bounds=None, **build_kw) -> tuple[NavSurface, bool]:
    """(surface, from_cache): load the cached surface for (env, agent, bounds) from cache_dir
    (None, a folder or a NavCache), or build it (and save it there when cache_dir is given)."""
    from baker.navmesh.build import build

    cache = NavCache.of(cache_dir)
    if cache is None:
        return build(env, agent, bounds=bounds, **build_kw), False
    p = cache_path(cache, env, agent, bounds)
    s = load(p)
    if s is not None:
        _touch(p)
        log.info("navigation surface loaded from cache %s", p)
        return s, True
    s = build(env, agent, bounds=bounds, **build_kw)
    store(cache, s, p)
    return s, False
