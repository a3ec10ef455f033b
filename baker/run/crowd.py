"""The run stage for a crowd: N creatures stepped in lockstep at the simulation rate, each with
its own random streams (Streams(seed, creature=i)), sharing the sun, the prey and the claims
on shade spots and prey (behaviour.claims: a spot holds one creature, a prey has one hunter).

Local avoidance: every AVOID_EVERY steps one cKDTree holds every creature's body points (its
head and its head path sampled a spacing apart over a body length, with the path's kinks
rounded as the body's trail rounds them, and the straight start line before it has walked
one) and one ball query finds, for all heads at once, the other creatures' points near each
(in plan; those higher or lower than the head by more than crowd_band are on another storey
and left out).
Each head then treats those points as obstacles on its walkable surface, keeping `separation`
metres from them (run.follow.Follower._surface_test): it turns or slides along another body as it
does along an edge. A body only ever lies on its own head's trail, so a head that never comes
within `separation` of another body keeps the bodies apart. A head the bodies corner while
their creatures walk holds still for them to move on (up to run.follow.HOLD_MAX) instead of
turning on the spot: a turn on the spot folds its trail into a cusp that its body's joints jump
across.

What the creatures measure on their own the same way every step is measured for all of them
at once before the step, in one surface query and one ray batch per kind: the legs' levers
(run.follow.measure_levers) and what the brains perceiving in that step sense
(behaviour.brain.sense_together); each creature checks that they were measured for what its
step reads, and the answers are the same bits as its own.

Each step the brains decide first, one after another (they share the claims), from every
follower's state after the last step (run.group.States); then the followers walk their
intents. With two or more workers (one per CPU, at least run.group.PER_PROCESS followers
each), the followers are dealt out among this process and forked peer processes, which step
their shares at once (run.group.Followers): the same bits as one process.
"""

from __future__ import annotations

import functools
import itertools
import logging
import math

import numpy as np

from scipy.spatial import cKDTree

from baker.behaviour.brain import Brain, Senses, sense_together
from baker.behaviour.claims import Claims
from baker.config import BakeConfig
from baker.context import Context
from baker.geometry.arrays import unique
from baker.locomotion.body import ROUND, chain_on, trail_ends
from baker.locomotion.cobra import lift_profile
from baker.locomotion.trail_kernels import first_at_or_above
from baker.navmesh.lazy import LazyNav
from baker.run.follow import Follower, turn_radius
from baker.run.group import Followers, States
from baker.run.loop import Clock, make_prey, make_sun, record, start_line
from baker.run.record import Recorder, RunRecord
from baker.run.start import (choose_start, full_behind, middle_anchor, start_score,
                              tail_reach)
from baker.streams import Streams

log = logging.getLogger(__name__)

#: steps between neighbour queries (the body points change as the heads move on)
AVOID_EVERY = 4
#: cobra lift profiles kept by amount (Bodies.lift)
LIFT_CACHE = 64
#: start draws per creature before the one farthest from the others is taken
START_TRIES = 48
#: walkable samples (evenly taken over the start's component) and headings a creature's
#: start is searched over when no draw keeps apart from the others (_free_start)
FREE_SAMPLES = 4096
FREE_HEADINGS = 16


def crowd_separation(rig) -> float:
    """[m] how far a head keeps from other creatures' body points: two agent radii (the
    agent radius covers the body and most of the legs' reach)."""
    return 2.0 * rig.navigation.radius


def crowd_band(rig, reach: float) -> float:
    """[m] how far above or below a head another body's points within `reach` of it can lie on
    the same walkable surface: the rise of the steepest walkable slope over `reach`, a step,
    a raised cobra's lift and an agent height to spare. Farther, they are on another storey
    (a floor above or below, a bridge over a passage) and not in the head's way."""
    nav = rig.navigation
    return (reach * math.tan(nav.max_slope) + nav.step_height + rig.cobra.height
            + nav.height)


