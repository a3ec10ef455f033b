"""The run stage's fixed-step loop for one creature. Phases, in order, every step:
1. brain   — perception and decisions, given as this step's Intent (behaviour.intent);
2. agent   — the follower applies the Intent (a new goal: a new path) and the navigation agent
             moves along its path (run/follow.py);
3. head    — the head follows the agent on the walkable surface, with the slither; its
             position extends the head path;
4. prey    — every prey wanders or flees from the head.
The drives and the prey are sampled at every exported frame into a RunRecord (record.py); the
solve stage (baker/solve) places the body, legs and prey from it.
"""

from __future__ import annotations

import numpy as np

from baker.behaviour.brain import Brain, Senses
from baker.behaviour.perception import in_shade
from baker.behaviour.prey import Prey
from baker.behaviour.sun import sun_path
from baker.config import BakeConfig, parse_sun_path
from baker.context import Context
from baker.run.follow import Follower
from baker.run.record import Recorder, RunRecord
from baker.run.start import choose_start, spawn_prey, tail_reach
from baker.streams import Streams


#: [body lengths] the straight line the body lies on at the start: the body, and behind the
#: tail three times the reach of the trail's rounding (body.ROUND spacings), which pulls a
#: line's ends in; the tail never runs off the trail's start, whatever the ground does
START_LINE = 1.3


def run(cfg: BakeConfig, env, nav, streams: Streams, ctx: Context, intent=None) -> RunRecord:
    """Run the bake's creature for cfg.seconds at cfg.sim_rate and record it.

    streams : the bake's random streams (baker.streams): the start, the brain and each prey
              draw from their own, so one subsystem's draws never shift another's.
    intent  : None lets the brain decide (behaviour.brain.Brain); otherwise a scripted source of
              Intents (behaviour.script.ScriptedIntent) takes its place, and no prey are
              spawned. Its `chain_period` (seconds or None) is passed on to the solve stage.
    """
    rig = cfg.rig
    body = rig.body
    start, heading = choose_start(nav, env, body.length, streams.get("start"), cfg.start,
                                  cfg.start_heading, spread=rig.wander.radius,
                                  tail=tail_reach(rig))
    follow = Follower(nav, env.rays, start, heading, rig, fps=cfg.fps)
    sun = make_sun(cfg, env)
    if intent is None:
        preys = make_prey(cfg, env, nav, streams, sun, start)
        brain = Brain(rig, nav, env.rays, sun, streams.get("brain"), preys, mode=cfg.behaviour,
                      cobra_mode=cfg.cobra)
    else:
        preys, brain = [], intent
    clock = Clock(cfg)
    heads = np.empty((clock.n_steps + 1, 3))
    heads[0] = start
    rec = Recorder(clock.n_frames, len(preys))
    ramp = clock.dt / rig.cobra.ramp_time
    want = brain.intent()
    cobra = want.cobra
    rec.sample(0, want, preys, cobra, follow.head.phase)
    for k in range(1, clock.n_steps + 1):
        t = (k - 1) * clock.dt
        # 1. brain: perception, the d10, hunting
        want = brain.step(Senses(t, follow.position, follow.head.heading, follow.agent.arrived))
        # 2.-3. a new goal means a new path; the agent walks it and the head follows it
        follow.apply(want)
        follow.step(clock.dt)
        head = heads[k]
        head[:] = follow.position
        # 4. prey react to the head
        for p in preys:
            p.step(t, clock.dt, head)
        cobra += max(-ramp, min(ramp, want.cobra - cobra))
        if k % clock.per_frame == 0:
            rec.sample(k // clock.per_frame, want, preys, cobra, follow.head.phase)
        if k % 2400 == 0:
            ctx.report_progress("simulate", k / clock.n_steps)
    events = brain.finish(cfg.seconds)
    return record(clock, nav, rig, start, heading, heads, rec, preys, sun, events,
                  getattr(intent, "chain_period", None), follow.replans)


class Clock:
    """The fixed step: dt [s], n_steps, per_frame (steps per exported frame), n_frames."""

    def __init__(self, cfg: BakeConfig):
        self.fps, self.sim_rate = cfg.fps, cfg.sim_rate
        self.dt = 1.0 / cfg.sim_rate
        self.n_steps = int(round(cfg.seconds * cfg.sim_rate))
        self.per_frame = cfg.sim_rate // cfg.fps
        self.n_frames = self.n_steps // self.per_frame + 1


def make_sun(cfg: BakeConfig, env):
    """The bake's sun path (--sun-path keys, else the environment's light and its turning)."""
    return sun_path(parse_sun_path(cfg.sun_path) if cfg.sun_path else None, env.sun.direction,
                    cfg.seconds, env.sun.azimuth_rate)


def make_prey(cfg: BakeConfig, env, nav, streams: Streams, sun, start) -> list[Prey]:
    """The bake's prey: at --prey-positions, else cfg.prey spawned around `start`; under cover
    where the sun is blocked a body clearance above the ground."""
    clearance = cfg.rig.body.clearance

    def in_cover(t, p):
        return bool(in_shade(env.rays, p, sun.at(t), clearance)[0])

    if cfg.prey_positions:
        return [Prey(i, nav.nearest(p, np.inf), cfg.rig.prey, nav, streams.get("prey", i),
                     in_cover) for i, p in enumerate(cfg.prey_positions)]
    return spawn_prey(cfg.prey, start, nav, cfg.rig, streams,
                      lambda p: in_shade(env.rays, p, sun.at(0.0), clearance), in_cover)


def start_line(nav, rig, start: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(n, 3) the straight line START_LINE body lengths behind the start, a point a spacing
    (tail end first, without the head's point), put on the layer nearest the start's height,
    never one a free agent height above or below."""
    body, navc = rig.body, rig.navigation
    n = int(round(START_LINE * body.segments)) + 1
    tail = start[None, :] - heading[None, :] * np.linspace(body.length * START_LINE, 0, n)[:, None]
    line = tail[:-1].copy()
    h = nav.surface_height(line, tol=0.5 * navc.height)
    line[np.isfinite(h), 1] = h[np.isfinite(h)]
    return line


def record(clock: Clock, nav, rig, start, heading, heads, rec: Recorder, preys, sun, events,
           chain_period, replans) -> RunRecord:
    """Pack one creature's run."""
    times = np.arange(0, clock.n_steps + 1, clock.per_frame) * clock.dt
    return RunRecord(
        fps=clock.fps, sim_rate=clock.sim_rate, start=start, heading=heading,
        start_line=start_line(nav, rig, start, heading), heads=heads, cobra=rec.cobra,
        warning=rec.warning, slither=rec.slither, sun_directions=sun.at(times),
        prey_names=tuple(p.name for p in preys), prey_positions=rec.prey_pos,
        prey_modes=rec.prey_mode, events=events, chain_period=chain_period, replans=replans)
