"""Joint-space swings: the fallback for swings whose foot-space path breaks a limit.

legs.py plans each swing as a foot path (an arc around the hip, lifted, then pushed off walls,
raised over obstacles, re-timed) and solves it with two-bone IK. Near walls, on stairs and in
tight turns those corrections can fight each other: the leg then turns too far in one frame,
a bone passes through something, the foot goes into a surface, skims along one, or crowds a
neighbour's foot.

Such a swing is replaced by one in the leg's own joint space: the upper bone's rotation
(relative to its segment) and the tip bone's (relative to the upper bone) slerp from the last
planted pose to the touchdown pose at an even pace, while the whole leg is raised about the
body's long axis (through the hip) by a bump raise * profile(u); when that is not enough the
knee also swivels round the hip -> foot line, or bends to tuck the foot in; last, the best
candidate so far has its fastest step spread evenly over the frames round it, on its own path
(PEAK_SPREAD: a path clear of everything but for one fast turn). Of the candidates,
the first that keeps every frame of the swing within all limits wins; when none does,
the one with the fewest offending frames, and the planned swing stays when it has no more
than that. A fault that breaks the bake's own limits (a bone through something, a foot deeper
than `deep` in a solid, a joint turning more than `hard_turn`, a neighbour's foot nearer than
`hard_gap`) outweighs any number of near misses (a shallow foot, a turn over `turn`, a foot
nearer than `gap`, a sliding touch). Both ends are the planted poses, so stances are untouched,
but for one last resort: a swing that still breaks a limit lifts off earlier (EARLY_LIFT of its
length sooner) and is redone over the longer swing, kept where it costs less. All swings,
candidates and frames are checked in flat batches (one ray batch per candidate).

The very last resort, for a swing that every candidate leaves broken (`_repair`): its frames
round the broken ones are searched afresh as a trellis. At each frame, poses are sampled round
its current pose and round the slerp across the window (REPAIR_GRID: raises, yaws, knee
swivels and tucks); poses with a bone through something or a foot deep in a solid are dropped,
and trellis.cheapest_path picks the sequence with the fewest faults, every step between frames
within the turn limit where it can be. Where a single fixed path family fails — a hip a few
millimetres over the ground beside a bank, a landing pose that only clears the ground in its
own frame — a path threaded pose by pose through what is clear usually exists. It is kept
only where the swing then breaks a limit in fewer frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from baker.geometry.transforms import (length, normalize, quat_about, quat_angle, quat_conj,
                                       quat_mul, quat_rotate, quat_slerp)
from baker.locomotion.leg_kernels import PoseRows, arc_pose, crowding, leg_pose
from baker.locomotion.trellis import cheapest_path

#: deep tucks (the foot drawn up to the hip) tried with the larger raises, last [rad]
TUCKS = np.radians([60.0, 90.0])
#: raises of the whole leg about the body's long axis tried, smallest first [rad]
RAISES = np.radians([4.0, 8.0, 12.0, 16.0, 24.0, 32.0, 45.0, 60.0])
#: knee swivels about the hip -> foot line tried when raising alone does not clear [rad]
SWIVELS = np.radians([25.0, -25.0, 50.0, -50.0])
#: knee bends that tuck the foot in, tried after raises and swivels [rad]
FLEXES = np.radians([20.0, 40.0])
#: the eased raises (tried last) grow by at most this share of the turn limit per frame
RAISE_STEP = 0.5
#: width (in swing progress) of the local lift round a frame where a swing crowds a neighbour
BUMP_WIDTH = 0.25
#: swings of the whole leg forward (> 0) or back round the hip, tried last [rad]
YAWS = np.radians([12.0, -12.0, 24.0, -24.0])
#: fractions of a swing spent waiting at its start (> 0) or landed early (< 0)
DELAYS = (0.3, -0.3)
#: a swing that still breaks a limit tries lifting off this fraction of its length sooner
EARLY_LIFT = 0.5
#: ... keeping at least this many planted frames after the previous touchdown
MIN_STANCE = 2
#: entries on either side of a swing's fastest step over which the "peak" candidates spread it
PEAK_SPREAD = (2, 4, 8)
#: the cost of a fault that breaks a limit, against 1 for a near miss
HARD = 100.0
#: the last resort's samples round each pose (raise about the body's long axis, yaw round the
#: hip, knee swivel, tuck) [rad]; the unchanged pose first
REPAIR_GRID = np.radians(np.stack(np.meshgrid(
    [0.0, -15.0, 10.0, 20.0, 30.0, 45.0, 60.0, 80.0], [0.0, 15.0, -15.0, 30.0, -30.0],
    [0.0, 30.0, -30.0], [0.0, 25.0, 50.0], indexing="ij"), -1).reshape(-1, 4))
#: frames on either side of a broken swing's faults that the last resort may change, tried in
#: turn until one is enough
REPAIR_MARGINS = (4, 16)
#: the last resort's cost per radian of a turn beyond the limit (a path that cannot keep within
#: it breaks it by as little as it can)
OVER = 10.0
#: the last resort's cost of a step between frames per unit of 1 - cos(half its largest turn):
#: a tie-breaker for smooth paths, far below a near miss over any swing
SMOOTH = 1e-2
#: raise profiles over the swing's progress u: a plain bump, and two that rise sooner (off the
#: ground and away from a neighbour's foot in the first frame)
PROFILES = (lambda u: np.sin(np.pi * u), lambda u: np.sqrt(np.sin(np.pi * u)),
            lambda u: np.sin(np.pi * u) ** 0.25)
_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Limits:
    """What a swing frame must respect.

    contact : a foot within this of a surface touches it; two touching frames in a row must
              not move the foot more than `slide` [m]
    tol     : the tip bone's last bit that may touch a surface [m]
    turn    : largest turn of any joint per frame, in its own space and in the world [rad]
    gap     : a swinging foot keeps this far from its neighbours' feet [m]
    hard_turn, hard_gap : the turn and gap that break a limit (None: turn, gap); between
              these and turn, gap a frame is a near miss
    deep    : a foot deeper than this inside a solid breaks a limit; shallower it is a near
              miss [m]
    judged  : (F,) bool, the frames whose faults count (None: all): legs planned over margins
              beyond the bake's frames do not trade a fault in the bake for one in a margin
    """

    contact: float
    slide: float
    tol: float
    turn: float
    gap: float
    hard_turn: float | None = None
    hard_gap: float | None = None
    deep: float = 0.0
    judged: np.ndarray | None = None

    @property
    def breaking_turn(self) -> float:
        """The per-frame turn that breaks a limit [rad]."""
        return self.turn if self.hard_turn is None else self.hard_turn

    @property
    def breaking_gap(self) -> float:
        """The distance to a neighbour's foot that breaks a limit [m]."""
        return self.gap if self.hard_gap is None else self.hard_gap

    def weight(self, f: np.ndarray) -> np.ndarray:
        """(n,) 1.0 for entries at judged frames `f`, else 0.0."""
        return np.ones(len(f)) if self.judged is None else self.judged[f].astype(float)


