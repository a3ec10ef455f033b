"""The run stage for a crowd: N creatures stepped in lockstep at the simulation rate, each with
its own random streams (Streams(seed, creature=i)), sharing the sun, the prey and the claims
on shade spots and prey (behaviour.claims: a spot holds one creature, a prey has one hunter).

Local avoidance: every AVOID_EVERY steps one cKDTree holds every creature's body points (its
head and its head path sampled a spacing apart over a body length, the straight start line
before it has walked one) and one ball query finds, for all heads at once, the other
creatures' points near each. Each head then treats those points as obstacles on its walkable
surface, keeping `separation` metres from them (run.follow.Follower._avoiding): it turns or
slides along another body as it does along an edge. A body only ever lies on its own head's
path, so a head that never comes within `separation` of another body keeps the bodies apart.
"""

from __future__ import annotations

import logging

import numpy as np

from scipy.spatial import cKDTree

from baker.behaviour.brain import Brain, Senses
from baker.behaviour.claims import Claims
from baker.config import BakeConfig
from baker.context import Context
from baker.run.follow import Follower
from baker.run.loop import Clock, make_prey, make_sun, record, start_line
from baker.run.record import Recorder, RunRecord
from baker.run.start import choose_start, middle_anchor
from baker.streams import Streams

log = logging.getLogger(__name__)

#: steps between neighbour queries (the body points change as the heads move on)
AVOID_EVERY = 4
#: start draws per creature before the one farthest from the others is taken
START_TRIES = 48


def crowd_separation(rig) -> float:
    """[m] how far a head keeps from other creatures' body points: two agent radii (the
    agent radius covers the body and most of the legs' reach)."""
    return 2.0 * rig.navigation.radius


def crowd_starts(nav, env, rig, streams: list[Streams], separation: float, at=None,
                 heading=None):
    """A start (point, heading) per creature whose straight start body line keeps `separation`
    from every earlier creature's: draws from the creature's own start stream, near the middle
    of the scene and farther out as draws fail (the first creature's first draw is a lone
    creature's start; `at` and `heading`, the bake's --start, apply to it alone).
    returns [(start (3,), heading (3,))]"""
    length = rig.body.length
    back = np.linspace(length * 1.05, 0, 22)
    taken = np.zeros((0, 2))
    out = []
    anchor = middle_anchor(nav, env)
    for st in streams:
        rng = st.get("start")
        tree = cKDTree(taken) if len(taken) else None
        best, best_gap = None, -1.0
        for attempt in range(START_TRIES):
            first = not out and attempt == 0
            start, head = choose_start(nav, env, length, rng, at if first else None,
                                       heading if first else None,
                                       spread=rig.wander.radius * (1.0 + attempt / 4.0),
                                       extent_frac=0.2 + 0.3 * attempt / START_TRIES,
                                       anchor=anchor)
            line = (start[None, :] - head[None, :] * back[:, None])[:, [0, 2]]
            gap = np.inf if tree is None else float(tree.query(line)[0].min())
            if gap > best_gap:
                best, best_gap = (start, head, line), gap
            if gap >= separation:
                break
        if best_gap < separation:
            log.warning("creature %d starts %.3f m from another (wanted %.3f m)", len(out),
                        best_gap, separation)
        out.append(best[:2])
        taken = np.vstack([taken, best[2]])
    return out


