"""The simulation and its metrics without the files: for tests judged by where the creature
goes and how its feet move (steps 1, 2, 4 and 6 of pipeline.bake; the clip, its reduction and
the files are tested elsewhere, and they cost as much again over a long bake)."""

from __future__ import annotations

from baker.config import BakeConfig, validate_bake
from baker.context import Context


def simulated(cfg: BakeConfig):
    """(trajectory, the report's `metrics`) of a lone creature's bake of `cfg`, in the
    environment's local frame."""
    from baker.environment import load_environment
    from baker.pipeline import in_local_frame, measure, navigation_surface, simulate_creatures

    cfg = validate_bake(cfg)
    env = load_environment(cfg.environment, sun_override=cfg.sun_direction)
    run_cfg = in_local_frame(cfg, env.origin)
    nav, _ = navigation_surface(run_cfg, env)
    traj = simulate_creatures(run_cfg, env, nav, Context())[0]
    return traj, measure(cfg, traj, env, nav)
