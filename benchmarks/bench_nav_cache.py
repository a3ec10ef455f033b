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
    with tempfile.TemporaryDirectory() as tmp:
        old, new = Path(tmp) / "raw.npz", Path(tmp) / "compact.npz"
        rows = []
        for name, path, save, load in (("raw (before)", old, save_raw, load_raw),
                                       ("compact (now)", new, cache.save,
                                        lambda p: cache.load(p, strict=True))):
            t_save = timed(lambda: save(s, path), max(1, args.runs // 3))
            load(path)
            t_warm = timed(lambda: load(path), args.runs)
            cold = drop_page_cache(path)
            t_cold = timed(lambda: load(path), max(1, args.runs // 3),
                           before=lambda: drop_page_cache(path)) if cold else float("nan")
            rows.append((name, path.stat().st_size / 1e6, t_save, t_warm, t_cold))
    print(f"  {'entry':<14} {'size':>9} {'save':>8} {'load (page cache)':>18} {'load (disk)':>12}")
    for name, mb, ts, tw, tc in rows:
        print(f"  {name:<14} {mb:7.1f} MB {ts:6.2f} s {tw:16.3f} s {tc:10.3f} s")
    print(f"  size ratio {rows[0][1] / rows[1][1]:.1f}x smaller")


if __name__ == "__main__":
    main()