def _runs(swing: np.ndarray):
    """(leg, a, b) of every swing of an (F, L) bool array: a = the last planted frame before it
    (or 0), b = the first planted frame after it (or F - 1); only swings with a frame strictly
    between a and b."""
    F, L = swing.shape
    pad = np.zeros((1, L), bool)
    edge = np.diff(np.concatenate([pad, swing, pad]).astype(np.int8), axis=0)
    s_f, s_l = np.nonzero(edge == 1)             # first swing frame
    e_f, e_l = np.nonzero(edge == -1)            # one past the last swing frame
    so, eo = np.lexsort((s_f, s_l)), np.lexsort((e_f, e_l))
    leg, a, b = s_l[so], np.maximum(s_f[so] - 1, 0), np.minimum(e_f[eo], F - 1)
    keep = b - a >= 2
    return leg[keep], a[keep], b[keep]


def _pose(q_seg, hip, U, T, l1, l2):
    """World upper/tip rotations and the knee and foot of local poses U, T (..., 4) on segment
    rotations q_seg (..., 4) and hips (..., 3) of one shape (leg_kernels.leg_pose)."""
    lead = U.shape[:-1]
    q_u, q_t, mid, end, _ = leg_pose(q_seg.reshape(-1, 4), hip.reshape(-1, 3),
                                     U.reshape(-1, 4), T.reshape(-1, 4), l1, l2)
    return (q_u.reshape(lead + (4,)), q_t.reshape(lead + (4,)), mid.reshape(lead + (3,)),
            end.reshape(lead + (3,)))


def _swivel(U, T, angle, l1, l2):
    """Upper-bone local rotations U (n, 4) turned by `angle` (n,) about the hip -> foot line
    (segment frame): the knee swings round, the foot stays."""
    foot = quat_rotate(U, l1 * _Y) + quat_rotate(quat_mul(U, T), l2 * _Y)
    axis = foot / np.maximum(length(foot)[..., None], 1e-12)
    return quat_mul(quat_about(axis, angle), U)


def _flex(U, T, angle, l1, l2):
    """Tip-bone local rotations T (n, 4) bent by `angle` (n,) about the knee's hinge (the upper
    bone's local +X), the way that draws the foot toward the hip (tucks the leg in)."""
    out = []
    knee = quat_rotate(U, l1 * _Y)
    for sgn in (1.0, -1.0):
        Tk = quat_mul(quat_about(np.broadcast_to(_X, U.shape[:-1] + (3,)), sgn * angle), T)
        foot = knee + quat_rotate(quat_mul(U, Tk), l2 * _Y)
        out.append((Tk, length(foot)))
    return np.where((out[0][1] <= out[1][1])[:, None], out[0][0], out[1][0])


def _swing_runs(sid):
    """(same (n-1,) bool: entries k and k+1 are one swing, first: each swing's first entry,
    runs: each swing's entry count) of flat entries of swings `sid`."""
    same = sid[1:] == sid[:-1]
    first = np.r_[0, np.nonzero(~same)[0] + 1]
    return same, first, np.diff(np.r_[first, len(sid)])


def _joint_steps(U, T):
    """(n-1,) the larger of the two bones' turns between consecutive entries."""
    return np.maximum(quat_angle(U[1:], U[:-1]), quat_angle(T[1:], T[:-1]))


def _run_progress(step, first, runs):
    """(n,) each entry's share of its swing's summed `step` (step[first] is not counted): 0 at
    each swing's first entry, 1 at its last."""
    cum = np.cumsum(step)
    cum -= np.repeat(cum[first], runs)
    total = np.repeat(cum[first + runs - 1], runs)
    return cum / np.maximum(total, 1e-12)


def _retimed(U, T, sid, u):
    """The swings' own poses (U, T local rotations, flat entries of swings `sid` at progress
    `u`) walked at an even pace in joint space: entry k gets the pose at u_k of the swing's
    cumulative joint turn (the largest of the two bones' turns between entries), so a swing
    that turns a joint too fast in one frame spreads the turn over its frames, on its own
    path (both ends unchanged)."""
    n = len(sid)
    same, first, runs = _swing_runs(sid)
    step = np.zeros(n)
    step[1:] = np.where(same, _joint_steps(U, T) + 1e-9, 0.0)
    key = sid + _run_progress(step, first, runs) * (1.0 - 1e-9)
    want = sid + np.clip(u, 0.0, 1.0) * (1.0 - 1e-9)
    j = np.clip(np.searchsorted(key, want, side="right") - 1, 0, n - 2)
    j = np.where(sid[np.minimum(j + 1, n - 1)] == sid, j, j - 1)
    span = np.maximum(key[j + 1] - key[j], 1e-15)
    t = np.clip((want - key[j]) / span, 0.0, 1.0)
    return quat_slerp(U[j], U[j + 1], t), quat_slerp(T[j], T[j + 1], t)


def _peak_spread(U, T, sid, w: int):
    """The swings' own poses (flat entries of swings `sid`, as _retimed) with each swing's
    fastest step (the largest of the two bones' turns between entries) spread over the `w`
    entries on either side of it, walked at an even pace in joint space there; the other
    entries, and both ends of every swing, unchanged."""
    n = len(sid)
    same, first, runs = _swing_runs(sid)
    step = np.full(n, -1.0)
    step[1:] = np.where(same, _joint_steps(U, T), -1.0)
    g = np.repeat(np.arange(len(first)), runs)
    idx = np.arange(n)
    top = np.repeat(np.maximum.reduceat(step, first), runs)
    peak = np.minimum.reduceat(np.where(step == top, idx, n), first)   # entry after the step
    lo = np.maximum(first, peak - 1 - w)
    hi = np.minimum(first + runs - 1, peak + w)
    win = np.nonzero((idx >= lo[g]) & (idx <= hi[g]))[0]
    u = (idx[win] - lo[g[win]]) / np.maximum(hi - lo, 1)[g[win]]
    U, T = U.copy(), T.copy()
    U[win], T[win] = _retimed(U[win], T[win], g[win], u)
    return U, T


