"""The simulation's entry points: the run stage (baker/run, the 240 Hz loop of decisions and
paths), then the solve stage (baker/solve, the body, legs and prey for every frame)."""

from __future__ import annotations

from baker.config import BakeConfig
from baker.context import Context
from baker.run.loop import run
from baker.solve.solve import solve
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
