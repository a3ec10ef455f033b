"""The JSON report and the metadata embedded in the GLB/USD (glTF extras, USD customData)."""

from __future__ import annotations

import dataclasses
import json
import math
import platform
from importlib import metadata
from pathlib import Path

import numpy as np

import baker

PACKAGES = ("numpy", "scipy", "trimesh", "embreex", "pygltflib", "usd-core", "click")


def jsonable(obj):
    """Plain JSON types from dataclasses, numpy values, paths and tuples."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, Path):
        return obj.as_posix()
    return obj


def rig_summary(rig_cfg) -> dict:
    """The resolved rig (metres, seconds, radians), as embedded in every output."""
    return jsonable(rig_cfg)


#: Keys of a timeline event's details that hold a position (3 numbers, metres).
POSITION_KEYS = ("target", "spot", "position")


def world_events(events, origin) -> list:
    """Timeline events {start, end, state, details} with the positions in their details moved
    from the environment's local frame to world (plus origin (3,) float64, metres; rounded to
    0.1 mm like the brain's own)."""
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    out = []
    for e in events:
        d = dict(e.get("details") or {})
        for k in POSITION_KEYS:
            v = d.get(k)
            if isinstance(v, (list, tuple, np.ndarray)) and len(v) == 3:
                d[k] = [round(float(x) + float(y), 4) for x, y in zip(v, o)]
        out.append({**e, "details": d} if "details" in e else dict(e))
    return out


def extras(cfg, traj, origin=(0.0, 0.0, 0.0)) -> dict:
    """Deterministic metadata for glTF extras / USD customData (no timings, no versions).
    origin : (3,) float64 metres, world position of the trajectory's frame (env.origin)."""
    return {
        "generator": f"baker {baker.__version__}",
        "seed": int(cfg.seed),
        "fps": int(cfg.fps),
        "seconds": float(cfg.seconds),
        "root_motion": str(cfg.root_motion),
        "rig": rig_summary(cfg.rig),
        "timeline": jsonable(world_events(traj.events, origin)),
        "foot_contacts": foot_contacts(traj, cfg.rig),
    }


def creature_entries(cfg, trajs, origin, motions=None, animations=None) -> list[dict]:
    """One entry per creature of a crowd (`--creatures N`), creature 0 first: {index, name (its
    placement node / SkelRoot), joint_prefix (of its glTF joint names), timeline (world)}, and
    either its foot_contacts (the files' extras, as the lone creature's `foot_contacts`) or,
    with `motions` / `animations` (the report), its `metrics` and its keyframe reduction's
    `animation`. A lone creature's files and report have no such list."""
    from baker.export import creature_label

    out = []
    for i, traj in enumerate(trajs):
        name, prefix = creature_label(i, len(trajs))
        entry = {"index": i, "name": name, "joint_prefix": prefix,
                 "timeline": jsonable(world_events(traj.events, origin))}
        if motions is not None:
            entry["metrics"] = jsonable(motions[i])
        if animations is not None:
            entry["animation"] = jsonable(animations[i])
        if motions is None:
            entry["foot_contacts"] = foot_contacts(traj, cfg.rig)
        out.append(entry)
    return out


def foot_contacts(traj, rig_cfg) -> dict:
    """Planted intervals per walking leg, keyed by the leg's foot joint (its end joint at the
    contact point), as inclusive [first, last] frame pairs:
    {"leg_L_01_foot": [[0, 11], [19, 30], ...], ...} (legs ordered L_01, R_01, L_02, ...)."""
    from baker.rig.limbs import leg_layout

    c = traj.foot_contacts
    if c is None:
        return {}
    c = np.asarray(c, dtype=bool)
    feet = leg_layout(rig_cfg).foot_names
    if len(feet) != c.shape[1]:
        from baker.errors import ExportError

        raise ExportError(f"foot contacts for {c.shape[1]} legs, the rig has {len(feet)}")
    out = {}
    for k, name in enumerate(feet):
        d = np.diff(np.concatenate([[0], c[:, k].astype(np.int8), [0]]))
        starts, ends = np.nonzero(d == 1)[0], np.nonzero(d == -1)[0] - 1
        out[name] = [[int(a), int(b)] for a, b in zip(starts, ends)]
    return out


def package_versions() -> dict:
    out = {"python": platform.python_version(), "baker": baker.__version__}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def navmesh_stats(nav, origin) -> dict:
    """The navigation surface's stats, with its lazy windows ((x0, z0, x1, z1) metres) in
    world coordinates."""
    stats = dict(nav.stats()) if callable(getattr(nav, "stats", None)) else {}
    if "lazy_windows" in stats:
        ox, oz = float(origin[0]), float(origin[2])
        stats["lazy_windows"] = [[round(w[0] + ox, 6), round(w[1] + oz, 6), round(w[2] + ox, 6),
                                  round(w[3] + oz, 6)] for w in stats["lazy_windows"]]
    return stats


def build_report(cfg, env, nav, traj, motion: dict, ctx, written: dict) -> dict:
    """The JSON report. Positions (environment bounds, timeline targets and spots, lazy
    navigation windows) are world coordinates; `environment.origin` is the local frame the
    simulation ran in."""
    return jsonable({
        "baker_version": baker.__version__,
        "seed": cfg.seed,
        "parameters": {
            "environment": str(cfg.environment),
            "seconds": cfg.seconds,
            "fps": cfg.fps,
            "sim_rate_hz": cfg.sim_rate,
            "prey": cfg.prey,
            "creatures": cfg.creatures,
            "behaviour": cfg.behaviour,
            "cobra": cfg.cobra,
            "formats": list(cfg.formats),
            "sun_direction": env.sun.direction,
            "rig": rig_summary(cfg.rig),
        },
        "environment": {
            "source": env.source,
            "up_axis": cfg.up_axis,     # None: the file's own
            "units": cfg.units,         # None: the file's own
            "meshes": len(env.meshes),
            "triangles": int(len(env.mesh.faces)),
            "bounds": env.bounds + env.origin,
            "origin": env.origin,
            "content_hash": env.content_hash,
        },
        "navmesh": navmesh_stats(nav, env.origin),
        "navmesh_cache_hit": ctx.notes.get("navmesh_cache_hit"),
        "path_replans": ctx.notes.get("path_replans"),
        "versions": package_versions(),
        "timings_s": {k: round(v, 4) for k, v in ctx.timings.items()},
        "metrics": motion,
        "timeline": world_events(traj.events, env.origin),
        "outputs": {k: str(v) for k, v in written.items()},
    })


def to_json_bytes(report: dict) -> bytes:
    return (json.dumps(report, indent=2, sort_keys=False, allow_nan=False) + "\n").encode()