def crowd_reach(rig, separation: float, dt: float) -> float:
    """[m] how far from a head the neighbour query looks for other bodies: `separation`, a
    quarter of the head's turning radius and how far the fastest head (an onslaught) walks
    between two queries."""
    return separation + 0.25 * turn_radius(rig) + 4.0 * AVOID_EVERY * dt * (
        rig.locomotion.max_speed * rig.behaviour.onslaught_speed)


def crowd_starts(nav, env, rig, streams: list[Streams], separation: float, at=None,
                 heading=None, band: float = np.inf):
    """A start (point, heading) per creature whose straight start body line keeps `separation`
    in plan from every earlier creature's on the same storey (within `band` above or below,
    crowd_band: the neighbour query's; a line on a floor above or below is not in the way):
    draws from the creature's own start stream, near the middle of the scene and farther out
    as draws fail (the first creature's first draw is a lone creature's start; `at` and
    `heading`, the bake's --start, apply to it alone).
    returns [(start (3,), heading (3,))]"""
    length = rig.body.length
    back = np.linspace(length * 1.05, 0, 22)
    taken = _Taken(band)
    out = []
    anchor = middle_anchor(nav, env)
    close = []                      # (creature, gap) of the starts nearer than `separation`
    for st in streams:
        rng = st.get("start")
        best, best_gap = None, -1.0
        for attempt in range(START_TRIES):
            first = not out and attempt == 0
            start, head = choose_start(nav, env, length, rng, at if first else None,
                                       heading if first else None,
                                       spread=rig.wander.radius * (1.0 + attempt / 4.0),
                                       extent_frac=0.2 + 0.3 * attempt / START_TRIES,
                                       anchor=anchor, tail=tail_reach(rig))
            line = start[None, :] - head[None, :] * back[:, None]
            gap = taken.gap(line, separation)
            if gap > best_gap:
                best, best_gap = (start, head, line), gap
            if gap >= separation:
                break
        # the draws found no room: search the whole level (once it has none, the creatures
        # after have none either)
        free = None
        if best_gap < separation and not close:
            free = _free_start(nav, anchor, length, back, taken, separation, tail_reach(rig))
        if best_gap < separation and free is None:
            close.append((len(out), best_gap))
        best = best if free is None else free
        out.append(best[:2])
        taken.add(best[2])
    if close:                       # one line, however many (a big crowd on a small level)
        log.warning("%d of %d creatures start nearer another than %.3f m (creature %d first; "
                    "the nearest %.3f m): the level has little room for them", len(close),
                    len(out), separation, close[0][0], min(g for _, g in close))
    return out


def _free_start(nav, anchor: np.ndarray, length: float, back: np.ndarray, taken: "_Taken",
                separation: float, tail: float = 0.0):
    """(start, heading, line) of a start that keeps `separation` from every line taken (on the
    same storey), or None: over FREE_SAMPLES walkable samples of the anchor's component and
    FREE_HEADINGS headings each, one whose straight body line behind is walkable all along
    (run.start.start_score), the most room ahead first, then the nearest the anchor. Where
    the draws near the middle found no room (a small level's few roomy spots, a tower's
    floors), this finds any that is left."""
    comp = nav.component_of(anchor)
    idx = np.flatnonzero(nav.component == comp)
    if not len(idx):
        return None
    idx = idx[np.unique(np.linspace(0, len(idx) - 1, min(len(idx), FREE_SAMPLES)).astype(int))]
    starts = nav.positions[idx].astype(np.float64)
    angles = np.linspace(0.0, 2.0 * np.pi, FREE_HEADINGS, endpoint=False)
    dirs = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1)
    score = start_score(nav, starts, dirs, length, tail)              # (k, headings)
    k, h = np.divmod(np.arange(score.size), FREE_HEADINGS)
    lines = starts[k][:, None, :] - dirs[h][:, None, :] * back[None, :, None]   # (c, m, 3)
    free = taken.clear(lines.reshape(-1, 3), separation).reshape(len(k), len(back)).all(axis=1)
    free &= score.reshape(-1) >= full_behind(tail)
    if not free.any():
        return None
    far = np.linalg.norm(starts[k] - anchor[None, :], axis=1)
    c = np.flatnonzero(free)
    c = c[np.lexsort((far[c], -score.reshape(-1)[c]))[0]]
    return starts[k[c]], dirs[h[c]], lines[c]


