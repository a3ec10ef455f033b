"""On-disk cache of built navigation surfaces, keyed by the environment's content hash, the agent
parameters, the build bounds, the surface's format version and the entry layout.

An entry (`navsurface-<key>.npz`) is a valid, uncompressed .npz: `meta.npy` (JSON: layout,
format version, scalars, a checksum per array) and every array of the NavData as `<name>.npy`
in its own dtype, its data aligned to ALIGN bytes in the file. A load memory-maps the file and
hands out read-only views of it (no copy, no inflating): 20-35 ms for the default scene's
2.2 M samples, where the compressed entries of layout 2 took 0.29-0.35 s to inflate and
rebuild; the entry is larger in exchange (191 MB against 13.3 MB; benchmarks/bench_nav_cache.py).

Integrity: the zip comment holds the CRC-32 of the entry's structure (every byte but the array
data: zip and .npy headers, meta, central directory), and the meta a 64-bit additive checksum
of each array's bytes (numpy sums them at memory speed); a load checks both, and every shape
and count against the meta.

The cache heals itself:
- an entry that cannot be read (truncated, empty, corrupt: the checksums above, lengths) is
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

import ast
import errno
import hashlib
import io
import json
import logging
import math
import mmap
import os
import stat
import struct
import time
import zipfile
import zlib
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from baker.atomic import atomic_output
from baker.errors import short_path
from baker.navmesh.query import NavSurface
from baker.navmesh.surface import DIRS, FORMAT_VERSION, NavData

log = logging.getLogger(__name__)

#: Layout of a cache entry (part of the key, so entries of another layout are never read).
LAYOUT = 3
#: Default bound of a cache folder, MB (--cache-max): room for a few dozen entries of the
#: default scene's size (about 13 MB each) or of big-level windows.
DEFAULT_MAX_MB = 1024.0
#: Temporary files older than this (seconds) are left-overs of killed processes and removed
#: when the folder is evicted.
STALE_TMP_S = 3600.0

_PREFIX = "navsurface-"
_SCALARS = ("origin", "shape", "cell_size", "coarse_factor", "agent_radius", "agent_height",
            "step_height", "max_slope")
#: errors that mean "this entry is damaged" (not "the cache folder is unusable")
_CORRUPT = (ValueError, KeyError, EOFError, TypeError, IndexError, SyntaxError, struct.error,
            NotImplementedError, OverflowError,
            zipfile.BadZipFile, zlib.error, json.JSONDecodeError, UnicodeDecodeError)
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


# ----------------------------------------------------------------------------- the entry's layout
#: Entry data (array bytes) starts at a multiple of this many bytes from the file's start.
ALIGN = 64
#: The zip comment: this prefix and 8 hex digits, the CRC-32 of the entry's structure.
_COMMENT = b"baker-navcache crc32 "
_COMMENT_LEN = len(_COMMENT) + 8
_LOCAL = struct.Struct("<4s5H3L2H")      # a zip local file header, without name and extra
_NPY_MAGIC = b"\x93NUMPY\x01\x00"


def _arrays(surface) -> dict[str, np.ndarray]:
    """The data's arrays, C-contiguous, in the surface's own dtypes (what load maps back)."""
    return {k: np.ascontiguousarray(v) for k, v in surface.arrays().items()
            if isinstance(v, np.ndarray)}


def _sum64(buf) -> int:
    """64-bit additive checksum of a byte buffer (its uint64 words, the last one zero-padded,
    summed modulo 2^64): any single changed word changes it; ~20 GB/s with numpy."""
    b = np.frombuffer(buf, dtype=np.uint8)
    n8 = len(b) // 8 * 8
    total = int(np.add.reduce(b[:n8].view(np.uint64), dtype=np.uint64)) if n8 else 0
    if n8 < len(b):
        tail = np.zeros(8, dtype=np.uint8)
        tail[:len(b) - n8] = b[n8:]
        total += int(tail.view(np.uint64)[0])
    return total % (1 << 64)


def _npy_header(a: np.ndarray, at: int) -> bytes:
    """A .npy (version 1.0) header for `a`, padded so that the data starts at a multiple of
    ALIGN when the header is written at file offset `at`."""
    d = "{'descr': %r, 'fortran_order': False, 'shape': %r, }" % (
        np.lib.format.dtype_to_descr(a.dtype), tuple(int(v) for v in a.shape))
    n = len(_NPY_MAGIC) + 2 + len(d) + 1
    pad = (-(at + n)) % ALIGN
    h = (d + " " * pad + "\n").encode("latin1")
    return _NPY_MAGIC + struct.pack("<H", len(h)) + h


def _write_entry(fh, meta: dict | bytes | None, arrays: dict[str, np.ndarray]) -> None:
    """Write the entry (a valid, uncompressed .npz) to the open binary file `fh` (w+b): meta.npy
    (the JSON meta as uint8; bytes as they are; None: none), then each array as <name>.npy with
    its data aligned; the zip comment holds the CRC-32 of everything but the array data (see
    _structure_crc)."""
    with zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        zf.comment = _COMMENT + b"0" * 8
        raw = meta if isinstance(meta, bytes) or meta is None else json.dumps(meta).encode()
        members = [] if raw is None else [("meta", np.frombuffer(raw, dtype=np.uint8))]
        members += list(arrays.items())
        for name, a in members:
            zi = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            with zf.open(zi, "w", force_zip64=a.nbytes > (1 << 30)) as w:
                w.write(_npy_header(a, fh.tell()))
                if a.nbytes:
                    w.write(memoryview(a).cast("B"))
    fh.flush()
    size = fh.tell()
    with mmap.mmap(fh.fileno(), size, access=mmap.ACCESS_READ) as mm:
        crc = _structure_crc(mm, _members(mm, size)[1])
    fh.seek(size - 8)
    fh.write(b"%08x" % crc)


def _members(mm, size: int):
    """Parse an entry mapped in `mm`: ({name: (dtype, shape, data offset)} of the .npy members,
    [(start, end)] byte ranges of the array data). Raises one of _CORRUPT when it is not an
    entry of this layout."""
    if size < 22 + _COMMENT_LEN:
        raise ValueError("too short")
    eocd = size - 22 - _COMMENT_LEN
    if mm[eocd:eocd + 4] != b"PK\x05\x06" or mm[size - _COMMENT_LEN:size - 8] != _COMMENT:
        raise ValueError("not a navigation cache entry of this layout")
    out, ranges = {}, []
    with zipfile.ZipFile(_MapFile(mm)) as zf:
        infos = zf.infolist()
    for zi in infos:
        sig, _, flags, method, _, _, _, csize, usize, nlen, xlen = _LOCAL.unpack_from(
            mm, zi.header_offset)
        name = bytes(mm[zi.header_offset + 30:zi.header_offset + 30 + nlen]).decode()
        if sig != b"PK\x03\x04" or method != zipfile.ZIP_STORED or flags & 1 \
                or name != zi.filename or not name.endswith(".npy"):
            raise ValueError(f"bad member header {name!r}")
        at = zi.header_offset + 30 + nlen + xlen
        end = at + zi.file_size
        if mm[at:at + 8] != _NPY_MAGIC or end > eocd:
            raise ValueError(f"{name}: not a .npy member")
        hlen = struct.unpack_from("<H", mm, at + 8)[0]
        d = ast.literal_eval(bytes(mm[at + 10:at + 10 + hlen]).decode("latin1"))
        dtype = np.lib.format.descr_to_dtype(d["descr"])
        shape = tuple(int(v) for v in d["shape"])
        start = at + 10 + hlen
        if dtype.hasobject or d["fortran_order"] or start + dtype.itemsize * math.prod(shape) != end:
            raise ValueError(f"{name}: inconsistent .npy header")
        out[name[:-4]] = (dtype, shape, start)
        if name != "meta.npy":
            ranges.append((start, end))
    return out, sorted(ranges)


class _MapFile(io.RawIOBase):
    """A read-only file over a mmap (zipfile reads the central directory through it)."""

    def __init__(self, mm):
        self.mm, self.pos = mm, 0

    def readable(self):
        return True

    def seekable(self):
        return True

    def seek(self, pos, whence=0):
        self.pos = pos if whence == 0 else (self.pos + pos if whence == 1 else len(self.mm) + pos)
        return self.pos

    def tell(self):
        return self.pos

    def readinto(self, b):
        n = max(0, min(len(b), len(self.mm) - self.pos))
        b[:n] = self.mm[self.pos:self.pos + n]
        self.pos += n
        return n


def _structure_crc(mm, ranges) -> int:
    """CRC-32 of the entry's bytes outside the array data and the comment's 8 hex digits:
    every zip and .npy header, the meta, the central directory."""
    crc, at = 0, 0
    for start, end in list(ranges) + [(len(mm) - 8, len(mm))]:
        crc = zlib.crc32(mm[at:start], crc)
        at = end
    return crc


def _meta(surface) -> dict:
    a = surface.arrays()
    scalars = {k: (list(a[k]) if isinstance(a[k], tuple) else a[k]) for k in _SCALARS}
    return {"layout": LAYOUT, "format_version": FORMAT_VERSION,
            "scalars": json.loads(json.dumps(scalars, default=float))}


def _decode(mm, size: int) -> NavData | None:
    """The NavData of an entry mapped in `mm` (its arrays are read-only views of the map);
    None when it is of another layout or format version. Raises one of _CORRUPT when it is
    damaged: a structure CRC, an array checksum, a shape or a count that does not match."""
    members, ranges = _members(mm, size)
    if int(bytes(mm[size - 8:size]), 16) != _structure_crc(mm, ranges):
        raise ValueError("structure checksum mismatch")
    dt, shape, at = members.pop("meta")
    meta = json.loads(bytes(mm[at:at + math.prod(shape)]).decode())
    if meta.get("layout") != LAYOUT or meta.get("format_version") != FORMAT_VERSION:
        return None
    sc = meta["scalars"]
    nx, nz = (int(v) for v in sc["shape"])
    arrays = {}
    for name, (dtype, shape, at) in members.items():
        a = np.frombuffer(mm, dtype=dtype, count=math.prod(shape), offset=at).reshape(shape)
        if _sum64(a.view(np.uint8).reshape(-1)) != int(meta["sums"][name]):
            raise ValueError(f"{name}: checksum mismatch")
        arrays[name] = a
    n = len(arrays["positions"])
    want = {"positions": (n, 3), "normals": (n, 3), "cells": (n, 2), "col_start": (nx * nz + 1,),
            "links": (n, len(DIRS)), "component": (n,), "clearance": (n,), "coarse_of": (n,)}
    for name, shp in want.items():
        if arrays[name].shape != shp:
            raise ValueError(f"{name}: wrong shape {arrays[name].shape}")
    if int(arrays["col_start"][-1]) != n:
        raise ValueError("column index does not add up to the samples")
    kw = dict(arrays, origin=tuple(float(v) for v in sc["origin"]), shape=(nx, nz),
              coarse_factor=int(sc["coarse_factor"]))
    for k in ("cell_size", "agent_radius", "agent_height", "step_height", "max_slope"):
        kw[k] = float(sc[k])
    return NavData(**{f.name: kw[f.name] for f in fields(NavData)})


# ----------------------------------------------------------------------------- files
def save(surface: NavData | NavSurface, path) -> Path:
    """Write `surface` to `path` (.npz) atomically (temporary file + os.replace). OSError (or
    ExportError) when the folder cannot be created or written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = _arrays(surface)
    meta = _meta(surface)
    meta["sums"] = {k: str(_sum64(memoryview(v).cast("B"))) for k, v in arrays.items()}
    with atomic_output(path) as tmp:
        with open(tmp, "w+b") as fh:
            _write_entry(fh, meta, arrays)
    return path


