"""Navigation cache entry: size, save and load time, the compact layout (navmesh/cache.py)
against every array stored raw (the layout before issue 11), for the default scene.

Loads are timed with the file in the page cache (the usual warm bake) and, where the machine
lets us drop it (`os.posix_fadvise(..., POSIX_FADV_DONTNEED)`), from disk. Run from the repo
root:  python benchmarks/bench_nav_cache.py [--runs 7] [--env PATH]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

from baker.config import DEFAULT_ENVIRONMENT, DEFAULT_RIG, load_rig_config
from baker.environment import load_environment
from baker.navmesh import build, cache
from baker.navmesh.surface import FORMAT_VERSION, NavSurface


def save_raw(surface: NavSurface, path: Path) -> None:
    """The layout before issue 11: every array as it is, uncompressed."""
    arrays = {k: np.asarray(v) for k, v in surface.arrays().items()}
    arrays["format_version"] = np.asarray(FORMAT_VERSION)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def load_raw(path: Path) -> NavSurface:
    with np.load(path, allow_pickle=False) as z:
        kw = {}
        for f in fields(NavSurface):
            if f.name == "_cache":
                continue
            v = z[f.name]
            kw[f.name] = tuple(v.tolist()) if f.name in ("origin", "shape") else (
                v.item() if v.ndim == 0 else v)
    return NavSurface(**kw)


def drop_page_cache(path: Path) -> bool:
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)
        return True
    except (AttributeError, OSError):
        return False


def timed(f, runs: int, before=None) -> float:
    ts = []
    for _ in range(runs):
        if before:
            before()
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--env", type=Path, default=DEFAULT_ENVIRONMENT)
    args = ap.parse_args()
    env = load_environment(args.env)
    agent = load_rig_config(DEFAULT_RIG).navigation
    t = time.perf_counter()
    s = build(env, agent)
    print(f"{args.env.name}: {s.n_samples:,} samples, grid {s.shape[0]} x {s.shape[1]}, "
          f"built in {time.perf_counter() - t:.2f} s; {args.runs} runs, medians")
    variants = [("raw (before)", save_raw, load_raw)]
    for label, raw in (("compact", ()), ("links raw", ("link_offsets",)),
                       ("links+normals raw", ("link_offsets", "normals"))):
        tag = " (now)" if frozenset(raw) == cache.RAW_MEMBERS else ""
        variants.append((label + tag, lambda surf, p, raw=raw: _save(surf, p, raw),
                         lambda p: cache.load(p, strict=True)))
    with tempfile.TemporaryDirectory() as tmp:
        paths = [Path(tmp) / f"v{i}.npz" for i in range(len(variants))]
        saves = []
        for (name, save, load), path in zip(variants, paths):
            saves.append(timed(lambda: save(s, path), max(1, args.runs // 3)))
            load(path)
        # loads round-robin, so every variant sees the same machine load
        warm = [[] for _ in variants]
        disk = [[] for _ in variants]
        for _ in range(args.runs):
            for i, ((name, save, load), path) in enumerate(zip(variants, paths)):
                warm[i].append(timed(lambda: load(path), 1))
                if drop_page_cache(path):
                    disk[i].append(timed(lambda: load(path), 1))
        print(f"  {'entry':<24} {'size':>9} {'save':>8} {'load (page cache)':>18} {'load (dropped)':>15}")
        med = statistics.median
        for i, (name, _, _) in enumerate(variants):
            print(f"  {name:<24} {paths[i].stat().st_size / 1e6:7.1f} MB {saves[i]:6.2f} s "
                  f"{med(warm[i]):16.3f} s {med(disk[i]) if disk[i] else float('nan'):13.3f} s")


def _save(surface, path, raw):
    members = cache.encode(surface, raw=raw)
    with open(path, "wb") as fh:
        np.savez(fh, **members)


if __name__ == "__main__":
    main()