class _Taken:
    """The start lines of the creatures placed so far (crowd_starts): a tree over most of
    them (in plan), rebuilt as RECENT more points gather, and the newest measured one by one.
    Points more than `band` above or below a line's point are on another storey: not near it.
    """

    RECENT = 512

    def __init__(self, band: float = np.inf):
        self.band = float(band)
        self.points = np.zeros((0, 3))
        self.tree, self.in_tree = None, 0

    def add(self, line: np.ndarray) -> None:
        self.points = np.vstack([self.points, line])
        if len(self.points) - self.in_tree > self.RECENT:
            self.tree, self.in_tree = cKDTree(self.points[:, [0, 2]]), len(self.points)

    def gap(self, line: np.ndarray, limit: float = np.inf) -> float:
        """The least plan distance from a point of `line` (k, 3) to a point taken within
        `band` of its height, when under `limit` (inf: none nearer)."""
        plan = line[:, [0, 2]]
        gap = np.inf
        if self.tree is not None:
            near = self.tree.query_ball_point(plan, limit) if np.isfinite(limit) else [
                list(range(self.in_tree))] * len(line)
            lens = np.fromiter(map(len, near), np.intp, len(near))
            if lens.sum():
                idx = np.fromiter(itertools.chain.from_iterable(near), np.intp, int(lens.sum()))
                gap = _least(line[np.repeat(np.arange(len(line)), lens)], self.points[idx],
                             self.band, limit)
        recent = self.points[self.in_tree:]
        if len(recent):
            a = np.repeat(line, len(recent), axis=0)
            gap = min(gap, _least(a, np.tile(recent, (len(line), 1)), self.band, limit))
        return gap

    def clear(self, points: np.ndarray, separation: float) -> np.ndarray:
        """(n,) bool: no point taken within `band` of each point's height is nearer than
        `separation` to it in plan (points (n, 3))."""
        taken = self.points
        if not len(taken):
            return np.ones(len(points), bool)
        near = cKDTree(taken[:, [0, 2]]).query_ball_point(points[:, [0, 2]], separation)
        lens = np.fromiter(map(len, near), np.intp, len(near))
        idx = np.fromiter(itertools.chain.from_iterable(near), np.intp, int(lens.sum()))
        who = np.repeat(np.arange(len(points)), lens)
        d = np.hypot(points[who, 0] - taken[idx, 0], points[who, 2] - taken[idx, 2])
        close = (np.abs(points[who, 1] - taken[idx, 1]) <= self.band) & (d < separation)
        return np.bincount(who[close], minlength=len(points)) == 0


def _least(a: np.ndarray, b: np.ndarray, band: float, limit: float) -> float:
    """The least plan distance between paired points a[i], b[i] (m, 3) within `band` of each
    other's height and under `limit` (inf: none)."""
    d = np.sqrt((a[:, 0] - b[:, 0]) ** 2 + (a[:, 2] - b[:, 2]) ** 2)
    d = d[(np.abs(a[:, 1] - b[:, 1]) <= band) & (d < limit)]
    return float(d.min()) if len(d) else np.inf


def tail_points(rig) -> int:
    """Body points behind the last spine joint: out to the ultimate legs' reach behind it
    (their bones' length), at least one."""
    legs = rig.legs
    reach = legs.ultimate_upper + legs.ultimate_tip if legs.enabled else 0.0
    return max(1, int(np.ceil(reach / rig.body.spacing)))