class CorruptEntry(Exception):
    """A cache entry exists but cannot be read back (see load)."""


def _nonblocking(path, flags: int) -> int:
    """open()'s opener that does not wait: opening a FIFO to read waits for a writer."""
    return os.open(path, flags | os.O_NONBLOCK)


def load(path, *, strict: bool = False) -> NavSurface | None:
    """Read a surface saved by `save`, its arrays memory-mapped (read-only); None when the file
    is missing or of another layout or format version. A damaged entry (truncated, empty,
    failing a checksum or a length check) gives None with a warning, or CorruptEntry when
    `strict`."""
    path = Path(path)
    try:
        with open(path, "rb", opener=_nonblocking) as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):    # a FIFO in its place: the read waited for ever
                raise ValueError("not a regular file")
            size = st.st_size
            if size == 0:
                raise ValueError("empty file")
            mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        data = _decode(mm, size)
        return None if data is None else NavSurface(data)
    except FileNotFoundError:
        return None
    except IsADirectoryError as exc:
        err = exc
    except _CORRUPT as exc:
        err = exc
    except OSError as exc:
        # a path the file system refuses as too long, or in a folder this user may not search,
        # holds no entry (store then warns once that the folder cannot be written, and the
        # bake goes on without the cache)
        if exc.errno in (errno.ENAMETOOLONG, errno.EACCES, errno.EPERM) or not _exists(path):
            return None
        err = exc
    if strict:
        raise CorruptEntry(f"{path}: {err}")
    log.warning("navigation cache entry %s is damaged (%s); rebuilding it", path.name,
                str(err).splitlines()[0] if str(err) else type(err).__name__)
    return None


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:
        return False


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
                   "baking without the cache", short_path(str(cache.folder)), why)
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
