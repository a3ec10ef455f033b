"""The simulation's entry points: the run stage (baker/run, the 240 Hz loop of decisions and
paths), then the solve stage (baker/solve, the body, legs and prey for every frame)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baker.config import BakeConfig
from baker.context import Context
from baker.parallel import fork_map
from baker.run.crowd import run_crowd
from baker.run.loop import run
from baker.solve.solve import CrowdSpines, prey_frames, solve, solve_body, solve_limbs
from baker.solve.trajectory import Trajectory
from baker.streams import Streams


def simulate(cfg: BakeConfig, env, nav, streams: Streams, ctx: Context,
             intent=None) -> Trajectory:
    """Run the bake's creature, then solve its frames at the export fps.

    streams : the bake's random streams (baker.streams)
    intent  : None lets the brain decide; else a scripted source of Intents
              (behaviour.script.ScriptedIntent), and no prey (run.loop.run)
    """
    rec = run(cfg, env, nav, streams, ctx, intent)
    ctx.notes["path_replans"] = rec.replans
    return solve(rec, env.rays, cfg.rig)


def simulate_crowd(cfg: BakeConfig, env, nav, seed: int, n: int, ctx: Context,
                   workers: int = 1) -> list[Trajectory]:
    """Run `n` creatures together (run.crowd.run_crowd: their own streams, separate starts,
    local avoidance, one creature per shade spot, one hunter per prey), then solve each (on
    up to `workers` processes: baker.parallel.fork_map, the same bits as one): every body,
    then every creature's limbs beside the other bodies.
    The bake's prey ride on the first trajectory (each held at its hunter's head while fed
    on); the others have none. ctx.notes["path_replans"] lists every creature's replans."""
    recs, prey = run_crowd(cfg, env, nav, seed, n, ctx, workers=workers)
    ctx.notes["path_replans"] = [r.replans for r in recs]
    # the bodies first, then the limbs, whose ultimate legs and antennae raise clear of the
    # other bodies they reach (locomotion.near)
    bodies = fork_map(lambda i: solve_body(recs[i], env.rays, cfg.rig), n, workers)
    crowd = CrowdSpines(np.stack([bf.positions for bf, _ in bodies]))
    trajs = fork_map(lambda i: solve_limbs(recs[i], *bodies[i], env.rays, cfg.rig, crowd, i),
                     n, workers)
    if prey["prey_names"]:
        holder = prey["prey_holder"]                        # (F, P) creature or -1
        heads_p = np.stack([t.spine_positions[:, 0] for t in trajs])    # (n, F, 3)
        heads_q = np.stack([t.spine_rotations[:, 0] for t in trajs])
        f = np.arange(len(holder))[:, None]
        h = np.maximum(holder, 0)
        frames = prey_frames(prey["prey_names"], prey["prey_positions"], prey["prey_modes"],
                             heads_p[h, f], heads_q[h, f], env.rays, cfg.rig)
        trajs[0] = replace(trajs[0], **frames)
    return trajs