def _world_paced(q_seg, sid, turn):
    """(n,) swing progress of flat entries (consecutive entries of one swing `sid` are
    consecutive frames) paced by the turn left to the leg: each frame's step is `turn` less the
    segment's world rotation (q_seg (n, 4)) since the previous frame, at least a quarter of
    `turn`; 0 at each swing's first entry, 1 at its last."""
    same, first, runs = _swing_runs(sid)
    step = np.zeros(len(sid))
    step[1:] = np.where(same, np.maximum(turn - quat_angle(q_seg[1:], q_seg[:-1]), 0.25 * turn),
                        0.0)
    return _run_progress(step, first, runs)


class _Answers:
    """A RayCaster's answers about leg poses, kept for the poses asked about again (a swing
    nothing improves is tried with the same candidates in every round, clipped and eased
    candidates repeat poses): once asked for, the foot's distance to the surface and whether
    the foot is inside a solid (whether a bone passes through something is cast afresh: two
    rays cost less than looking a pose up). Poses are told apart by the exact bits of their
    hip, knee and foot."""

    def __init__(self, rays):
        self.rays = rays
        self.poses = PoseRows()                 # each pose's row (its hip, knee, foot bits)
        self.dist = np.zeros(0)                 # NaN: not asked yet
        self.inside = np.zeros(0, np.int8)      # -1: not asked yet

    @classmethod
    def of(cls, rays) -> "_Answers":
        return rays if isinstance(rays, cls) else cls(rays)

    def ask(self, hip, mid, end, inner, reach):
        """(bone (n,) bool, dist (n,), inside (n,) bool: asked for `inner` entries only) of
        poses hip -> mid -> end (n, 3); reach: the two bones' ray lengths."""
        row = self.row_of(hip, mid, end)
        return (self.bones(hip, mid, end, reach), self.dist_of(row, end),
                self.inside_of(row, end, inner))

    def bones(self, hip, mid, end, reach) -> np.ndarray:
        """(n,) bool: either bone of poses hip -> mid -> end (n, 3) passes through something
        (both bones' rays in one batch; each ray's hit is its own: Embree casts them one by
        one); reach: the two bones' ray lengths."""
        n = len(hip)
        prim = self.rays.cast(np.concatenate([hip, mid]),
                              np.concatenate([normalize(mid - hip), normalize(end - mid)]),
                              np.repeat(reach, n))[1]
        return (prim[:n] >= 0) | (prim[n:] >= 0)

    def row_of(self, hip, mid, end) -> np.ndarray:
        """(n,) the rows of poses hip -> mid -> end (n, 3), new poses added (nothing asked
        about them yet)."""
        had = self.poses.n
        row = self.poses.rows(hip, mid, end)
        n = self.poses.n
        if n > len(self.dist):
            size = max(2 * len(self.dist), n, 1024)
            self.dist, self.inside = np.resize(self.dist, size), np.resize(self.inside, size)
        self.dist[had:n] = np.nan
        self.inside[had:n] = -1
        return row

    def dist_of(self, row, end) -> np.ndarray:
        """(n,) the distances of feet `end` (n, 3), of poses in rows `row`, to the surface,
        uncapped."""
        ask = np.nonzero(np.isnan(self.dist[row]))[0]
        if len(ask):
            r, first = np.unique(row[ask], return_index=True)
            self.dist[r] = self.rays.closest(end[ask[first]], np.inf)[0]
        return self.dist[row]

    def inside_of(self, row, end, inner) -> np.ndarray:
        """(n,) bool whether feet `end` (n, 3), of poses in rows `row`, are inside a solid:
        asked for `inner` entries only (the others: as far as known)."""
        ask = np.nonzero(inner & (self.inside[row] < 0))[0]
        if len(ask):
            r, first = np.unique(row[ask], return_index=True)
            self.inside[r] = self.rays.inside(end[ask[first]])
        return self.inside[row] == 1

def _node_faults(rays, lim: Limits, hip, q_seg, U, T, l1, l2, inner):
    """(cost (n,), q_u, q_t, feet (n, 3), touch (n,) bool) of single poses: a bone through the
    environment (HARD); an inner pose's foot inside a solid (1, HARD deeper than `deep`); touch:
    the foot within `contact` of a surface. rays: a RayCaster or its _Answers."""
    q_u, q_t, mid, end = _pose(q_seg, hip, U, T, l1, l2)
    # the touch and the depth are both read from the foot's distance to the surface (the
    # same distance a capped query returns within its cap)
    bone, d, inside = _Answers.of(rays).ask(hip, mid, end, inner,
                                            [l1 - 1e-9, max(l2 - lim.tol, 0.0)])
    cost = HARD * bone
    k = np.nonzero(inner & inside)[0]
    cost[k] += 1.0
    if lim.deep > 0.0 and len(k):
        k = k[~(d[k] <= lim.deep)]
    cost[k] += HARD - 1.0
    return cost, q_u, q_t, end, d < lim.contact


def _own_faults(rays, lim: Limits, hip, q_seg, U, T, l1, l2, inner, same):
    """(cost (n,), feet (n, 3)) per entry of flat swing frames (consecutive entries of one
    swing are consecutive frames; `same[k]`: entries k and k+1 belong to one swing): a bone
    through the environment; an inner frame's foot inside a solid; a joint turning more than
    `turn` to the next entry; a foot touching a surface in this and the next entry while it
    slides more than `slide`. A near miss costs 1, a broken limit HARD (see Limits)."""
    n = len(U)
    cost, _, end = _bounded_faults(_Answers.of(rays), lim, hip, q_seg, U, T, l1, l2, inner, same,
                                   np.ones(n), None, np.zeros(n, np.int64), np.array([np.inf]))
    return cost, end


def _turn_faults(lim: Limits, dots, same) -> np.ndarray:
    """(n-1,) the cost of a joint turning more than `turn` (1) or the breaking turn (HARD)
    from each entry to the next of the same swing (`same`); dots: (4, n-1) the dot products of
    consecutive entries' local and world rotations of the upper and tip bones (leg_pose): the
    largest of their quat_angle."""
    steps = np.maximum.reduce(2.0 * np.arccos(np.clip(np.abs(dots), 0.0, 1.0)))
    return (same & (steps > lim.turn)) + (HARD - 1.0) * (same & (steps > lim.breaking_turn))


