"""The navigation cache heals itself: damaged entries are rebuilt with one warning, an
unwritable folder means no caching with one warning, entries are compact and exact, and the
folder is bounded (least recently used entries evicted)."""

from __future__ import annotations

import json
import logging
import os
import time
import zipfile
from dataclasses import replace

import numpy as np
import pytest

from baker.navmesh import build, cache
from baker.navmesh.cache import NavCache
from test_navmesh_scenes import AGENT, bridge_scene, half_log, env_of, floor, ramp_scene, wall_scene

SCENES = {
    "bridge": bridge_scene,
    "wall": wall_scene,
    "ramp": lambda: ramp_scene(30.0),
    "log": lambda: env_of(floor(-0.2, 1.2, -0.2, 1.2), half_log()),
}


@pytest.fixture(autouse=True)
def fresh_warnings(monkeypatch):
    """Every test starts with no folder warned about yet."""
    monkeypatch.setattr(cache, "_warned", set())


@pytest.fixture(scope="module")
def env():
    return bridge_scene()


@pytest.fixture(scope="module")
def surface(env):
    return build(env, AGENT)


def same_surface(a, b):
    for k, v in a.arrays().items():
        w = b.arrays()[k]
        if isinstance(v, np.ndarray):
            assert v.dtype == w.dtype and v.shape == w.shape and np.array_equal(v, w), k
        else:
            assert v == w and type(v) is type(w), k


def warnings_of(caplog):
    return [r for r in caplog.records if r.levelno >= logging.WARNING]


# ----------------------------------------------------------------------------- exact entries
@pytest.mark.parametrize("name", sorted(SCENES))
def test_entry_round_trip_is_exact_and_mapped(name, tmp_path):
    s = build(SCENES[name](), AGENT)
    p = cache.save(s, tmp_path / "e.npz")
    back = cache.load(p, strict=True)
    same_surface(s, back)
    arrays = {k: v for k, v in back.arrays().items() if isinstance(v, np.ndarray)}
    raw = sum(v.nbytes for v in arrays.values())
    # the arrays as they are (plus headers), handed out as read-only views of the mapped file
    assert raw < p.stat().st_size < raw + len(arrays) * (cache.ALIGN + 256) + 1024
    for k, v in arrays.items():
        assert not v.flags.writeable and v.base is not None, k
        assert v.ctypes.data % cache.ALIGN == 0 or v.nbytes == 0, k
    a, b = [0.05, 0.0, 0.5], [0.95, 0.0, 0.5]
    assert np.array_equal(s.find_path(a, b).points, back.find_path(a, b).points)


def test_arrays_that_cannot_be_derived_are_stored(surface, tmp_path):
    """Positions off the column centres and cells that disagree with the counts are kept as
    they are, not rebuilt."""
    pos = surface.positions.copy()
    pos[:, 0] += np.float32(1e-3)
    odd = replace(surface.data, positions=pos)   # the data (NavData) is the dataclass
    back = cache.load(cache.save(odd, tmp_path / "a.npz"), strict=True)
    same_surface(odd, back)


# ----------------------------------------------------------------------------- damaged entries
def _damages():
    """(id, damage(bytes) -> bytes): generated truncations, bit flips and replacements."""
    out = [("empty", lambda b: b""), ("garbage", lambda b: b"not a zip at all" * 10),
           ("zeros", lambda b: bytes(len(b)))]
    for frac in (0.02, 0.25, 0.5, 0.75, 0.98):
        out.append((f"truncated-{frac}", lambda b, f=frac: b[:int(len(b) * f)]))
    out.append(("truncated-1-byte", lambda b: b[:-1]))
    for frac in np.linspace(0.0, 0.999, 24):
        def flip(b, f=frac):
            a = bytearray(b)
            a[int(len(a) * f)] ^= 0x10
            return bytes(a)
        out.append((f"bit-flip-{frac:.3f}", flip))
    return out


DAMAGES = _damages()


def _npz(members):
    import io
    buf = io.BytesIO()
    np.savez(buf, **members)
    return buf.getvalue()


def _entry_bytes(meta, arrays, tmp_path):
    """An entry written by the cache's own writer (valid checksums) with the given content."""
    p = tmp_path / "scratch.bin"
    with open(p, "w+b") as fh:
        cache._write_entry(fh, meta, arrays)
    out = p.read_bytes()
    p.unlink()
    return out