class Bodies:
    """Every creature's head path (after its start line) and the body points sampled from it
    for the neighbour query: where the solve will put the body (locomotion.body.trail_ends and
    chain_on: on the path with its kinks rounded, as the body's trail has them, each joint a
    spacing behind the one ahead, the cobra's raised front included), not along the raw path,
    which a head's turn on the spot folds into a cusp. The paths are kept a point every
    KEEP_EVERY of the trail's resolution (the head's current point last), for all creatures at
    once.

    lift : the cobra's lift per spine joint (segments,) [m] at a cobra amount 0..1
    tail : points a spacing apart behind the last joint (the ultimate legs reach behind it)
    """

    #: the model's trail resolution, in spacings (the solve's is an eighth: a quarter keeps
    #: the body points within a millimetre or two of it at a quarter of the cost)
    RESOLUTION = 0.25
    KEEP_EVERY = 0.5

    def __init__(self, lines: list[np.ndarray], n_steps: int, spacing: float, segments: int,
                 lift=None, tail: int = 1):
        n, m = len(lines), len(lines[0])
        self.spacing, self.segments, self.lift = spacing, segments, lift
        self.size = segments + tail           # points per body
        self.res = self.RESOLUTION * spacing
        # the trail the chain and its bracket (four spacings behind a joint) walk, and the
        # raw path kept for it: two windows trail_ends may take (a dithering head's raw path
        # is longer than its trail)
        self.extent = (self.size + 5) * spacing
        self.window = 4.0 * self.extent + 16.0 * ROUND * spacing
        self.path = np.zeros((n, m + n_steps + 1, 3))
        self.cum = np.zeros((n, m + n_steps + 1))
        for i, line in enumerate(lines):
            self.path[i, :m] = line
            self.cum[i, 1:m] = np.cumsum(np.hypot(*np.diff(line[:, [0, 2]], axis=0).T))
        self.count = np.full(n, m - 1)     # index of each path's current (last) point
        self._row = np.arange(n) * self.cum.shape[1]        # each path's first flat index
        self._key = np.full((n, 2), np.nan)          # (arc length, cobra) of the points kept
        self._points = np.zeros((n, self.size, 3))

    def advance(self, heads: np.ndarray) -> None:
        """The heads after a step (n, 3), for all creatures at once: each becomes its path's current
        point, after the one before it if that one is KEEP_EVERY resolutions on."""
        # flat indices into the paths' rows (one index array a lookup, not two)
        cum, path, row = self.cum.reshape(-1), self.path.reshape(-1, 3), self._row
        last = self.count
        keep = cum[row + last] - cum[row + np.maximum(last - 1, 0)] >= (
            self.KEEP_EVERY * self.res)
        at = last + keep
        flat = row + at
        d = heads - path[flat - 1]
        cum[flat] = cum[flat - 1] + np.hypot(d[:, 0], d[:, 2])
        path[flat] = heads
        self.count = at

    def points(self, rows: np.ndarray, cobra: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """(len(rows) * size, 3) the body points of creatures `rows` (every joint's, and
        `tail` more behind the last) and (same,) their creature.
        cobra : (n,) every creature's cobra amount 0..1 (None: all down)"""
        amount = (np.zeros(len(rows)) if cobra is None or self.lift is None
                  else np.asarray(cobra, float)[rows])
        key = np.column_stack([self.cum[rows, self.count[rows]], amount])
        moved = ~(key == self._key[rows]).all(axis=1)          # still heads: as they were
        if moved.any():
            self._points[rows[moved]] = self._place(rows[moved], amount[moved])
            self._key[rows[moved]] = key[moved]
        return (self._points[rows].reshape(-1, 3),
                np.repeat(rows, self.size))

    def _place(self, rows: np.ndarray, amount: np.ndarray) -> np.ndarray:
        """(len(rows), size, 3) the body points of creatures `rows`."""
        ends = self.count[rows]
        starts = first_at_or_above(self.cum, rows, ends, self.cum[rows, ends] - self.window)
        # each path from its window's start to its head, read where it is kept
        trails = trail_ends(self.path, self.cum, ends, self.extent, self.spacing, self.res,
                            rows=rows, starts=starts)
        lift = np.zeros((len(rows), self.size))
        for r in np.flatnonzero(amount > 0.0):
            lift[r, :self.segments] = self.lift(float(amount[r]))
        return chain_on(trails, lift, self.spacing, self.res)


def run_crowd(cfg: BakeConfig, env, nav, seed: int, n: int, ctx: Context,
              separation: float | None = None, workers: int = 1
              ) -> tuple[list[RunRecord], dict]:
    """Run `n` creatures together. Returns (one RunRecord per creature, the prey's record:
    dict(prey_names, prey_positions (F, P, 3), prey_modes (F, P) int8, prey_holder (F, P) int,
    the creature whose head holds each prey, -1 for none)). The prey are the bake's
    (cfg.prey, spawned around creature 0 from its prey streams, as for a lone creature)."""
    rig = cfg.rig
    sep = crowd_separation(rig) if separation is None else float(separation)
    clock = Clock(cfg)
    reach = crowd_reach(rig, sep, clock.dt)
    band = crowd_band(rig, reach)
    streams = [Streams(seed, creature=i) for i in range(n)]
    starts = crowd_starts(nav, env, rig, streams, sep, cfg.start, cfg.start_heading, band)
    sun = make_sun(cfg, env)
    claims = Claims(rig.behaviour.shade_spot_spacing)
    follows = [Follower(nav, env.rays, s, h, rig, fps=cfg.fps) for s, h in starts]
    for f in follows:
        f.separation = sep
    preys = make_prey(cfg, env, nav, streams[0], sun, starts[0][0])
    brains = [Brain(rig, nav, env.rays, sun, st.get("brain"), preys, mode=cfg.behaviour,
                    cobra_mode=cfg.cobra, claims=claims, who=i) for i, st in enumerate(streams)]
    lines = [start_line(nav, rig, s, h) for s, h in starts]
    # a raised cobra's amount stays at 1 (and the bodies are placed every few steps): the
    # profiles of the last amounts are kept (Bodies copies them)
    bodies = Bodies(lines, clock.n_steps, rig.body.spacing, rig.body.segments,
                    lift=functools.lru_cache(maxsize=LIFT_CACHE)(
                        lambda a: lift_profile(np.array([a]), rig.cobra.curve, rig.cobra.height,
                                               rig.body.segments)[0]),
                    tail=tail_points(rig))
    heads = np.empty((n, clock.n_steps + 1, 3))
    heads[:, 0] = [s for s, _ in starts]
    bodies.advance(heads[:, 0])
    recs = [Recorder(clock.n_frames, 0) for _ in range(n)]
    prey_rec = Recorder(clock.n_frames, len(preys))
    holder = np.full((clock.n_frames, len(preys)), -1)
    ramp = clock.dt / rig.cobra.ramp_time
    wants = [b.intent() for b in brains]
    cobra = np.array([w.cobra for w in wants])
    group = Followers(follows, clock.dt, workers, lazy=isinstance(nav, LazyNav))
    state = group.states
    sample(0, recs, prey_rec, holder, wants, preys, brains, cobra, state)
    try:
        for k in range(1, clock.n_steps + 1):
            t = (k - 1) * clock.dt
            others = None
            if (k - 1) % AVOID_EVERY == 0 and n > 1:
                others = neighbours(bodies, heads[:, k - 1], state.speeds, reach, cobra, band)
            told = senses(t, state)
            due = [i for i in range(n) if brains[i].perceives(t)]
            if due:                     # what the brains perceiving this step sense, at once
                sense_together([brains[i] for i in due], [told[i] for i in due])
            for i in range(n):
                wants[i] = brains[i].step(told[i])
            group.step(wants, others)
            heads[:, k] = state.positions
            bodies.advance(heads[:, k])
            if preys:
                step_prey(preys, t, clock.dt, heads[:, k])
            cobra += np.clip(np.array([w.cobra for w in wants]) - cobra, -ramp, ramp)
            if k % clock.per_frame == 0:
                sample(k // clock.per_frame, recs, prey_rec, holder, wants, preys, brains, cobra,
                       state)
            if k % 2400 == 0:
                ctx.report_progress("simulate", k / clock.n_steps)
    finally:
        group.close()
    out = [record(clock, nav, rig, s, h, heads[i], recs[i], [], sun,
                  brains[i].finish(cfg.seconds), None, state.replans(i))
           for i, (s, h) in enumerate(starts)]
    return out, dict(prey_names=tuple(p.name for p in preys), prey_positions=prey_rec.prey_pos,
                     prey_modes=prey_rec.prey_mode, prey_holder=holder)


def neighbours(bodies: Bodies, heads: np.ndarray, speeds: np.ndarray, reach: float,
               cobra: np.ndarray | None = None, band: float = np.inf) -> list[tuple]:
    """Every creature's (the other creatures' body points (x, z) within `reach` of its head
    and within `band` above or below it (crowd_band: a body on another storey is not in the
    way), or None; whether those creatures all walk), from one tree and one ball query for all
    heads; speeds: (n,) the heads' speeds, cobra: (n,) the cobra amounts. Only the bodies of
    creatures whose heads are near another's are placed: a body lies within bodies.extent of
    its head."""
    out = [(None, False)] * len(heads)
    xz = heads[:, [0, 2]]
    need = unique(cKDTree(xz).query_pairs(bodies.extent + reach, output_type="ndarray"))
    if not len(need):
        return out
    pts3, owner = bodies.points(need, cobra)
    pts = pts3[:, [0, 2]]
    near = cKDTree(pts).query_ball_point(xz[need], reach)
    # every head's points in one flat array (in the tree's order), the head's own body's out
    lens = np.fromiter(map(len, near), np.intp, len(near))
    idx = np.fromiter(itertools.chain.from_iterable(near), np.intp, int(lens.sum()))
    who = np.repeat(np.arange(len(need)), lens)
    keep = (owner[idx] != need[who]) & (np.abs(pts3[idx, 1] - heads[need[who], 1]) <= band)
    idx, who = idx[keep], who[keep]
    count = np.bincount(who, minlength=len(need))
    # the bodies near move on (their heads walk): a head they corner may wait for them
    stopped = np.bincount(who, weights=~(speeds[owner[idx]] > 0.0), minlength=len(need))
    near_pts = np.split(pts[idx], np.cumsum(count)[:-1])
    for r, i in enumerate(need.tolist()):
        if count[r]:
            out[i] = (near_pts[r], not stopped[r])
    return out


def senses(t: float, state: States) -> list[Senses]:
    """What each creature's brain is told at time t about its follower (its head point and
    heading are rows of one copy of the states: no brain's Senses shares memory with
    another's, nor with the states the next step writes)."""
    rows = state.rows[:, 0:7].copy()
    arrived = (rows[:, 6] != 0.0).tolist()
    return [Senses(t, rows[i, 0:3], rows[i, 3:6], arrived[i]) for i in range(len(rows))]


def step_prey(preys, t: float, dt: float, heads: np.ndarray) -> None:
    """Every prey reacts to the nearest head."""
    for p in preys:
        d = np.hypot(heads[:, 0] - p.position[0], heads[:, 2] - p.position[2])
        p.step(t, dt, heads[int(np.argmin(d))])


def sample(f: int, recs, prey_rec: Recorder, holder, wants, preys, brains, cobra,
           state: States):
    """Frame f of every creature's drives, the prey and which head holds each prey."""
    for i, rec in enumerate(recs):
        rec.sample(f, wants[i], (), float(cobra[i]), state.phase(i))
    prey_rec.sample(f, wants[0], preys, 0.0)
    for i, b in enumerate(brains):
        if b.prey is not None:
            holder[f, preys.index(b.prey)] = i