def _bounded_faults(rays: "_Answers", lim: Limits, hip, q_seg, U, T, l1, l2, inner, same, w,
                    near, key, bound):
    """(cost (n,), score (len(bound),), feet (n, 3)) of flat swing frames as _own_faults,
    weighted by `w` (n,), and each group's score: the sum of its entries' weighted costs and
    crowding of the neighbours' feet `near` (n, 2, 3; None: no crowding); entries are grouped
    by `key` (n,). The faults are found cheapest first (turns and crowding, bones through
    something, feet inside a solid, touching feet that slide), each only for the groups whose
    score so far is below `bound`: a group's cost and score are whole where its score is below
    `bound`, else its score is at least `bound`."""
    _, _, mid, end, dots = leg_pose(q_seg, hip, U, T, l1, l2)
    n = len(U)
    cost = np.zeros(n)
    crowd = np.zeros(n) if near is None else w * _crowding(end, inner, near, lim)
    if n > 1:
        cost[:-1] += _turn_faults(lim, dots, same)
    row = np.full(n, -1)
    reach = [l1 - 1e-9, max(l2 - lim.tol, 0.0)]

    def live(where):
        """Entries among `where` (n,) bool of the groups still below their bound, weighted."""
        score = np.bincount(key, weights=cost * w + crowd, minlength=len(bound))
        return np.nonzero(where & (w > 0) & (score < bound)[key])[0]

    def rows(k):
        new = k[row[k] < 0]
        if len(new):
            row[new] = rays.row_of(hip[new], mid[new], end[new])
        return row[k]

    k = live(np.ones(n, bool))
    cost[k] += HARD * rays.bones(hip[k], mid[k], end[k], reach)
    k = live(inner)
    k = k[rays.inside_of(rows(k), end[k], np.ones(len(k), bool))]
    cost[k] += 1.0
    if lim.deep > 0.0 and len(k):
        k = k[~(rays.dist_of(rows(k), end[k]) <= lim.deep)]
    cost[k] += HARD - 1.0
    if n > 1:
        slides = np.r_[same & (length(np.diff(end, axis=0)) > lim.slide), False]
        k = live(slides)
        # the even entry of each pair first: a pair whose even entry is clear of the surface
        # is settled without the other
        touch = np.zeros(n, bool)
        odd = k % 2 == 1
        e = np.unique(np.where(odd, k + 1, k))
        touch[e] = rays.dist_of(rows(e), end[e]) < lim.contact
        e = np.unique(np.where(odd, k, k + 1)[touch[k] | touch[k + 1]])
        touch[e] = rays.dist_of(rows(e), end[e]) < lim.contact
        cost[k] += touch[k] & touch[k + 1]
    cost *= w
    return cost, np.bincount(key, weights=cost + crowd, minlength=len(bound)), end


def _crowding(end, inner, near_feet, lim: Limits):
    """(n,) the cost of an inner frame's foot (n, 3) near a neighbour's foot (near_feet
    (n, 2, 3), NaN for none): 1 within lim.gap, HARD within lim.hard_gap."""
    return crowding(end, inner, near_feet, lim.gap, lim.breaking_gap, HARD)


def _entry_costs(sw: "_Swings", own, w, feet, lim: Limits, k: np.ndarray) -> np.ndarray:
    """(len(k),) the cost now of entries k: their own faults (`own`, weighted by `w`) and their
    feet's crowding of the neighbours' current feet (`feet` (F, L, 3))."""
    return own[k] + w[k] * _crowding(feet[sw.f[k], sw.lg[k]], sw.inner[k], sw.near(feet, k), lim)


class _Swings:
    """Every swing of every leg as flat entries, one per frame from the last planted frame to
    the first planted one: swing id `sid`, frame `f`, leg `lg`, progress `u`."""

    def __init__(self, swing: np.ndarray):
        leg, a, b = _runs(swing)
        self.n = len(leg)
        length = b - a + 1
        self.sid = np.repeat(np.arange(self.n), length)
        self.start = np.repeat(np.cumsum(length) - length, length)
        self.last = self.start + np.repeat(length, length) - 1
        self.f = np.repeat(a, length) + (np.arange(len(self.sid)) - self.start)
        self.lg = leg[self.sid]
        self.u = (self.f - a[self.sid]) / (b - a)[self.sid]
        self.inner = (self.u > 0.0) & (self.u < 1.0)
        self.leg, self.a, self.b = leg, a, b

    def near(self, feet: np.ndarray, k: np.ndarray) -> np.ndarray:
        """(len(k), 2, 3) the feet of legs l - 2 and l + 2 at entries k (NaN for none): only
        the entries' own neighbours are copied (no padded copy of every frame's feet)."""
        f, lg = self.f[k], self.lg[k]
        out = np.full((len(k), 2, 3), np.nan)
        for side, other in ((0, lg - 2), (1, lg + 2)):
            has = np.nonzero((other >= 0) & (other < feet.shape[1]))[0]
            out[has, side] = feet[f[has], other[has]]
        return out


def joint_space_swings(rays, hip, q_seg, q_u, q_t, mid, end, swing, side, l1, l2, lim: Limits,
                       rounds: int = 2):
    """Swings that break a limit, replaced by joint-space swings (see the module docstring).

    hip   : (F, L, 3) hips; q_seg : (F, L, 4) each leg's segment rotation (world)
    q_u, q_t : (F, L, 4) world rotations of the upper and tip bones (bones along local +Y)
    mid, end : (F, L, 3) the planner's knees and feet
    swing : (F, L) bool, frames in which the foot is not planted
    side  : (L,) +1 left, -1 right; l1, l2 : bone lengths
    Legs are ordered L_01, R_01, L_02, ...: leg l's neighbours on its side are l - 2 and l + 2.
    Each swing's own faults are found once; crowding is judged against the neighbours' latest
    feet, and neighbours never change in the same pass (legs of odd and even segments take
    turns, `rounds` times). A swing that still breaks a limit then tries again longer
    (_second_tries: merged with a swing next to it across a single planted frame or a stance
    too short to lift off from sooner, or lifting off earlier, and if that is not enough,
    merged with the swing before): a longer swing turns its joints more slowly, so it can rise
    over what it could not. The longer swing is kept where it costs less.
    returns (q_u, q_t, mid, end, swing), each (F, L, ...); swing with the earlier lifts
    """
    rays = _Answers(rays)               # poses asked about again are not cast again
    args = (rays, hip, q_seg, side, l1, l2, lim, rounds)
    out, sw, cost = _swings_pass(*args, q_u, q_t, mid, end, swing)
    tries = _second_tries(sw, cost)
    if not tries:
        return out + (swing,)
    out, swing, still = _longer(args, out, swing, tries)
    # a swing still broken after lifting off sooner: one swing with the swing before it, over
    # the stance between (too short to help it)
    ending = {(lg, b): i for i, (lg, b) in enumerate(zip(sw.leg, sw.b))}
    merges = []
    for leg, s, e, now in still:
        i = ending.get((leg, e), 0)
        if i > 0 and sw.leg[i - 1] == leg and sw.a[i - 1] < s and sw.a[i] > sw.b[i - 1]:
            merges.append((leg, sw.a[i - 1], e, now + cost[i - 1]))
    if merges:
        out, swing, _ = _longer(args, out, swing, merges)
    return out + (swing,)