class Bodies:
    """Every creature's head path (after its start line) and its arc length, and the body
    points sampled from them for the neighbour query."""

    def __init__(self, lines: list[np.ndarray], n_steps: int, spacing: float, segments: int):
        n, m = len(lines), len(lines[0])
        self.m = m
        self.path = np.zeros((n, m + n_steps + 1, 2))
        self.cum = np.zeros((n, m + n_steps + 1))
        for i, line in enumerate(lines):
            self.path[i, :m] = line[:, [0, 2]]
            d = np.hypot(*np.diff(line[:, [0, 2]], axis=0).T)
            self.cum[i, 1:m] = np.cumsum(d)
        self.back = spacing * np.arange(segments + 1)

    def advance(self, k: int, heads: np.ndarray) -> None:
        """Step k's heads (n, 3), for all creatures at once."""
        j = self.m + k
        xz = heads[:, [0, 2]]
        self.cum[:, j] = self.cum[:, j - 1] + np.hypot(*(xz - self.path[:, j - 1]).T)
        self.path[:, j] = xz

    def points(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(n * (segments + 1), 2) body points after step k and (same,) their creature."""
        j = self.m + k
        out = np.empty((len(self.path), len(self.back), 2))
        for i in range(len(self.path)):
            cum = self.cum[i, :j + 1]
            idx = np.searchsorted(cum, cum[-1] - self.back).clip(0, j)
            out[i] = self.path[i, idx]
        return out.reshape(-1, 2), np.repeat(np.arange(len(self.path)), len(self.back))


def run_crowd(cfg: BakeConfig, env, nav, seed: int, n: int, ctx: Context,
              separation: float | None = None) -> tuple[list[RunRecord], dict]:
    """Run `n` creatures together. Returns (one RunRecord per creature, the prey's record:
    dict(prey_names, prey_positions (F, P, 3), prey_modes (F, P) int8, prey_holder (F, P) int,
    the creature whose head holds each prey, -1 for none)). The prey are the bake's
    (cfg.prey, spawned around creature 0 from its prey streams, as for a lone creature)."""
    rig = cfg.rig
    sep = crowd_separation(rig) if separation is None else float(separation)
    streams = [Streams(seed, creature=i) for i in range(n)]
    starts = crowd_starts(nav, env, rig, streams, sep, cfg.start, cfg.start_heading)
    sun = make_sun(cfg, env)
    claims = Claims(rig.behaviour.shade_spot_spacing)
    follows = [Follower(nav, env.rays, s, h, rig, fps=cfg.fps) for s, h in starts]
    for f in follows:
        f.separation = sep
    preys = make_prey(cfg, env, nav, streams[0], sun, starts[0][0])
    brains = [Brain(rig, nav, env.rays, sun, st.get("brain"), preys, mode=cfg.behaviour,
                    cobra_mode=cfg.cobra, claims=claims, who=i) for i, st in enumerate(streams)]
    clock = Clock(cfg)
    lines = [start_line(nav, rig, s, h) for s, h in starts]
    bodies = Bodies(lines, clock.n_steps, rig.body.spacing, rig.body.segments)
    heads = np.empty((n, clock.n_steps + 1, 3))
    heads[:, 0] = [s for s, _ in starts]
    bodies.advance(0, heads[:, 0])
    recs = [Recorder(clock.n_frames, 0) for _ in range(n)]
    prey_rec = Recorder(clock.n_frames, len(preys))
    holder = np.full((clock.n_frames, len(preys)), -1)
    ramp = clock.dt / rig.cobra.ramp_time
    wants = [b.intent() for b in brains]
    cobra = np.array([w.cobra for w in wants])
    sample(0, recs, prey_rec, holder, wants, preys, brains, cobra, follows)
    reach = sep + 0.25 * max(f.turn_radius for f in follows) + 4.0 * AVOID_EVERY * clock.dt * (
        rig.locomotion.max_speed * rig.behaviour.onslaught_speed)
    for k in range(1, clock.n_steps + 1):
        t = (k - 1) * clock.dt
        if (k - 1) % AVOID_EVERY == 0 and n > 1:
            neighbours(bodies, k - 1, heads[:, k - 1], follows, reach)
        for i in range(n):
            f = follows[i]
            wants[i] = brains[i].step(Senses(t, f.position, f.head.heading, f.agent.arrived))
            f.apply(wants[i])
            f.step(clock.dt)
            heads[i, k] = f.position
        bodies.advance(k, heads[:, k])
        if preys:
            step_prey(preys, t, clock.dt, heads[:, k])
        cobra += np.clip(np.array([w.cobra for w in wants]) - cobra, -ramp, ramp)
        if k % clock.per_frame == 0:
            sample(k // clock.per_frame, recs, prey_rec, holder, wants, preys, brains, cobra,
                   follows)
        if k % 2400 == 0:
            ctx.report_progress("simulate", k / clock.n_steps)
    out = [record(clock, nav, rig, s, h, heads[i], recs[i], [], sun,
                  brains[i].finish(cfg.seconds), None, follows[i].replans)
           for i, (s, h) in enumerate(starts)]
    return out, dict(prey_names=tuple(p.name for p in preys), prey_positions=prey_rec.prey_pos,
                     prey_modes=prey_rec.prey_mode, prey_holder=holder)


def neighbours(bodies: Bodies, k: int, heads: np.ndarray, follows, reach: float) -> None:
    """Hand each follower the other creatures' body points within `reach` of its head (one
    tree, one ball query for all heads)."""
    pts, owner = bodies.points(k)
    tree = cKDTree(pts)
    near = tree.query_ball_point(heads[:, [0, 2]], reach)
    for i, idx in enumerate(near):
        idx = np.asarray(idx, dtype=np.intp)
        idx = idx[owner[idx] != i]
        follows[i].others = pts[idx] if len(idx) else None


def step_prey(preys, t: float, dt: float, heads: np.ndarray) -> None:
    """Every prey reacts to the nearest head."""
    for p in preys:
        d = np.hypot(heads[:, 0] - p.position[0], heads[:, 2] - p.position[2])
        p.step(t, dt, heads[int(np.argmin(d))])


def sample(f: int, recs, prey_rec: Recorder, holder, wants, preys, brains, cobra, follows):
    """Frame f of every creature's drives, the prey and which head holds each prey."""
    for i, rec in enumerate(recs):
        rec.sample(f, wants[i], (), float(cobra[i]), follows[i].head.phase)
    prey_rec.sample(f, wants[0], preys, 0.0)
    for i, b in enumerate(brains):
        if b.prey is not None:
            holder[f, preys.index(b.prey)] = i
