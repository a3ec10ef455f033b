"""On-disk cache of built navigation surfaces (.npz), keyed by the environment's content hash,
the agent parameters, the build bounds and the format version."""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

from baker.atomic import atomic_output
from baker.navmesh.surface import FORMAT_VERSION, NavSurface

log = logging.getLogger(__name__)


def cache_key(env, agent, bounds=None) -> str:
    """Hex key of (environment content, agent parameters, bounds, format version)."""
    params = {
        "env": env.content_hash,
        "agent": {k: float(v) for k, v in sorted(asdict(agent).items())},
        "bounds": None if bounds is None else np.asarray(bounds, float).round(9).tolist(),
        "version": FORMAT_VERSION,
    }
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:32]


def cache_path(cache_dir, env, agent, bounds=None) -> Path:
    return Path(cache_dir) / f"navsurface-{cache_key(env, agent, bounds)}.npz"


def save(surface: NavSurface, path) -> Path:
    """Write `surface` to `path` (.npz) atomically (temporary file + os.replace)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(v) for k, v in surface.arrays().items()}
    arrays["format_version"] = np.asarray(FORMAT_VERSION)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return path


def load(path) -> NavSurface | None:
    """Read a surface saved by `save`; None when the file is missing, unreadable or of another
    format version."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if int(z["format_version"]) != FORMAT_VERSION:
                return None
            kw = {}
            for f in fields(NavSurface):
                if f.name == "_cache":
                    continue
                v = z[f.name]
                if f.name in ("origin", "shape"):
                    v = tuple(v.tolist())
                elif v.ndim == 0:
                    v = v.item()
                kw[f.name] = v
    except (OSError, KeyError, ValueError) as exc:
        if path.exists():
            log.warning("ignoring unreadable navigation cache %s: %s", path, exc)
        return None
    return NavSurface(**kw)


def load_or_build(env, agent, cache_dir=None, *, bounds=None, **build_kw) -> tuple[NavSurface, bool]:
    """(surface, from_cache): load the cached surface for (env, agent, bounds) from cache_dir,
    or build it (and save it there when cache_dir is given)."""
    from baker.navmesh.build import build

    if cache_dir is None:
        return build(env, agent, bounds=bounds, **build_kw), False
    p = cache_path(cache_dir, env, agent, bounds)
    s = load(p)
    if s is not None:
        log.info("navigation surface loaded from cache %s", p)
        return s, True
    s = build(env, agent, bounds=bounds, **build_kw)
    try:
        save(s, p)
    except OSError as exc:
        log.warning("cannot write navigation cache %s: %s", p, exc)
    return s, False