def _longer(args, out, swing, tries):
    """Each try (leg, s, e, cost now) redone as one swing from planted frame s to planted frame
    e, kept where it costs less. Returns (out, swing, the tries whose swing still breaks a
    limit, with their cost)."""
    longer = np.zeros_like(swing)           # only the lengthened swings are redone
    for leg, s, e, _ in tries:
        longer[s + 1:e, leg] = True
    out2, sw2, cost2 = _swings_pass(*args[:-1], 1, *out, longer)
    by_end = dict(zip(zip(sw2.leg, sw2.b), cost2))
    final = swing.copy()
    merged = [x.copy() for x in out]
    still = []
    for leg, s, e, old in tries:
        new = by_end.get((leg, e), np.inf)
        if new < old:
            final[s + 1:e, leg] = True
            for x, y in zip(merged, out2):
                x[s:e + 1, leg] = y[s:e + 1, leg]
        if min(new, old) >= HARD:
            still.append((leg, s, e, min(new, old)))
    return tuple(merged), final, still


def _second_tries(sw: "_Swings", cost: np.ndarray) -> list:
    """(leg, s, e, cost now) of the longer swing each swing that still breaks a limit tries
    next, from the planted frame s to the planted frame e: through a tap (a single planted
    frame between it and the swing before or after it: the foot lands and lifts again in the
    next frame, reversing its joints within two frames; or a stance before it too short to
    lift off from any sooner) the two swings become one, from the hold before to the hold
    after; otherwise it lifts off EARLY_LIFT of its length sooner, keeping MIN_STANCE planted
    frames (joint_space_swings merges it with the swing before if that is not enough). Tries
    of one leg never overlap: two broken swings on either side of a tap share one."""
    tries = []
    for i in np.nonzero(cost >= HARD)[0]:
        leg, a, b = sw.leg[i], sw.a[i], sw.b[i]
        # swings are ordered by leg, then time: the previous one of this leg lands at its b
        before = i > 0 and sw.leg[i - 1] == leg
        after = i + 1 < sw.n and sw.leg[i + 1] == leg
        landed = sw.b[i - 1] if before else 0
        # a stance before it too short to lift off from any sooner counts as a tap
        tap_before = before and a - landed <= MIN_STANCE
        tap_after = after and sw.a[i + 1] == b
        s = sw.a[i - 1] if tap_before else a
        e = sw.b[i + 1] if tap_after else b
        old = cost[i] + (cost[i - 1] if tap_before else 0.0) + (cost[i + 1] if tap_after else 0.0)
        if not (tap_before or tap_after):
            s = max(a - max(2, int(np.ceil(EARLY_LIFT * (b - a)))), landed + MIN_STANCE)
        if s >= a and e <= b:
            continue
        if not (tries and tries[-1][0] == leg and s < tries[-1][2]):
            tries.append((leg, s, e, old))   # (a broken swing before a tap took this one in)
    return tries