def _bad_entries(surface, tmp_path):
    """Well-formed entries, checksums right, whose content is wrong."""
    arrays = cache._arrays(surface)
    meta = cache._meta(surface)
    meta["sums"] = {k: str(cache._sum64(memoryview(v).cast("B"))) for k, v in arrays.items()}
    cases = {"no-meta": (None, arrays), "meta-not-json": (b"{not json", arrays)}
    for name, cut in (("short-heights", "positions"), ("half-the-links", "links")):
        a = dict(arrays)
        a[cut] = a[cut][: len(a[cut]) // 2 if cut == "links" else -3]
        m = json.loads(json.dumps(meta))
        m["sums"][cut] = str(cache._sum64(memoryview(a[cut]).cast("B")))
        cases[name] = (m, a)
    cases["missing-normals"] = (meta, {k: v for k, v in arrays.items() if k != "normals"})
    m = json.loads(json.dumps(meta))
    m["sums"]["clearance"] = str((int(m["sums"]["clearance"]) + 1) % 2 ** 64)
    cases["wrong-checksum"] = (m, arrays)
    a = dict(arrays)
    a["col_start"] = a["col_start"].copy()
    a["col_start"][-1] += 1
    m = json.loads(json.dumps(meta))
    m["sums"]["col_start"] = str(cache._sum64(memoryview(a["col_start"]).cast("B")))
    cases["column-index"] = (m, a)
    return {k: _entry_bytes(m, a, tmp_path) for k, (m, a) in cases.items()}


@pytest.mark.parametrize("damage", [d[1] for d in DAMAGES], ids=[d[0] for d in DAMAGES])
def test_damaged_entry_is_rebuilt_with_one_warning(damage, env, surface, tmp_path, caplog):
    s0, hit = cache.load_or_build(env, AGENT, tmp_path)
    p = cache.cache_path(tmp_path, env, AGENT)
    good = p.read_bytes()
    bad = damage(good)
    assert bad != good
    p.write_bytes(bad)
    _check_heals(env, surface, tmp_path, p, caplog)


@pytest.mark.parametrize("case", ["no-meta", "meta-not-json", "short-heights", "half-the-links",
                                  "missing-normals", "wrong-checksum", "column-index"])
def test_inconsistent_entry_is_rebuilt_with_one_warning(case, env, surface, tmp_path, caplog):
    p = cache.cache_path(tmp_path, env, AGENT)
    p.write_bytes(_bad_entries(surface, tmp_path)[case])
    _check_heals(env, surface, tmp_path, p, caplog)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_an_entry_that_is_a_fifo_is_rebuilt_not_waited_for(env, surface, tmp_path, caplog):
    """A FIFO in an entry's place: opening it to read waited for a writer for ever (the bake
    hung in its navmesh stage); it is a damaged entry, replaced by a file."""
    p = cache.cache_path(tmp_path, env, AGENT)
    os.mkfifo(p)
    _check_heals(env, surface, tmp_path, p, caplog)
    assert p.is_file()


def _check_heals(env, surface, folder, p, caplog):
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        s, hit = cache.load_or_build(env, AGENT, folder)
    assert not hit
    warns = warnings_of(caplog)
    assert len(warns) == 1 and "damaged" in warns[0].getMessage(), [w.getMessage() for w in warns]
    same_surface(s, surface)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        s2, hit2 = cache.load_or_build(env, AGENT, folder)
    assert hit2 and not warnings_of(caplog)          # healed: the entry was rewritten
    same_surface(s2, surface)
    assert sorted(x.name for x in folder.iterdir()) == [p.name]     # no temporaries


def test_entry_of_an_older_layout_is_replaced_silently(env, tmp_path, caplog):
    p = cache.cache_path(tmp_path, env, AGENT)
    p.write_bytes(_npz({"format_version": np.asarray(3), "positions": np.zeros((2, 3))}))
    with caplog.at_level(logging.WARNING):
        s, hit = cache.load_or_build(env, AGENT, tmp_path)
    assert not hit
    assert len(warnings_of(caplog)) == 1          # no meta: treated as damaged, rebuilt once


# ----------------------------------------------------------------------------- unwritable folder
def _unwritable_folders(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")
    return {"under-a-file": blocker / "cache", "is-a-file": blocker}


@pytest.mark.parametrize("kind", ["under-a-file", "is-a-file", "read-only"])
def test_unwritable_folder_bakes_on_with_one_warning(kind, env, surface, tmp_path, caplog):
    if kind == "read-only":
        if os.geteuid() == 0:
            pytest.skip("root writes into read-only folders")
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
    else:
        folder = _unwritable_folders(tmp_path)[kind]
    try:
        with caplog.at_level(logging.WARNING):
            for bounds in (None, ((0.0, -1.0, 0.0), (0.5, 1.0, 1.0)), None):
                s, hit = cache.load_or_build(env, AGENT, folder, bounds=bounds)
                assert not hit
        warns = warnings_of(caplog)
        assert len(warns) == 1 and "without the cache" in warns[0].getMessage(), warns
        same_surface(cache.load_or_build(env, AGENT, None)[0], surface)
    finally:
        if kind == "read-only":
            folder.chmod(0o755)


def test_failed_write_leaves_no_temporary(env, tmp_path, monkeypatch, caplog):
    def full(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(cache, "_write_entry", full)
    with caplog.at_level(logging.WARNING):
        cache.load_or_build(env, AGENT, tmp_path)
    assert list(tmp_path.iterdir()) == []
    assert len(warnings_of(caplog)) == 1


# ----------------------------------------------------------------------------- bounded
WINDOWS = [((0.0, -1.0, 0.0), (x, 1.0, 1.0)) for x in (0.4, 0.6, 0.8, 1.0)]


def _entry(folder, env, bounds):
    return cache.cache_path(folder, env, AGENT, bounds)


def _age(paths, start=1_000_000.0):
    """Give paths increasing mtimes (oldest first), one hour apart."""
    for i, p in enumerate(paths):
        os.utime(p, (start + 3600 * i, start + 3600 * i))


def test_least_recently_used_entries_are_evicted(env, tmp_path):
    probe = tmp_path / "probe"
    sizes = []
    for b in WINDOWS:
        cache.load_or_build(env, AGENT, probe, bounds=b)
        sizes.append(_entry(probe, env, b).stat().st_size)
    folder = tmp_path / "c"
    unbounded = NavCache(folder)
    for b in WINDOWS[:3]:
        cache.load_or_build(env, AGENT, unbounded, bounds=b)
    e = [_entry(folder, env, b) for b in WINDOWS]
    _age(e[:3])
    # a hit makes window 0 the most recently used
    s, hit = cache.load_or_build(env, AGENT, unbounded, bounds=WINDOWS[0])
    assert hit
    # room for about three entries: writing a fourth evicts the least recently used, window 1
    bound = NavCache(folder, max_bytes=sizes[0] + sizes[2] + sizes[3] + min(sizes) // 2)
    assert bound.max_bytes < sum(sizes)
    cache.load_or_build(env, AGENT, bound, bounds=WINDOWS[3])
    assert [p.exists() for p in e] == [True, False, True, True]
    total = sum(p.stat().st_size for p in folder.glob("navsurface-*.npz"))
    assert total <= bound.max_bytes


@pytest.mark.parametrize("max_mb", [0.0, 1e-6])
def test_a_bound_below_one_entry_keeps_nothing(env, tmp_path, max_mb):
    c = NavCache.of(tmp_path, max_mb)
    s, hit = cache.load_or_build(env, AGENT, c)
    assert not hit and list(tmp_path.glob("navsurface-*")) == []
    s, hit = cache.load_or_build(env, AGENT, c)
    assert not hit


def test_stale_temporaries_are_removed_fresh_ones_kept(env, tmp_path):
    stale = tmp_path / ".navsurface-abc.tmp12345678.npz"
    fresh = tmp_path / ".navsurface-def.tmp87654321.npz"
    for p in (stale, fresh):
        p.write_bytes(b"partial")
    os.utime(stale, (time.time() - 2 * cache.STALE_TMP_S,) * 2)
    cache.load_or_build(env, AGENT, tmp_path)
    assert not stale.exists() and fresh.exists()


def test_default_bound():
    assert NavCache.of("x").max_bytes == int(cache.DEFAULT_MAX_MB * 2 ** 20)
    assert NavCache.of(NavCache.of("x"), 5).max_bytes == 5 * 2 ** 20
    assert NavCache.of(None, 5) is None


def test_entries_are_valid_zip_files(env, tmp_path):
    cache.load_or_build(env, AGENT, tmp_path)
    with zipfile.ZipFile(cache.cache_path(tmp_path, env, AGENT)) as z:
        assert z.testzip() is None
        assert "meta.npy" in z.namelist()
