"""Where creatures and prey start: reachable points and a heading whose straight body line
behind the head lies on walkable ground."""

from __future__ import annotations

import numpy as np

from baker.behaviour.prey import Prey
from baker.errors import NavError
from baker.streams import Streams

#: [body lengths] the room ahead of the head a start heading looks for: about two turning
#: circles
AHEAD = 0.25
#: start points drawn at most until one has a full line behind and room ahead
START_DRAWS = 8
#: then at most this many more, out to `spread` or the level's whole extent (a small level's
#: middle, a tower's stair landing, may have no room for a straight body)
WIDE_DRAWS = 56
_BEHIND = np.linspace(0.0, 1.0, 9)
_AHEAD = -AHEAD * np.arange(1, 5) / 4
_FULL = len(_BEHIND) * 10 + len(_AHEAD)
#: shares of the ultimate legs' reach behind the tail sampled on the start line too
_TAIL = np.array([0.5, 1.0])


def tail_reach(rig) -> float:
    """[m] how far the ultimate legs trail behind the last spine joint (their two bones; 0
    without legs): the start line is sampled out to there, so the tail does not start against
    a wall or a riser the legs would trail into."""
    legs = rig.legs
    return float(legs.ultimate_upper + legs.ultimate_tip) if legs.enabled else 0.0


def full_behind(tail: float = 0.0) -> int:
    """The least start_score of a start whose body line behind (and the tail's reach) is
    walkable all along."""
    return 10 * (len(_BEHIND) + (len(_TAIL) if tail > 0.0 else 0))


def full_score(tail: float = 0.0) -> int:
    """start_score of a start walkable all along its line (and the tail's reach), with room
    ahead."""
    return full_behind(tail) + len(_AHEAD)


def choose_start(nav, env, body_length: float, rng: np.random.Generator, at=None, heading=None,
                 spread: float = np.inf, extent_frac: float = 0.2, anchor=None,
                 tail: float = 0.0):
    """A walkable start point near the middle of the scene (within `extent_frac` of its extent,
    at most `spread` metres; or the one nearest to `at`), and a heading (or `heading`) whose
    straight body line behind the head is as walkable as possible, with room ahead. A point
    with no heading that has both (at an edge: the head would be deflected at once, and its
    trail would kink against the straight start line) is drawn again, up to START_DRAWS times;
    then up to WIDE_DRAWS more out to `spread` (or the level's extent); the best draw is kept.

    anchor : the scene's middle_anchor(nav, env) when the caller has it (a crowd's many draws)
    tail   : [m] the line is sampled this far past the body's length too (tail_reach)
    returns (position (3,), heading (3,) unit horizontal)
    """
    lo, hi = env.bounds
    if at is not None:
        anchor = nav.nearest(np.asarray(at, dtype=np.float64), np.inf)
    elif anchor is None:
        anchor = middle_anchor(nav, env)
    if anchor is None:
        raise NavError("environment has no walkable surface")
    radius = min(extent_frac * float(np.max(hi - lo)), spread)
    if at is not None or heading is not None:
        start = anchor if at is not None else nav.random_point_near(anchor, radius, rng)
        start = anchor if start is None else start
        if heading is None:
            return start, _best_heading(nav, start, body_length, rng, tail)[1]
        h = np.array([heading[0], 0.0, heading[2]], dtype=np.float64)
        return start, h / max(np.linalg.norm(h), 1e-12)
    best = (-1, None, None)
    wide = max(radius, min(float(np.max(hi - lo)), spread))
    for k in range(START_DRAWS + WIDE_DRAWS):
        start = nav.random_point_near(anchor, radius if k < START_DRAWS else wide, rng)
        start = anchor if start is None else start
        score, h = _best_heading(nav, start, body_length, rng, tail)
        if score > best[0]:
            best = (score, start, h)
        if score == full_score(tail):
            break
    return best[1], best[2]


def _best_heading(nav, start: np.ndarray, body_length: float, rng,
                  tail: float = 0.0) -> tuple[int, np.ndarray]:
    """The best of 16 headings (a random first one) at `start`: the most walkable samples on
    the body line behind, then ahead. returns (score, heading (3,))"""
    angles = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, 16, endpoint=False)
    dirs = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1)
    score = start_score(nav, start[None, :], dirs, body_length, tail)[0]
    i = int(np.argmax(score))
    return int(score[i]), dirs[i]


def start_score(nav, starts: np.ndarray, dirs: np.ndarray, body_length: float,
                tail: float = 0.0) -> np.ndarray:
    """(k, h) how walkable each start (k, 3) is with each heading (h, 3): ten a walkable
    sample of the straight body line behind (and of the `tail` metres past it, tail_reach),
    one a sample of the room ahead (full_score: all)."""
    behind = body_length * _BEHIND
    if tail > 0.0:
        behind = np.concatenate([behind, body_length + tail * _TAIL])
    d = np.concatenate([behind, body_length * _AHEAD])
    pts = starts[:, None, None, :] - dirs[None, :, None, :] * d[None, None, :, None]
    ok = nav.is_walkable(pts.reshape(-1, 3)).reshape(len(starts), len(dirs), len(d))
    return ok[..., :len(behind)].sum(axis=-1) * 10 + ok[..., len(behind):].sum(axis=-1)


def middle_anchor(nav, env) -> np.ndarray | None:
    """The largest walkable component's sample closest to the middle of the scene (None when
    nothing is walkable)."""
    lo, hi = env.bounds
    centre = 0.5 * (lo + hi)
    main = np.nonzero(nav.component == 0)[0]
    d = np.linalg.norm(nav.positions[main] - centre.astype(np.float32), axis=1)
    return nav.positions[main[np.argmin(d)]].astype(np.float64) if len(main) else None


def spawn_prey(count: int, start: np.ndarray, nav, rig, streams: Streams,
               shaded=None, in_cover=None) -> list[Prey]:
    """`count` prey at reachable points between 1.2 and 2 detection ranges from the start, each
    placed and later fleeing with its own stream. Prey shelter in shade as the centipede does:
    with `shaded` ((n, 3) points -> (n,) bool) each takes the first shaded one of 32 draws,
    else the first draw in range; on a level too small for the range, the farthest draw (it
    had started on the centipede's head, caught at once). `in_cover` is handed to each
    (Prey)."""
    preys = []
    r = rig.behaviour.detection_range
    for i in range(count):
        rng = streams.get("prey", i)
        found, far, far_d = [], start.copy(), 0.0
        for _ in range(32):
            q = nav.random_point_near(start, 2.0 * r, rng)
            d = -1.0 if q is None else float(np.linalg.norm(q - start))
            if d > far_d:
                far, far_d = q, d
            if d >= 1.2 * r:
                found.append(q)
                if shaded is None or shaded(q[None])[0]:
                    found = [q]
                    break
        preys.append(Prey(i, found[0] if found else far, rig.prey, nav, rng, in_cover))
    return preys