def _swings_pass(rays, hip, q_seg, side, l1, l2, lim: Limits, rounds, q_u, q_t, mid, end, swing):
    """One joint_space_swings pass: ((q_u, q_t, mid, end), the _Swings, (n,) each swing's final
    cost)."""
    U_all = quat_mul(quat_conj(q_seg), q_u)
    T_all = quat_mul(quat_conj(q_u), q_t)
    sw = _Swings(swing)
    if sw.n == 0:
        return (q_u, q_t, mid, end), sw, np.zeros(0)
    f, lg = sw.f, sw.lg
    own, _ = _own_faults(rays, lim, hip[f, lg], q_seg[f, lg], U_all[f, lg], T_all[f, lg],
                         l1, l2, sw.inner, sw.sid[1:] == sw.sid[:-1])
    w = lim.weight(f)
    own *= w
    feet = end.copy()
    redone = np.zeros(swing.shape, bool)
    plan = (U_all.copy(), T_all.copy())     # the planner's poses, a candidate in every pass
    for _ in range(rounds):
        for parity in (0, 1):
            mine = ((sw.leg // 2) % 2 == parity)[sw.sid]
            k = np.nonzero(mine)[0]
            cost = _entry_costs(sw, own, w, feet, lim, k)
            best = np.bincount(sw.sid[k], weights=cost, minlength=sw.n)
            todo = best > 0
            if todo.any():
                _redo(rays, lim, hip, q_seg, U_all, T_all, side, l1, l2, sw, feet, own, best,
                      todo, redone, plan)
    every = np.arange(len(f))
    final = _entry_costs(sw, own, w, feet, lim, every)
    broken = np.bincount(sw.sid, weights=final, minlength=sw.n)
    if (broken >= HARD).any():
        _repair(rays, lim, hip, q_seg, side, l1, l2, sw, U_all, T_all, feet, own, w, redone,
                broken)
        final = _entry_costs(sw, own, w, feet, lim, every)
    q_u2, q_t2, mid2, end2 = _pose(q_seg, hip, U_all, T_all, l1, l2)
    # frames left as planned keep the planner's exact numbers (no round trip through rotations)
    r = redone[..., None]
    return ((np.where(r, q_u2, q_u), np.where(r, q_t2, q_t), np.where(r, mid2, mid),
             np.where(r, end2, end)), sw, np.bincount(sw.sid, weights=final, minlength=sw.n))


def _candidates() -> list:
    """The joint-space candidates, in the order _redo tries them: (kind, raise profile, raise,
    swivel, flex, delay, yaw). "plan" is the planner's swing, "even" the same path at an even
    joint pace, "arc" the slerp from the last planted pose to the touchdown pose, "bump" the
    current swing lifted round its crowded frame, "peak" the best so far with its fastest step
    spread (raise: the entries on either side); a delay > 0 waits that fraction of the swing
    at the start, < 0 lands that much early; a yaw swings the leg forward (> 0) or back round
    the hip (a neighbour swinging at the same time gets out of the way)."""
    out = [("plan", None, 0.0, 0.0, 0.0, 0.0, 0.0), ("even", None, 0.0, 0.0, 0.0, 0.0, 0.0)]
    out += [("arc", p, r, 0.0, 0.0, 0.0, 0.0) for p in PROFILES for r in RAISES]
    out += [("arc", PROFILES[0], r, sv, 0.0, 0.0, 0.0) for sv in SWIVELS
            for r in RAISES[::2]]
    out += [("arc", p, r, 0.0, fx, 0.0, 0.0) for fx in FLEXES for p in PROFILES
            for r in RAISES[:4]]
    out += [(kind, PROFILES[1], r, 0.0, 0.0, dl, 0.0) for dl in DELAYS
            for kind, r in (("even", 0.0), ("arc", RAISES[1]), ("arc", RAISES[3]))]
    out += [("arc", PROFILES[0], r, 0.0, 0.0, 0.0, yw) for yw in YAWS
            for r in RAISES[1:4]]
    out += [("bump", None, r, 0.0, 0.0, 0.0, 0.0) for r in RAISES[1:]]
    out += [("arc", p, r, 0.0, fx, 0.0, 0.0) for fx in TUCKS for p in PROFILES[:2]
            for r in RAISES[2::2]]
    # last, the same paths paced so each frame's share of the leg's own turn shrinks by what
    # the segment turns in the world that frame (a leg joint turns in the world by its turn
    # relative to the body plus the body's own turn)
    out += [("even/world", None, 0.0, 0.0, 0.0, 0.0, 0.0)]
    out += [("arc/world", p, r, 0.0, 0.0, 0.0, 0.0) for p in PROFILES[:2] for r in RAISES]
    # and the raises too steep at the ends for the turn limit (a sooner-rising profile turns the
    # leg by raise x profile(1 / frames) in the first and last frame), eased: the raise grows
    # and shrinks by at most RAISE_STEP x turn per frame from either end of the swing
    out += [("arc/eased", p, r, 0.0, 0.0, 0.0, 0.0) for p in PROFILES
            for r in RAISES[3:]]
    # and the best so far, its fastest turn spread evenly over the frames round it, on its own
    # path (a path clear of everything but for one fast turn)
    out += [("peak", None, w, 0.0, 0.0, 0.0, 0.0) for w in PEAK_SPREAD]
    return out


#: the candidates, in order (see _candidates)
CANDIDATES = tuple(_candidates())


#: the joint-space candidates whose poses of a swing depend on the other swings tried with it
#: (their progress is a running sum over every entry tried), so each is tried with exactly the
#: swings still open
SHARED = ("even", "even/world", "peak")
#: _redo tries several candidates in one batch of rays while each costs fewer entries than this
#: (a speed setting only: each entry's faults are its own; 4096 cost about 5 % less than 2048 on
#: a crowd's swings, 8192 no less again)
BATCH_ENTRIES = 4096


@dataclass
class _Trial:
    """The entries of the swings _redo improves, and what their candidate poses are made of:
    swing id, frame, leg, progress, inner, segment rotation, hip, weight and neighbours' feet of
    each entry; its current, planned, first and last poses; the progress at which its swing
    first crowds a neighbour (u_c), paced by the segment's turn (u_world), and the frames to
    the nearer end of its swing (from_end)."""

    sk: np.ndarray
    f: np.ndarray
    lg: np.ndarray
    u: np.ndarray
    inner: np.ndarray
    qs: np.ndarray
    hp: np.ndarray
    wk: np.ndarray
    near: np.ndarray
    U0: np.ndarray
    T0: np.ndarray
    U_plan: np.ndarray
    T_plan: np.ndarray
    U_first: np.ndarray
    U_last: np.ndarray
    T_first: np.ndarray
    T_last: np.ndarray
    u_c: np.ndarray
    u_world: np.ndarray
    from_end: np.ndarray
    #: the slerps of the entries asked about so far, per pace and delay (_arc): (done (n,)
    #: bool, U (n, 4), T (n, 4)) over all entries
    arcs: dict = field(default_factory=dict)

    def _arc(self, j, uj, key):
        """(U, T) the slerps from the first to the last pose of entries j at progress uj (a
        function of the entry, its pace and delay `key`), each entry's kept for the later
        candidates and blocks of the same key (slerps are element by element: the same bits
        in any batch)."""
        got = self.arcs.get(key)
        if got is None:
            n = len(self.sk)
            got = self.arcs[key] = (np.zeros(n, bool), np.empty((n, 4)), np.empty((n, 4)))
        done, U, T = got
        new = np.nonzero(~done[j])[0]
        if len(new):
            e = j[new]
            U[e] = quat_slerp(self.U_first[e], self.U_last[e], uj[new])
            T[e] = quat_slerp(self.T_first[e], self.T_last[e], uj[new])
            done[e] = True
        return U[j], T[j]

    def pose(self, cand, j, side, l1, l2, turn, chosen_U, chosen_T):
        """(U, T) local poses of entries j under candidate `cand` (see _candidates); "peak"
        spreads the chosen poses chosen_U, chosen_T."""
        kind, profile, r, swivel, flex, delay, yaw = cand
        sj, uj, s = self.sk[j], self.u[j], side[self.lg[j]]
        pace = (kind.endswith("/world"), delay)
        if kind.endswith("/world"):       # paced by the turn the segment leaves the leg
            kind, uj = kind[:-6], self.u_world[j]
        cap = np.inf
        if kind.endswith("/eased"):
            kind, cap = kind[:-6], RAISE_STEP * turn * self.from_end[j]
        if delay > 0:
            uj = np.clip((uj - delay) / (1.0 - delay), 0.0, 1.0)
        elif delay < 0:
            uj = np.clip(uj / (1.0 + delay), 0.0, 1.0)
        if kind == "plan":
            return self.U_plan[j], self.T_plan[j]
        if kind == "even":
            return _retimed(self.U_plan[j], self.T_plan[j], sj, uj)
        if kind == "peak":
            return _peak_spread(chosen_U[j], chosen_T[j], sj, int(r))
        if kind == "bump":                # the current swing, lifted round its crowded frame
            bump = np.nan_to_num(np.exp(-((uj - self.u_c[j]) / BUMP_WIDTH) ** 2)
                                 * np.sin(np.pi * uj))
            return quat_mul(quat_about(np.broadcast_to(_Z, (len(j), 3)), s * r * bump),
                            self.U0[j]), self.T0[j]
        # the "arc" family, the only one with a swivel, a yaw or a flex (see _candidates)
        U, T = self._arc(j, uj, pace)
        return arc_pose(U, T, s, profile(uj), np.sin(np.pi * uj) if yaw else uj,
                        np.broadcast_to(cap, uj.shape), r, swivel, yaw, flex, l1, l2)


def _trial(lim, hip, q_seg, U_all, T_all, sw: _Swings, feet, todo, plan) -> _Trial:
    """The _Trial of the swings flagged in `todo`."""
    k = np.nonzero(todo[sw.sid])[0]
    sk, f, lg, u, inner = sw.sid[k], sw.f[k], sw.lg[k], sw.u[k], sw.inner[k]
    qs = q_seg[f, lg]
    first, last = sw.start[k], sw.last[k]
    near = sw.near(feet, k)
    # where each swing first crowds a neighbour now: a local lift there is a candidate too
    crowd = _crowding(feet[f, lg], inner, near, lim) > 0
    u_c = np.full(sw.n, np.nan)
    ck = np.nonzero(crowd)[0][::-1]
    u_c[sk[ck]] = u[ck]
    # paces: the segment's turn left to the leg (".../world"), raises eased from either end of
    # the swing (".../eased")
    return _Trial(sk, f, lg, u, inner, qs, hip[f, lg], lim.weight(f), near, U_all[f, lg],
                  T_all[f, lg], plan[0][f, lg], plan[1][f, lg],
                  U_all[sw.f[first], sw.lg[first]], U_all[sw.f[last], sw.lg[last]],
                  T_all[sw.f[first], sw.lg[first]], T_all[sw.f[last], sw.lg[last]], u_c[sk],
                  _world_paced(qs, sk, lim.turn), np.minimum(f - sw.a[sk], sw.b[sk] - f))


def _judged(rays, lim, tr: _Trial, j, poses, l1, l2, best) -> list:
    """[(own cost (len(j),), score (n,) per swing)] of each candidate's poses (U, T) of entries
    j, all in one batch of rays (each entry's faults are its own): whole for the swings it
    scores below their `best` (n,) now, else a score of at least `best` (_bounded_faults)."""
    m, sj, n = len(poses), tr.sk[j], len(best)
    same = np.tile(np.r_[sj[1:] == sj[:-1], False], m)[:-1]       # no step between candidates
    key = (np.arange(m)[:, None] * n + sj).ravel()                 # candidate x swing
    cost, score, _ = _bounded_faults(
        rays, lim, np.tile(tr.hp[j], (m, 1)), np.tile(tr.qs[j], (m, 1)),
        np.concatenate([p[0] for p in poses]), np.concatenate([p[1] for p in poses]), l1, l2,
        np.tile(tr.inner[j], m), same, np.tile(tr.wk[j], m), np.tile(tr.near[j], (m, 1, 1)), key,
        np.tile(best, m))
    return list(zip(np.split(cost, m), np.split(score, m)))


def _block(i: int, entries: int) -> range:
    """The candidates _redo tries in one batch from CANDIDATES[i], for `entries` entries each:
    a "peak" alone (it spreads the poses chosen so far), else up to the next "peak" while the
    batch keeps within BATCH_ENTRIES."""
    if CANDIDATES[i][0] == "peak":
        return range(i, i + 1)
    end = i + max(1, BATCH_ENTRIES // max(entries, 1))
    while end > i + 1 and any(c[0] == "peak" for c in CANDIDATES[i:end]):
        end -= 1
    return range(i, min(end, len(CANDIDATES)))


def _redo(rays, lim, hip, q_seg, U_all, T_all, side, l1, l2, sw: _Swings, feet, own, best,
          todo, redone, plan) -> None:
    """The swings flagged in `todo` (best: their current cost) get the best joint-space
    candidate: U_all, T_all (local poses), feet (F, L, 3), own (per-entry own costs) and
    redone (F, L) are updated in place. Candidates are tried in order, each on the swings it
    has not brought to no cost yet; several at once (_block), then taken in turn as if one by
    one (one tried with swings that closed in the meantime is tried again, when SHARED)."""
    k = np.nonzero(todo[sw.sid])[0]
    tr = _trial(lim, hip, q_seg, U_all, T_all, sw, feet, todo, plan)
    chosen_U, chosen_T, chosen_own = tr.U0.copy(), tr.T0.copy(), own[k].copy()
    i = 0
    while i < len(CANDIDATES):
        open_ = todo & (best > 0)
        if not open_.any():
            break
        j = np.nonzero(open_[tr.sk])[0]          # entries of the swings still to improve
        block = _block(i, len(j))
        poses = [tr.pose(CANDIDATES[x], j, side, l1, l2, lim.turn, chosen_U, chosen_T)
                 for x in block]
        for x, (U, T), (c_own, score) in zip(block, poses,
                                              _judged(rays, lim, tr, j, poses, l1, l2, best)):
            now = todo & (best > 0)
            if x > i and (not now.any() or (CANDIDATES[x][0] in SHARED
                                            and not np.array_equal(now, open_))):
                break
            take = now & (score < best)
            best[take] = score[take]
            sel = take[tr.sk[j]]
            chosen_U[j[sel]], chosen_T[j[sel]], chosen_own[j[sel]] = U[sel], T[sel], c_own[sel]
            i = x + 1
    f, lg = tr.f, tr.lg
    changed = (np.any(chosen_U != tr.U0, axis=-1) | np.any(chosen_T != tr.T0, axis=-1)) & tr.inner
    U_all[f[changed], lg[changed]] = chosen_U[changed]
    T_all[f[changed], lg[changed]] = chosen_T[changed]
    own[k] = chosen_own
    redone[f[changed], lg[changed]] = True
    feet[f[changed], lg[changed]] = _pose(tr.qs[changed], tr.hp[changed], chosen_U[changed],
                                          chosen_T[changed], l1, l2)[3]


def _grid_poses(U, T, side, l1, l2):
    """(n, G, 4) local poses U, T (n, 4) each turned by every REPAIR_GRID entry (the leg raised
    about the body's long axis, swivelled round the hip -> foot line, yawed round the hip, the
    foot tucked in); side: +1 left, -1 right."""
    n, G = len(U), len(REPAIR_GRID)
    r, yaw, swivel, flex = (np.tile(REPAIR_GRID[:, i], n) for i in range(4))
    Ub, Tb = np.repeat(U, G, axis=0), np.repeat(T, G, axis=0)
    Ub = quat_mul(quat_about(np.broadcast_to(_Z, (n * G, 3)), side * r), Ub)
    Ub = _swivel(Ub, Tb, swivel, l1, l2)
    Ub = quat_mul(quat_about(np.broadcast_to(_Y, (n * G, 3)), side * yaw), Ub)
    Tb = _flex(Ub, Tb, flex, l1, l2)
    return Ub.reshape(n, G, 4), Tb.reshape(n, G, 4)


@dataclass
class _Layer:
    """The sampled poses of one frame of a repaired swing (see _searched): Q (4, n, 4) their
    local and world upper and tip bone rotations (U, T, q_u, q_t; float32: only turns between
    frames are read from them, and the swing is checked afresh), their feet, which touch a
    surface, their own costs and the frame's weight."""

    Q: np.ndarray
    end: np.ndarray
    touch: np.ndarray
    cost: np.ndarray
    w: float


def _step_cost(a: _Layer, b: _Layer, lim: Limits) -> np.ndarray:
    """(n_a, n_b) the cost of stepping from each pose of layer a to each of the next frame's b:
    a joint turning more than `turn` (1) or `hard_turn` (HARD, and OVER per radian beyond it),
    a touching foot sliding (1), and SMOOTH x (1 - cos(half the largest turn))."""
    d = np.abs(np.matmul(a.Q, b.Q.transpose(0, 2, 1)))         # cos(half of each turn)
    dot = np.minimum(np.minimum(d[0], d[1]), np.minimum(d[2], d[3])).astype(np.float64)
    hard = lim.breaking_turn
    c = (dot < np.cos(0.5 * lim.turn)) + (HARD - 1.0) * (dot < np.cos(0.5 * hard))
    over = np.nonzero(dot < np.cos(0.5 * hard))
    c[over] += OVER * (2.0 * np.arccos(dot[over]) - hard)
    i, j = np.nonzero(a.touch)[0], np.nonzero(b.touch)[0]
    if len(i) and len(j):
        slide = length(a.end[i, None] - b.end[None, j]) > lim.slide
        c[np.ix_(i, j)] += slide
    return a.w * c + SMOOTH * (1.0 - dot)


def _searched(rays, lim: Limits, hp, qs, U, T, near, w, side, l1, l2, lo: int, hi: int):
    """The frames strictly between entries lo and hi of one swing (hp, qs, U, T, near (the
    neighbours' feet), w: per entry) re-chosen among poses sampled round the current ones and
    round the slerp from lo's pose to hi's (REPAIR_GRID), as the cheapest sequence from lo's
    pose to hi's (trellis.cheapest_path). Returns the swing's (U, T) with those frames
    replaced."""
    free = np.arange(lo + 1, hi)
    m = len(free)
    t = (free - lo) / (hi - lo)
    arc_U = quat_slerp(np.broadcast_to(U[lo], (m, 4)), np.broadcast_to(U[hi], (m, 4)), t)
    arc_T = quat_slerp(np.broadcast_to(T[lo], (m, 4)), np.broadcast_to(T[hi], (m, 4)), t)
    Us, Ts = (np.concatenate(p, axis=1) for p in zip(_grid_poses(U[free], T[free], side, l1, l2),
                                                    _grid_poses(arc_U, arc_T, side, l1, l2)))
    S = Us.shape[1]
    all_U = np.concatenate([Us.reshape(-1, 4), U[[lo, hi]]])   # the samples, then lo's, hi's
    all_T = np.concatenate([Ts.reshape(-1, 4), T[[lo, hi]]])
    at = np.r_[np.repeat(free, S), lo, hi]                      # each row's entry
    sampled = np.arange(len(at)) < m * S
    cost, q_u, q_t, end, touch = _node_faults(rays, lim, hp[at], qs[at], all_U, all_T, l1, l2,
                                              sampled)
    cost += _crowding(end, sampled, near[at], lim)
    # a layer per frame: lo's pose, each frame's samples clear of every hard fault (and its
    # unchanged pose, so that a path always exists), hi's pose
    kept = [np.r_[m * S]] + [j * S + np.nonzero((cost[j * S:(j + 1) * S] < HARD) |
                                                (np.arange(S) == 0))[0] for j in range(m)]
    kept.append(np.r_[m * S + 1])
    layers = [_Layer(np.stack([all_U[rows], all_T[rows], q_u[rows], q_t[rows]]).astype(np.float32),
                     end[rows], touch[rows], w[at[rows[0]]] * cost[rows] * sampled[rows],
                     float(w[at[rows[0]]])) for rows in kept]
    pick, _ = cheapest_path([x.cost for x in layers],
                            lambda k: _step_cost(layers[k], layers[k + 1], lim))
    U, T = U.copy(), T.copy()
    U[free] = [all_U[rows[p]] for rows, p in zip(kept[1:-1], pick[1:-1])]
    T[free] = [all_T[rows[p]] for rows, p in zip(kept[1:-1], pick[1:-1])]
    return U, T


def _repair(rays, lim: Limits, hip, q_seg, side, l1, l2, sw: _Swings, U_all, T_all, feet, own,
            w, redone, cost) -> None:
    """The last resort for each swing still breaking a limit (cost >= HARD): its frames from
    REPAIR_MARGINS[0] before its first broken frame to as many after its last are searched
    afresh (_searched), and again with each wider margin while that is not enough. A result is
    kept only where the whole swing then costs less and breaks a limit in fewer frames.
    U_all, T_all (local poses), feet, own (per-entry own costs) and redone are updated in
    place."""
    for i in np.nonzero(cost >= HARD)[0]:
        k = np.nonzero(sw.sid == i)[0]
        f, lg = sw.f[k], sw.lg[k[0]]
        hp, qs, near = hip[f, lg], q_seg[f, lg], sw.near(feet, k)
        now = _entry_costs(sw, own, w, feet, lim, k)
        bad = np.nonzero(now >= HARD)[0]
        for margin in REPAIR_MARGINS if len(bad) else ():
            lo, hi = max(bad[0] - margin, 0), min(bad[-1] + 1 + margin, len(k) - 1)
            U, T = _searched(rays, lim, hp, qs, U_all[f, lg], T_all[f, lg], near, w[k],
                             side[lg], l1, l2, lo, hi)
            c_own, end = _own_faults(rays, lim, hp, qs, U, T, l1, l2, sw.inner[k],
                                     np.ones(len(k) - 1, bool))
            c_own *= w[k]
            new = c_own + w[k] * _crowding(end, sw.inner[k], near, lim)
            if new.sum() < now.sum() and (new >= HARD).sum() < len(bad):
                changed = (np.any(U != U_all[f, lg], axis=-1) | np.any(T != T_all[f, lg], axis=-1))
                U_all[f, lg], T_all[f, lg], own[k] = U, T, c_own
                feet[f, lg] = end
                redone[f[changed], lg] = True
                break
            if hi - lo == len(k) - 1:
                break                              # the whole swing was searched
