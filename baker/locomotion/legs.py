"""Legs for the whole bake in one vectorized pass after the spine (like body.py).

Walking legs (two bones each, one pair per trunk segment):
1. Gait clock (gait.py): the phase advances with the distance the body travels along its
   trail; the duty factor is the setting, lowered at high speed so no leg sweeps faster than
   `max_swing_rate`.
2. Anchors: each leg's neutral foot spot in its segment frame, pulled in on the inside of tight
   bends and next to walls (one batch of horizontal rays from the hips).
3. Steps: touchdown when a leg's phase crosses an integer, liftoff at integer + duty. A foothold
   is the anchor placed ahead by half the stance sweep (duty * stride / 2) at touchdown. Safety
   rules keep every planted foot usable:
   - a swing lasts at most `settle_time` seconds: when the body slows or stops, the foot lands
     (at most half a stance sweep ahead of its anchor) and stays put;
   - a planted foot lifts early (a frame before it happens) when the body would carry it out of
     reach, too far behind, under the body, or behind a wall, or turn its leg round the hip by
     more than STANCE_TURN in one frame (a fast, tight turn); when the phase's next touchdown
     is far off (a slow body), it lands settle_time later on a new hold (_land_early).
   The loop runs over step cycles (a few hundred a minute), vectorized over legs.
4. Footholds: one batch of ray casts for every touchdown of every leg: straight down the
   segment's up axis, then fans tilted toward the body, also from origins pulled in. A hold must
   face up, be in reach, outside the body, not straight down a ledge and in sight of its hip.
   Planted feet of neighbouring legs are then pushed apart ("legs that know where their
   neighbours are"), a level hold kept level where some push allows it.
5. Swing: the foot sweeps around its hip in the segment frame, from the old hold as seen at
   liftoff to the new one as seen at touchdown, with a lift; raised where the surface below or
   a wall is in the way; lifted over a neighbour's foot; re-timed to an even angular pace where
   the path is uneven. Swings (from the last planted frame) in which a leg joint would still
   turn more than EVEN_JOINT in a frame are re-timed to an even pace in joint space. A
   swinging leg that would still reach through something (past a wall's corner) is drawn in
   toward its hip, eased in and out. It lands exactly on the hold.
6. Two-bone IK for all frames x legs at once (geometry/ik.py), knee pole across the leg (up and
   out); knees swivel about the hip->foot line where a bone would touch the environment, the
   swivel easing in and out at most SWIVEL_RATE per frame. A planted leg that no swivel clears
   lifts off the frame before; the stance rules of 3-4 and steps 5-6 run again (at most
   STUCK_ROUNDS times). Bones are tested with FILE_MARGIN to spare for the files' keyframe
   reduction.

Ultimate legs and antennae are posed by angles in their segment's frame; their raise/pitch is
lifted where a bone would go through the environment (candidate angles, one batch of rays),
easing in and out at most CHAIN_RAISE_RATE per frame and never below a raise that clears.
Forcipules keep their rest posture on the head (not driven here).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from baker.config import LegsConfig, RigConfig
from baker.geometry.conventions import FORWARD, LEFT, UP
from baker.geometry.ik import bone_frames, reach_clamp, soft_clamp, two_bone_ik
from baker.geometry.transforms import (cross, dot, length, limit_rotation, normalize, quat_angle,
                                       quat_conj, quat_mul, quat_rotate)
from baker.locomotion.body import SPINE_FRAME_TURN, BodyFrames
from baker.locomotion.gait import gait_clock
from baker.locomotion.leg_kernels import leg_traces
from baker.locomotion.near import NearBodies, frames_of
from baker.locomotion.swing import Limits, joint_space_swings
from baker.locomotion.trellis import cheapest_path
from baker.rig.limbs import LegLayout, chains, leg_layout, leg_pole

#: the reachable fraction of the full leg length used for planning footholds
PLAN_REACH = 0.74
#: a planted foot lifts before its hip gets further than this fraction of the leg's length
LIFT_REACH = 0.8
#: fan of foothold rays: tilt from the segment's down axis toward the body [rad]
FAN = np.radians([0.0, 25.0, 45.0, 65.0])
#: foothold fans also start from origins pulled this fraction of the way toward the hip
FAN_PULL = (0.0, 0.35, 0.6)
#: points along the hip -> foot line (fractions) whose clearance sets a swing's lift
LINE_SAMPLES = (0.4, 0.6, 0.8, 1.0)
#: footholds are preferred where the surface is level this fraction of the leg's reach around
EDGE_CLEAR = 0.2
#: a foothold lies at most this many times its outward distance below its hip
MAX_DROP = 1.2
#: what the files may move a joint whose bone passes near a surface [BL]: twice the bound the
#: keyframe reduction keeps such joints within (a tenth of its default 0.001 BL tolerance)
FILE_MARGIN = 0.0002
#: the last bit of a tip bone (its foot's end) that may touch a surface [BL]: the 0.005 BL the
#: files are judged by (metrics) less FILE_MARGIN
BONE_TOL = 0.005 - FILE_MARGIN
#: ... and a bone keeps FILE_MARGIN over a surface below it (as a share of BONE_TOL)
GRAZE = FILE_MARGIN / BONE_TOL
#: a foothold's surface faces at most this far from the segment's up [rad]
FOOT_SLOPE = np.radians(65.0)
#: next to a wall, feet stay within this fraction of the free distance from hip to wall
WALL_FOLD = 0.7
#: ... but never nearer its hip than this share of the leg's open-ground lever
FOLD_MIN = 0.35
#: inside a bend of radius R, feet stay within INNER_REACH * R of the centre line
INNER_REACH = 0.6
#: swing progress peak rate relative to its mean (see _swing_shape)
SWING_PEAK = 1.1
#: frames ahead over which the shortest lever sets the duty factor (see _levers)
LEVER_LEAD = 15
#: frames added to a swing's longest time for the margins the legs are planned over before
#: the first frame and after the last (see _planned_with_margins)
MARGIN_FRAMES = 4
#: the duty factor never drops below this at high speed
MIN_DUTY = 0.4
#: frames ahead in which a planted foot is checked against its hip (reach, under the body)
LIFT_WINDOW = 48
#: ... or fewer, the shortest of these that reaches the stance's end (LIFT_WINDOW last)
WINDOWS = (8, 16, 32, LIFT_WINDOW)
#: a swinging foot's angle about its hip stays within this of straight out [rad]
SWEEP_LIMIT = np.radians(80.0)
#: knee swivels about the hip->foot axis tried when a leg bone would go through something [rad]
KNEE_SWIVELS = np.radians([20.0, -20.0, 40.0, -40.0, 60.0, -60.0, 85.0, -85.0])
#: a knee swivel (clearing the environment) changes by at most this much per frame [rad]
SWIVEL_RATE = np.radians(8.0)
#: rounds in which eased frames whose partial swivel hits something join their run, whose swivel
#: is chosen again
KNEE_EASE_ROUNDS = 4
#: a planted foot lifts before the body turns its leg by more than this in one frame [rad]
STANCE_TURN = np.radians(24.0)
#: an ultimate leg or antenna raised clear of the environment rises and falls at most this much
#: per frame [rad]
CHAIN_RAISE_RATE = np.radians(4.0)
#: rounds of easing an ultimate leg's or antenna's raises in which a frame that still touches
#: something takes the next clearing raise (legs._eased_chain)
CHAIN_ROUNDS = 8
#: a chain still touching after those rounds has its raises searched afresh (_chain_path) on a
#: grid this fine [rad] ...
CHAIN_GRID = np.radians(2.0)
#: ... over its touching frames and the first of these many frames either side whose path is
#: clear, its raise changing by at most CHAIN_STEEP_RATE per frame [rad] (each radian beyond
#: CHAIN_RAISE_RATE costs CHAIN_STEEP_COST; a bone in the environment costs CHAIN_HIT_COST)
CHAIN_PATH_MARGINS = (24, 48, 96)
CHAIN_STEEP_RATE = np.radians(12.0)
CHAIN_STEEP_COST = 10.0
CHAIN_HIT_COST = 1e6
#: a swinging foot whose leg would pass through the environment is drawn toward its hip to
#: the first of these fractions of its distance that clears
PULL_IN = (0.85, 0.7, 0.55, 0.4)
#: ... with the pull changing by at most this fraction per frame
PULL_RATE = 0.1
#: swings turning the leg by more than this in a frame are re-timed to an even pace [rad]
EVEN_SWING = np.radians(18.0)
#: swings turning a leg joint (IK) by more than this in a frame are re-timed in joint space [deg]
EVEN_JOINT = 24.0
#: a swinging foot rises at most this many upper-bone lengths above its hip
SWING_CEILING = 0.8
#: swing wall checks: at most this many half-lift raises
WALL_STEPS = 4
#: largest turn of a leg joint in one frame (in its own space and in the world) [deg]; swings
#: that exceed it are redone in joint space
SWING_TURN = 27.0
#: a foot touching a surface in two frames in a row moves at most this many body lengths
SLIDE = 0.004
#: a swinging foot keeps at least this many segment spacings from its neighbours' feet
SWING_GAP = 0.24
#: what breaks a limit in a joint-space swing (swing.Limits): a joint turning more than
#: HARD_TURN deg in a frame, a foot nearer than HARD_GAP spacings to a neighbour's, or deeper
#: than DEEP body lengths in a solid (the bake's limits are 30 deg, 0.2 spacing, 0.5% BL)
HARD_TURN = 29.0
HARD_GAP = 0.21
DEEP = 0.004
#: a swinging foot stays at least this fraction of the leg's full length from its hip
MIN_REACH = 0.36
#: inside a swing a foot stays at least this fraction of the rig's lift off every surface
SWING_CLEAR = 0.5
#: planted feet of neighbouring legs keep at least this many segment spacings apart
NEIGHBOUR_GAP = 0.3
#: rounds of spreading neighbours' holds and lifting unusable ones (a foot that lands early
#: gets a new hold, spread and checked in the next round)
STANCE_ROUNDS = 4
#: a foot lifted early lands early when it would otherwise swing longer than this many
#: settle_times (a slow body's swings are settle_time long: one lifted a frame or two early
#: keeps its touchdown)
HANG_SWINGS = 2.0
#: the legs are planned at most this many times over, each time lifting the feet whose planted
#: leg goes through something (_lift_stuck), until no stance is shortened: nearly every solve
#: needs one round; a foot lifted from under a step's edge can land under it again, and a
#: crowd creature on the multi-storey level needed four (three left 2 bone-frames through the
#: step)
STUCK_ROUNDS = 6
#: [Hz] the ultimate legs' slow sway: yaw and pitch frequencies
ULTIMATE_SWAY_HZ = (0.35, 0.22)


@dataclass(frozen=True)
class LegFrames:
    """World frames of the limb joints, per exported frame.

    names     : K driven limb joint names (walking legs first: upper, tip per leg; then chains)
    positions : (F, K, 3) float64, metres, world joint origins
    rotations : (F, K, 4) float64, xyzw world; bones along local +Y
    feet      : (F, L, 3) float64, walking-leg foot tips (end of the tip bone)
    targets   : (F, L, 3) float64, where each foot was asked to be
    contacts  : (F, L) bool, foot planted
    touchdown : (F, L) bool, first frame of a stance that began when the phase said so (not an
                early, settling landing); for phase measurements
    lag       : (L,) float64, cycles, gait phase offset of each leg (the setting)
    """

    names: tuple[str, ...]
    positions: np.ndarray
    rotations: np.ndarray
    feet: np.ndarray
    targets: np.ndarray
    contacts: np.ndarray
    touchdown: np.ndarray
    lag: np.ndarray


def _axes(q: np.ndarray):
    sh = q.shape[:-1] + (3,)
    return (quat_rotate(q, np.broadcast_to(LEFT, sh)), quat_rotate(q, np.broadcast_to(UP, sh)),
            quat_rotate(q, np.broadcast_to(FORWARD, sh)))


def project_footholds(rays, points: np.ndarray, up: np.ndarray, inward: np.ndarray,
                      hips: np.ndarray, reach: float, probe: float,
                      min_out: np.ndarray | float = 0.0) -> np.ndarray:
    """Footholds on the surface near `points`, all in one batch of ray casts.

    points, up, inward, hips : (n, 3); up = segment normal, inward = toward the body's centre line
    Candidates, in order of preference: a ray straight down (along -up) from `probe` above the
    point; rays tilted toward the body (the fan, for a log's or a ledge's edge); the same from
    origins pulled toward the body. A candidate counts when it hits a surface that faces up
    (within FOOT_SLOPE of the segment's up) within `reach` of its hip and at least `min_out`
    (scalar or (n,)) outward from it, and no steeper below it than MAX_DROP (a leg does not
    reach straight down a ledge beside the body), and in sight of its hip. Without one, the
    first candidate that meets an upward face is taken (the foot stays on the surface, not in
    it), and without that the point itself is kept.
    """
    n = len(points)
    if n == 0:
        return points.copy()
    lat = dot(points - hips, inward)[..., None]                        # <= 0: distance outward
    along = normalize(cross(up, inward))
    edge = EDGE_CLEAR * reach
    cands_o, cands_d = [], []
    for pull in FAN_PULL:
        o = points + probe * up - pull * lat * inward
        for a in FAN:
            cands_o.append(o)
            cands_d.append(normalize(-np.cos(a) * up + np.sin(a) * inward))
    for shift in (1.0, -1.0, 2.0, -2.0, 3.0, -3.0):   # ahead or behind, off a step's edge
        cands_o.append(points + probe * up + shift * edge * along)
        cands_d.append(-up)
    k = len(cands_o)
    o = np.concatenate(cands_o)
    d = np.concatenate(cands_d)
    h = rays.first_hit(o, d, max_distance=4.0 * probe + reach)
    pts = h.points.reshape(k, n, 3)
    facing = _faces_up(h.normals.reshape(k, n, 3), up[None])
    out_dist = -dot(pts - hips[None], inward[None])
    drop = -dot(pts - hips[None], up[None])
    ok = (h.hit.reshape(k, n) & facing & (out_dist >= np.broadcast_to(min_out, (n,))[None])
          & (drop <= MAX_DROP * out_dist)
          & (length(pts - hips[None]) < reach))
    # of the candidates that pass, a foot takes the first that is usable and level (_usable),
    # else the first usable: each foot's first is checked alone, the rest only for the feet
    # whose first is not both
    has = ok.any(axis=0)
    p1 = np.nonzero(has)[0]
    c1 = np.argmax(ok, axis=0)[p1]
    use1, flat1 = _usable(rays, pts, up, inward, hips, reach, edge, c1, p1)
    rest = has.copy()
    rest[p1[use1 & flat1]] = False
    more = ok & rest[None, :]
    more[c1[rest[p1]], p1[rest[p1]]] = False
    kk, nn = np.nonzero(more)
    use2, flat2 = _usable(rays, pts, up, inward, hips, reach, edge, kk, nn)
    ok = np.zeros_like(ok)
    flat = np.zeros_like(ok)
    ok[c1, p1], flat[c1, p1] = use1, use1 & flat1
    ok[kk, nn], flat[kk, nn] = use2, use2 & flat2
    ok &= np.where(flat.any(axis=0)[None, :], flat, True)
    # without a usable hold the foot still goes on the surface, never into it: the first
    # candidate that meets an upward face, out of reach or not (IK leaves such a foot short,
    # in the air), else the point itself
    ok |= ~ok.any(axis=0)[None, :] & h.hit.reshape(k, n) & facing
    first = np.argmax(ok, axis=0)
    any_ok = ok.any(axis=0)
    out = points.copy()
    out[any_ok] = pts[first[any_ok], np.nonzero(any_ok)[0]]
    return out


def _usable(rays, pts, up, inward, hips, reach: float, edge: float, kk, nn):
    """(usable (m,) bool, level (m,) bool) of candidate footholds pts[kk, nn] (pts (k, n, 3);
    up, inward, hips (n, 3)) for project_footholds: a hold is a top surface in the open (not a
    face inside another solid: a ray that starts inside a step finds the step's own bottom, or
    a buried face) that its hip sees (no wall or log side between them); level (is_level, read
    for usable holds only): the surface `edge` around it is level (a foot at a stair's nosing
    or at the foot of a riser leaves its tip bone no room)."""
    ok = np.zeros(len(kk), bool)
    level = np.zeros(len(kk), bool)
    if len(kk) == 0:
        return ok, level
    ok[:] = ~rays.inside(pts[kk, nn] + 0.01 * reach * up[nn])
    i = np.nonzero(ok)[0]
    if len(i):
        v = pts[kk[i], nn[i]] - hips[nn[i]]
        dist = length(v)
        lift = 0.02 * reach * up[nn[i]]            # aim just above the hold: it lies on a surface
        ok[i[rays.occluded(hips[nn[i]], v + lift, max_distance=dist)]] = False
    i = np.nonzero(ok)[0]
    if len(i):
        level[i] = is_level(rays, pts[kk[i], nn[i]], up[nn[i]], inward[nn[i]], edge)
    return ok, level


def _cast(rays, origins, directions, max_distance=np.inf) -> tuple[np.ndarray, np.ndarray]:
    """(t (n,), prim (n,)) the cast rays.first_hit(origins, directions, max_distance) makes
    (the directions normalized as it does: t is its distance, prim >= 0 its hit) without the
    hits' points, normals and faces, which the caller does not read (for the hits alone:
    rays.occluded, the same cast)."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = normalize(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    return rays.cast(o, d, max_distance)


def _faces_up(normals: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Surface normals (..., 3) a foot can stand on: within FOOT_SLOPE of the segment's `up`
    and of the world's (on a stair the segment's up leans back with the flight, and a riser
    would face it). NaN normals (no hit) give False."""
    n = np.nan_to_num(normals)
    cos = np.cos(FOOT_SLOPE)
    return (dot(n, up) > cos) & (n @ UP > cos)


def is_level(rays, pts: np.ndarray, up: np.ndarray, inward: np.ndarray, edge: float) -> np.ndarray:
    """(n,) bool: the surface `edge` metres ahead, behind, in and out of each point (n, 3) is
    one plane with it, within half an `edge` along `up` (no step's edge or riser next to a
    foothold), and no steeper than an `edge` rise per `edge`. Opposite sides are compared with
    each other (a second difference), so a level tread under a body leaning with a flight of
    stairs, or a ramp, is level. A ray that starts inside a solid (RayCaster.inside) has a step
    or ledge taller than its start (2 `edge` up) over it: not level (its first hit would be the
    step's bottom, or the floor under it, level with the point: the foot of a flight's first
    riser or side, a plate of leaf litter)."""
    along = normalize(cross(up, inward))
    ring = np.stack([along, -along, inward, -inward], 1) * edge                 # (n, 4, 3)
    top = (pts[:, None] + ring + 2.0 * edge * up[:, None]).reshape(-1, 3)
    hr = rays.first_hit(top, np.repeat(-up, 4, axis=0), max_distance=4.0 * edge)
    rise = np.where(rays.inside(top), 4.0 * edge,
                    2.0 * edge - np.where(hr.hit, hr.distance, np.inf))
    rise = rise.reshape(-1, 4)                                            # above the point
    bend = np.abs(rise[:, [0, 2]] + rise[:, [1, 3]])                      # (n, 2): per axis
    return (np.all(np.abs(rise) < edge, axis=1) & np.all(bend < 0.5 * edge, axis=1))


def _swing_shape(u: np.ndarray) -> np.ndarray:
    """Horizontal progress along a swing, 0 -> 1, gently eased (peak rate SWING_PEAK x mean)."""
    return u - (SWING_PEAK - 1.0) * np.sin(2.0 * np.pi * u) / (2.0 * np.pi)


def spine_curvature(positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(F, S) signed curvature [1/m] of the spine at each joint, + when it bends to the joint's
    left (+X), from the turn between the neighbouring spine segments."""
    p = np.asarray(positions, float)
    d = np.diff(p, axis=1)                                   # (F, S-1, 3), tail -> head is -d
    seg = length(d)
    t = d / np.maximum(seg, 1e-12)[..., None]
    # turn angle between segment s-1 -> s and s -> s+1, seen along the joint's up axis
    up = quat_rotate(rotations, np.broadcast_to(UP, p.shape))
    cr = cross(-t[:, 1:], -t[:, :-1])                     # heading change walking forward
    ang = np.arctan2(np.einsum("fsi,fsi->fs", cr, up[:, 1:-1]),
                     np.einsum("fsi,fsi->fs", t[:, 1:], t[:, :-1]))
    k = ang / np.maximum(0.5 * (seg[:, 1:] + seg[:, :-1]), 1e-12)
    k = np.concatenate([k[:, :1], k, k[:, -1:]], axis=1)
    return gaussian_filter1d(k, 1.0, axis=1, mode="nearest")


@dataclass
class _Frames:
    """The walking legs' frames and reach limits, shared by the planning stages below.

    q, q_inv         : (F, L, 4) segment rotation of each leg, and its inverse
    left, up, fwd    : (F, L, 3) the segment's axes
    origin, hip      : (F, L, 3) the segment's origin and the leg's hip
    span             : the farthest a planted foot may be from its hip (metres)
    a_back           : (L,) how far behind its anchor a planted foot may fall before it lifts
    out_min          : (L,) how far outward of its hip a foot stays (else it is under the body)
    lever            : the shortest hip-to-anchor lever (metres), for the swing rate
    """

    lay: LegLayout
    lg: LegsConfig
    q: np.ndarray
    q_inv: np.ndarray
    left: np.ndarray
    up: np.ndarray
    fwd: np.ndarray
    origin: np.ndarray
    hip: np.ndarray
    span: float
    a_back: np.ndarray
    out_min: np.ndarray
    lever: float

    @property
    def shape(self) -> tuple[int, int]:
        return self.q.shape[:2]

    @property
    def reach(self) -> float:
        """How far from its hip a foothold is looked for (project_footholds' `reach`)."""
        return PLAN_REACH * (self.lay.l1 + self.lay.l2)

    def first_bad(self, rays, hold, start, stop, sight=False, legs=None):
        """(n,) first frame in [start, stop) where a foot of leg `legs` (n,) planted at `hold`
        (n, 3) would be out of reach, too far behind, or under the body (with `sight`, also:
        hidden from its hip behind a wall); F where there is none (legs None: one row per leg,
        n = L). Checked LIFT_WINDOW frames at a time, or the shortest of WINDOWS that reaches
        a row's stop; each row on its own, so rows of any legs and stances may share a call.
        A bad frame after stop may be found or not: stop - 1 or more then means none before
        stop."""
        F, L = self.shape
        legs = np.arange(L) if legs is None else legs
        out = np.full(len(legs), F, dtype=np.int64)
        t0 = start
        start = start.copy()
        open_ = start < stop
        while open_.any():
            rows = np.nonzero(open_)[0]
            # up to stop (inclusive: a bad frame at stop lifts the foot at stop - 1)
            need = stop[rows] - start[rows] + 1
            for lo, width in zip((0,) + WINDOWS[:-1], WINDOWS):
                g = rows[(need > lo) & ((need <= width) | (width == WINDOWS[-1]))]
                if len(g) == 0:
                    continue
                fw, bad = self._window_bad(rays, hold[g], start[g], legs[g], width, sight)
                found = bad.any(1)
                # lift one frame before it happens: a fast body can stretch a leg a lot in a
                # frame
                first = fw[found, np.argmax(bad[found], 1)]
                out[g[found]] = np.maximum(first - 1, np.minimum(t0[g[found]], first))
                start[g] += width
            open_ &= (out == F) & (start < stop)
        return out

    def _window_bad(self, rays, hold, start, ll, width: int, sight: bool):
        """(fw (n, width) frames start.., bad (n, width) bool) for first_bad: feet of legs ll
        (n,) planted at hold (n, 3), checked over `width` frames from `start` (n,)."""
        F = self.shape[0]
        lay, hip, span = self.lay, self.hip, self.span
        fw_ext = np.clip(start[:, None] - 1 + np.arange(width + 1)[None, :], 0, F - 1)
        q_inv, hip_ext = self.q_inv[fw_ext, ll[:, None]], hip[fw_ext, ll[:, None]]
        rel_ext = quat_rotate(q_inv, hold[:, None, :] - hip_ext)
        fw, rel = fw_ext[:, 1:], rel_ext[:, 1:]
        n_ext = np.sqrt(np.einsum("lwi,lwi->lw", rel_ext, rel_ext))
        bad = ((rel[..., 0] * lay.side[ll, None] < self.out_min[ll, None])
               | (n_ext[:, 1:] > span) | (rel[..., 2] < -self.a_back[ll, None]))
        # a fast turn would swing the planted leg round its hip too fast: lift first
        cos_t = np.einsum("lwi,lwi->lw", rel, rel_ext[:, :-1]) / np.maximum(
            n_ext[:, 1:] * n_ext[:, :-1], 1e-300)
        bad |= cos_t < np.cos(STANCE_TURN)
        # ... or turn one of its bones too fast in a frame (near a straight or folded knee)
        bad |= _stance_turns(hip_ext, hold, self.fwd[fw_ext, ll[:, None]],
                             self.left[fw_ext, ll[:, None]], q_inv, lay, ll,
                             self.lg.knee_out) > SWING_TURN
        if sight:
            hp = hip[fw, ll[:, None]].reshape(-1, 3)
            v = np.broadcast_to(hold[:, None, :], fw.shape + (3,)).reshape(-1, 3) - hp
            dist = length(v)
            aim = v + 0.02 * span * self.up[fw, ll[:, None]].reshape(-1, 3)
            bad |= rays.occluded(hp, aim, max_distance=dist).reshape(fw.shape)
        return fw, bad


def _leg_frames(bf: BodyFrames, cfg: RigConfig) -> _Frames:
    """Each walking leg's segment frame and hip per frame, and the reach limits of a stance."""
    lay = leg_layout(cfg)
    lg = cfg.legs
    q = bf.rotations[:, lay.segment]                                  # (F, L, 4)
    left, up, fwd = _axes(q)
    origin = bf.positions[:, lay.segment]
    hip = origin + quat_rotate(q, np.broadcast_to(lay.hip, q.shape[:-1] + (3,)))
    lever = float(np.min(lg.reach - np.abs(lay.hip[:, 0])))
    # how far behind its anchor a planted foot may fall before it must lift
    lat0 = np.linalg.norm(lay.anchor[:, [0, 1]] - lay.hip[:, [0, 1]], axis=1)
    span = LIFT_REACH * (lay.l1 + lay.l2)
    a_back = np.sqrt(np.maximum(span ** 2 - lat0 ** 2, 0.0))         # (L,)
    a_back = np.minimum(a_back, 1.5 * 0.5 * lg.duty * lg.stride_max)   # (L,)
    # a planted foot also lifts when the body turns so that it would come under the body
    # a foot stays at least this far outward of its hip (else it is under the body)
    out_min = np.full(lay.n_legs, 0.3 * lever)                         # (L,) metres
    return _Frames(lay, lg, q, q * np.array([-1.0, -1.0, -1.0, 1.0]), left, up, fwd, origin,
                   hip, span, a_back, out_min, lever)


def folded_lever(free, reach: float, hip: float):
    """[m] the lever (hip to neutral foot, across the body) of a walking leg whose hip sits
    `hip` metres out from the spine, with `free` metres clear outward of it (inf in the open):
    next to a wall the anchors fold in as in `_anchors` (reach: legs.reach), and a planted
    foot then sweeps round its hip faster at the same speed."""
    return np.clip(WALL_FOLD * np.asarray(free, dtype=np.float64), FOLD_MIN * (reach - hip),
                   reach - hip)


def _anchors(rays, lf: _Frames, bf: BodyFrames) -> np.ndarray:
    """(F, L, 3) each leg's neutral foot spot, pulled in on the inside of tight bends and next
    to walls."""
    lay, lg, left, fwd, hip = lf.lay, lf.lg, lf.left, lf.fwd, lf.hip
    F, L = lf.shape
    # anchors: on the inside of a tight bend the feet pull in toward the body, so neighbouring
    # feet do not crowd (or cross) near the bend's centre
    kappa = spine_curvature(bf.positions, bf.rotations)[:, lay.segment]       # (F, L) 1/m, +left
    inner = kappa * lay.side[None, :] > 0
    lat_max = np.where(inner, INNER_REACH / np.maximum(np.abs(kappa), 1e-9), np.inf)
    lat_min = np.abs(lay.hip[:, 0]) + FOLD_MIN * (lg.reach - np.abs(lay.hip[:, 0]))
    # ... and next to a wall they fold in: the free distance from each hip outward (one batch
    # of rays at hip and at knee height), eased over time
    free = np.full((F, L), np.inf)
    for yaw in np.radians([0.0, 40.0, -40.0]):       # straight out, ahead and behind
        out_dir = np.cos(yaw) * left * lay.side[None, :, None] + np.sin(yaw) * fwd
        for h in (0.0, 0.5 * lay.l1):
            o = hip + h * lf.up
            t, prim = _cast(rays, o.reshape(-1, 3), out_dir.reshape(-1, 3),
                            max_distance=lg.reach * 1.2)
            free = np.minimum(free, np.where(prim >= 0, t * np.cos(yaw), np.inf).reshape(F, L))
    free = -maximum_filter1d(-free, 9, axis=0, mode="nearest")
    free = np.where(np.isfinite(free), free, lg.reach * 2.0)
    free = gaussian_filter1d(free, 2.0, axis=0, mode="nearest")
    lat_max = np.minimum(lat_max, np.abs(lay.hip[None, :, 0]) + WALL_FOLD * free)
    lat = np.clip(lat_max, lat_min[None, :], lg.reach) * lay.side[None, :]
    anc = np.broadcast_to(lay.anchor, lf.q.shape[:-1] + (3,)).copy()
    anc[..., 0] = lat
    return lf.origin + quat_rotate(lf.q, anc)


@dataclass
class _Steps:
    """The step plan. Ts (C+1, L) touchdown frames (row 0: frame 0), LOs (C, L) liftoff frames,
    xs (C+1, L) landing offsets along fwd, phase_td (C+1, L) the touchdown came from the phase
    (not an early, settling landing)."""

    Ts: np.ndarray
    LOs: np.ndarray
    xs: np.ndarray
    phase_td: np.ndarray


def _levers(lf: _Frames, anchor: np.ndarray) -> np.ndarray:
    """(F,) the shortest lever (hip to anchor, across the body) of any leg at each frame: the
    anchors fold in next to walls and inside bends, and a shorter lever sweeps its foot round
    the hip faster for the same stride. Never below half the rig's own lever (a foot folded
    against a riser beside it does not slow a slow climb's gait), held a little ahead of time
    (a minimum over the next LEVER_LEAD frames) and eased, so the duty factor changes smoothly
    before the feet fold in."""
    rel = quat_rotate(lf.q_inv, anchor - lf.hip)
    lat = np.maximum(np.min(np.abs(rel[..., 0]), axis=1), 0.5 * lf.lever)
    lat = -maximum_filter1d(-lat, LEVER_LEAD, axis=0, mode="nearest", origin=-(LEVER_LEAD // 2))
    return np.minimum(gaussian_filter1d(lat, 3.0, mode="nearest"), lf.lever)


def _step_events(rays, lf: _Frames, clock, anchor: np.ndarray, times: np.ndarray) -> _Steps:
    """Touchdown and liftoff frames of every step, one cycle at a time for all legs."""
    lay, lg = lf.lay, lf.lg
    F, L = lf.shape
    phi, D, travel = clock.phase, clock.stride, clock.travel
    # duty factor: the setting, lowered at high speed so that no swing is faster than
    # max_swing_rate (a swinging foot sweeps about duty/(1-duty) * v / lever rad/s)
    ratio = lg.max_swing_rate * _levers(lf, anchor) / (SWING_PEAK * np.maximum(clock.speed, 1e-9))
    duty = np.clip(ratio / (1.0 + ratio), MIN_DUTY, lg.duty)           # (F,)
    lift_gate = np.maximum.accumulate(phi - duty)   # liftoff of cycle i: first f with this >= i - lag
    A = 0.5 * duty * D                                                # half stance sweep (F,)
    a_back, lag, legs = lf.a_back, lay.lag, np.arange(L)
    T = np.zeros(L, dtype=np.int64)
    e0 = lag.copy()                                                   # phase at frame 0
    x = np.clip(A[0] - e0 * D[0], -a_back, A[0])
    recs_T, recs_LO, recs_x, recs_phase_td = [T.copy()], [], [x], [np.zeros(L, bool)]
    i = 0
    while np.any(T < F):
        Tc = np.minimum(T, F - 1)
        lo_phase = np.searchsorted(lift_gate, i - lag, side="left")
        lo_reach = np.searchsorted(travel, travel[Tc] + x + a_back, side="left")
        # body-frame check of the planted foot, LIFT_WINDOW frames at a time, up to the phase's
        # liftoff: lift early when it would fall out of reach or come under the body
        hold = anchor[Tc, legs] + lf.fwd[Tc, legs] * x[:, None]
        lo_body = lf.first_bad(rays, hold, Tc, np.minimum(lo_phase + 1, F))
        LO = np.clip(np.minimum(np.minimum(lo_phase, lo_body), lo_reach), T, F)
        LOc = np.minimum(LO, F - 1)
        td_phase = np.searchsorted(phi, i + 1 - lag, side="left")
        td_time = np.searchsorted(times, times[LOc] + lg.settle_time - 1e-9, side="left")
        Tn = np.minimum(np.maximum(np.minimum(td_phase, td_time), LO + 1), F)
        fr = np.minimum(Tn, F - 1)
        e = phi[fr] + lag - (i + 1)
        x = np.clip(A[fr] - e * D[fr], -a_back, A[fr])
        recs_LO.append(LO)
        recs_T.append(Tn)
        recs_x.append(x)
        recs_phase_td.append(td_phase <= td_time)
        T = Tn
        i += 1
    return _Steps(np.stack(recs_T), np.stack(recs_LO), np.stack(recs_x), np.stack(recs_phase_td))


def _footholds(rays, lf: _Frames, cfg: RigConfig, anchor: np.ndarray, st: _Steps) -> np.ndarray:
    """(C+1, L, 3) the hold of every touchdown: one batch of rays."""
    L = lf.shape[1]
    legs = np.broadcast_to(np.arange(L)[None, :], st.Ts.shape)
    return _holds_at(rays, lf, cfg, anchor, st.Ts.ravel(), legs.ravel(),
                     st.xs.ravel()).reshape(st.Ts.shape + (3,))


def _holds_at(rays, lf: _Frames, cfg: RigConfig, anchor: np.ndarray, frames: np.ndarray,
              legs: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """(n, 3) the holds of touchdowns of legs `legs` at frames `frames` (n,), each `xs` along
    its segment's forward axis from its anchor (project_footholds, one batch of rays)."""
    fr = np.minimum(frames, lf.shape[0] - 1)
    pts = anchor[fr, legs] + lf.fwd[fr, legs] * xs[:, None]
    inward = -lf.left[fr, legs] * lf.lay.side[legs][:, None]
    return project_footholds(rays, pts, lf.up[fr, legs], inward, lf.hip[fr, legs], lf.reach,
                             probe=cfg.body.clearance + 2.0 * lf.lg.lift,
                             min_out=lf.out_min[legs])


def _cycles(st: _Steps, F: int) -> tuple[np.ndarray, np.ndarray]:
    """(cidx, contact), each (F, L): the hold (cycle) index of each frame and leg, and whether
    the foot is planted. One search over every leg's touchdowns st.Ts (C+1, L), each leg's
    (non-decreasing, at most F) offset past the previous leg's."""
    C1, L = st.Ts.shape
    legs = np.arange(L)
    off = legs * (F + 1)
    c = np.searchsorted((st.Ts.T + off[:, None]).ravel(), np.arange(F)[:, None] + off[None, :],
                        side="right") - 1 - legs[None, :] * C1
    cidx = np.clip(c, 0, C1 - 2)
    return cidx, np.arange(F)[:, None] < st.LOs[cidx, legs[None, :]]


def _stances(rays, lf: _Frames, cfg: RigConfig, st: _Steps, holds: np.ndarray,
             anchor: np.ndarray, times: np.ndarray):
    """Spread neighbours' holds, then lift early the feet the surface put somewhere unusable.
    Returns (holds, cidx (F, L) hold index of each frame, contact (F, L)); st.LOs is updated,
    and st.Ts, st.phase_td where an early lift lands early (_land_early: the new holds are
    then spread from their neighbours' and checked again, until no foot lands early; the
    last of STANCE_ROUNDS rounds only lifts)."""
    F = lf.shape[0]
    for r in range(STANCE_ROUNDS):
        cidx, contact = _cycles(st, F)
        holds = _spread_neighbours(holds, st.Ts, cidx, contact,
                                   NEIGHBOUR_GAP * cfg.body.spacing, rays, lf.up,
                                   probe=cfg.body.clearance + 2.0 * lf.lg.lift,
                                   level=(EDGE_CLEAR * lf.reach, -lf.left * lf.lay.side[:, None]))
        if not _lift_unusable(rays, lf, cfg, st, holds, anchor, times,
                              land=r < STANCE_ROUNDS - 1):
            break
    return (holds,) + _cycles(st, F)


def _lift_unusable(rays, lf: _Frames, cfg: RigConfig, st: _Steps, holds: np.ndarray,
                   anchor: np.ndarray, times: np.ndarray, land: bool = True) -> bool:
    """The surface (and the neighbours) put some feet elsewhere than planned: lift those early
    where they would now fall out of reach, under the body or behind a wall (the next swing
    starts sooner; with `land`, one left hanging lands early, _land_early). True when a foot
    lands early on a new hold."""
    F, L = lf.shape
    Ts, LOs = st.Ts, st.LOs
    C = len(Ts) - 1
    # every stance in one batch (first_bad's rows are independent); a stance whose touchdown
    # or hold an early landing then changes is checked again
    def check(c, legs):
        return lf.first_bad(rays, holds[c, legs].reshape(-1, 3),
                            np.minimum(Ts[c, legs], F - 1).ravel(),
                            np.minimum(LOs[c, legs] + 1, F).ravel(), sight=True,
                            legs=np.broadcast_to(legs, np.shape(Ts[c, legs])).ravel())
    bad = check(slice(0, C), np.arange(L)).reshape(C, L)
    seen_T, seen_hold = Ts[:C].copy(), holds[:C].copy()
    landed = False
    for c in range(C):
        again = np.nonzero((Ts[c] != seen_T[c]) | np.any(holds[c] != seen_hold[c], axis=-1))[0]
        if len(again):
            bad[c, again] = check(c, again)
        LOs[c] = np.clip(np.minimum(LOs[c], bad[c]), Ts[c], F)
        if land:
            landed |= _land_early(rays, lf, cfg, st, holds, anchor, times, c)
    return landed


def _land_early(rays, lf: _Frames, cfg: RigConfig, st: _Steps, holds: np.ndarray,
                anchor: np.ndarray, times: np.ndarray, c: int) -> bool:
    """A foot lifted early off hold c (a slow or stopped body: the phase's touchdown may be
    seconds away) would hang beside the body until the phase comes round. When that would take
    longer than HANG_SWINGS settle_times, it lands settle_time after its liftoff, as the
    phase's swings do, on a hold chosen for that frame, if that hold stays usable (lf.first_bad)
    for a settle_time; else a settle_time later, and so on, while that is still sooner than the
    phase's touchdown (a foot whose every hold is out of reach, beside a body rearing over an
    edge, keeps hanging rather than tapping). Updates st.Ts[c + 1], st.phase_td[c + 1] and
    holds[c + 1] in place; True when any did."""
    F, L = lf.shape
    lo = st.LOs[c]
    t_lo = times[np.minimum(lo, F - 1)]
    settle = lf.lg.settle_time
    hang = np.searchsorted(times, t_lo + HANG_SWINGS * settle - 1e-9, side="left")
    todo = (lo < F) & (hang < st.Ts[c + 1])
    landed = np.zeros(L, bool)
    k = 1
    while todo.any():
        td = np.maximum(np.searchsorted(times, t_lo + k * settle - 1e-9, side="left"), lo + 1)
        end = np.searchsorted(times, t_lo + (k + 1) * settle - 1e-9, side="left")
        todo &= end < st.Ts[c + 1]
        legs = np.nonzero(todo)[0]
        if len(legs) == 0:
            break
        new = holds[c + 1].copy()
        new[legs] = _holds_at(rays, lf, cfg, anchor, td[legs], legs, st.xs[c + 1, legs])
        start = np.minimum(td, F - 1)
        ok = todo & (lf.first_bad(rays, new, start, np.where(todo, end, start),
                                  sight=True) >= end)
        st.Ts[c + 1, ok] = td[ok]
        holds[c + 1, ok] = new[ok]
        landed |= ok
        todo &= ~ok
        k += 1
    st.phase_td[c + 1, landed] = False
    return bool(landed.any())


def _swing_progress(lf: _Frames, st: _Steps, holds, cidx, contact, clock, times):
    """Per frame and leg: the hold it left (p0), the hold it goes to (p1), its swing progress
    u in [0, 1] (0 while planted) and whether the frame is a phase touchdown."""
    F, L = lf.shape
    legs = np.arange(L)[None, :]
    p0, p1 = holds[cidx, legs], holds[cidx + 1, legs]
    lo_c = np.minimum(st.LOs[cidx, legs], F - 1)
    ph = clock.phase[:, None] + lf.lay.lag[None, :]
    ph_lo = ph[lo_c, legs]
    u_phase = (ph - ph_lo) / np.maximum(cidx + 1 - ph_lo, 1e-9)
    u_time = (times[:, None] - times[lo_c]) / lf.lg.settle_time
    swing_u = np.where(contact, 0.0, np.clip(np.maximum(u_phase, u_time), 0.0, 1.0))
    td_flag = np.zeros((F, L), bool)
    r, leg = np.nonzero(st.phase_td[1:])
    starts = st.Ts[1:][r, leg]
    td_flag[starts[starts < F], leg[starts < F]] = True
    return p0, p1, swing_u, td_flag


def _swing_arcs(lf: _Frames, st: _Steps, cidx, p0, p1, u, vert) -> np.ndarray:
    """(F, L, 3) swinging feet sweeping around their hips in the segment's frame: from the old
    hold as the segment saw it at liftoff to the new hold as it sees it at touchdown (angle and
    radius about the hip interpolated), so the leg's motion relative to the body is smooth and
    both ends are exact in the world."""
    F, L = lf.shape
    legs = np.arange(L)
    q, q_inv, hip = lf.q, lf.q_inv, lf.hip
    h = _swing_shape(u)[..., None]
    f_lo = np.minimum(st.LOs[cidx, legs[None, :]], F - 1)
    f_td = np.minimum(st.Ts[cidx + 1, legs[None, :]], F - 1)
    lg_ = np.broadcast_to(legs[None, :], (F, L))
    r0 = quat_rotate(q_inv[f_lo, lg_], p0 - hip[f_lo, lg_])
    r1 = quat_rotate(q_inv[f_td, lg_], p1 - hip[f_td, lg_])
    s_ = lf.lay.side[None, :]
    th0 = np.clip(np.arctan2(r0[..., 2], s_ * r0[..., 0]), -SWEEP_LIMIT, SWEEP_LIMIT)
    th1 = np.clip(np.arctan2(r1[..., 2], s_ * r1[..., 0]), -SWEEP_LIMIT, SWEEP_LIMIT)
    rho0 = np.hypot(r0[..., 0], r0[..., 2])
    rho1 = np.hypot(r1[..., 0], r1[..., 2])
    hh_ = h[..., 0]
    th = th0 + (th1 - th0) * hh_
    rho = rho0 + (rho1 - rho0) * hh_
    rel = np.stack([s_ * rho * np.cos(th), r0[..., 1] + (r1[..., 1] - r0[..., 1]) * hh_,
                    rho * np.sin(th)], -1)
    # exact at the ends whatever the clipping: blend the straight chord back in near u = 0, 1
    chord = r0 + (r1 - r0) * h
    ends = (np.cos(np.pi * u) ** 8)[..., None]
    rel = ends * chord + (1.0 - ends) * rel
    # the arc never bulges further out than its ends (a wall beside the body stays clear)
    out_max = np.maximum(s_ * r0[..., 0], s_ * r1[..., 0])
    rel[..., 0] = s_ * np.minimum(s_ * rel[..., 0], out_max)
    rel[..., 1] += vert
    return hip + quat_rotate(q, rel)


def _outside_body(lf: _Frames, target: np.ndarray, sw: np.ndarray) -> np.ndarray:
    """Swinging feet stay outside the body, whatever the body's turn."""
    rel = quat_rotate(lf.q_inv, target - lf.hip)
    out = rel[..., 0] * lf.lay.side[None, :]
    rel[..., 0] = np.where(sw, np.maximum(out, lf.out_min[None, :]), out) * lf.lay.side[None, :]
    return lf.hip + quat_rotate(lf.q, rel)


def _above_surface(rays, lf: _Frames, cfg: RigConfig, target, sw, vert, inside, clear):
    """Swinging feet above the surface below them and on their hip's side of a wall (one batch
    of rays each)."""
    lg, hip, up = lf.lg, lf.hip, lf.up
    sp = target[sw]
    probe = cfg.body.clearance + 2.0 * lg.lift
    hh = rays.cast_down(sp, probe, max_distance=2.0 * probe)
    ground = np.full(sw.shape, -np.inf)
    ground[sw] = np.where(hh.hit, hh.points[:, 1], -np.inf)
    # a foot that crosses a step's edge between two frames is above the higher side in both
    # (else the straight move between them cuts through the riser or the nosing, and the foot
    # jumps a riser's height in one frame); the liftoff and touchdown frames stay on their holds
    pad = np.full((1,) + sw.shape[1:], -np.inf)
    nb = np.maximum(np.concatenate([ground[1:], pad]), np.concatenate([pad, ground[:-1]]))
    ground = np.where(inside, np.maximum(ground, nb), ground)[sw]
    hit = np.isfinite(ground)
    need = np.where(hit, ground, 0.0) + np.maximum(0.35 * vert, np.where(inside, clear, 0.0))[sw]
    y = np.where(hit, np.maximum(sp[:, 1], need), sp[:, 1])
    sp[:, 1] = y
    # a swinging foot stays on its hip's side of a wall: pulled back toward the hip where
    # the hip->foot line meets a steep face (eased in and out; re-timed below)
    hp = hip[sw]
    v = sp - hp
    dist = length(v)
    wall = rays.first_hit(hp, v + 0.02 * lf.span * up[sw], max_distance=dist)
    steep = wall.hit & (np.abs(dot(wall.normals, up[sw])) < 0.5)
    if steep.any():
        keep = np.maximum(wall.distance[steep] - 0.25 * lg.lift, 0.6 * dist[steep])
        sp[steep] = hp[steep] + v[steep] / dist[steep, None] * keep[:, None]
    target[sw] = sp
    return target


def _step_over(rays, lf: _Frames, target, sw):
    """A swinging foot never goes into a wall: where its path from the previous frame is blocked
    (or it ends inside something), it goes over, raised in lift-sized steps."""
    lg, lay = lf.lg, lf.lay
    start = target[sw].copy()
    ceiling = lf.hip[sw][:, 1] + SWING_CEILING * lay.l1
    wall_side = np.zeros(len(start), bool)     # by something too tall to step over
    for _ in range(WALL_STEPS):
        prev = np.concatenate([target[:1], target[:-1]])[sw]
        cur = target[sw]
        v = cur - prev
        dist = length(v)
        moving = dist > 1e-9
        blocked = np.zeros(len(cur), bool)
        moving &= ~wall_side
        eps = 0.1 * lg.lift * UP      # rays start just above feet resting on the surface
        if np.any(moving):
            blocked[moving] = rays.occluded(prev[moving] + eps, v[moving],
                                   max_distance=dist[moving])
        top = 3.0 * lg.lift
        hb = rays.first_hit(cur + top * UP, np.tile(-UP, (len(cur), 1)),
                            max_distance=top - 0.1 * lg.lift)
        below = hb.hit & ~wall_side
        if not (blocked.any() or below.any()):
            break
        cur[blocked] += 0.5 * lg.lift * UP
        lift_to = cur[below, 1] + top - hb.distance[below] + 0.1 * lg.lift
        cur[below, 1] = np.maximum(cur[below, 1], lift_to)
        # never above knee height over the hip: something that tall is not stepped over;
        # the foot keeps its path and is pushed off the face later (_clear_swings)
        wall_side |= cur[:, 1] > ceiling
        cur[wall_side] = start[wall_side]
        target[sw] = cur
    return target


def _retimed(rays, lf: _Frames, cfg: RigConfig, target, cidx, st: _Steps, sw):
    """Swings that turn the leg unevenly (over an obstacle, down a ledge) re-timed so the leg
    turns by equal angles each frame, then to an even pace in joint space where a leg joint
    still turns more than EVEN_JOINT in a frame; re-timed feet stay above the surface."""
    lay, lg = lf.lay, lf.lg
    target = _even_swings(target, lf.hip, lf.q, lf.q_inv, cidx, st.LOs, st.Ts, sw, EVEN_SWING)
    moved = np.zeros(sw.shape, bool)
    step = m = None
    for _ in range(2):
        # the second pass solves again only the legs the first re-timed (the others' steps
        # are the same)
        target, m, step = _even_joint_swings(target, lf.hip, lf.q, lf.q_inv, lf.fwd, lf.left,
                                             lay, lg.knee_out, cidx, st.LOs, st.Ts, sw,
                                             EVEN_JOINT, step, None if m is None else m.any(0))
        moved |= m
    if np.any(moved):
        sp = target[moved]
        probe = cfg.body.clearance + 2.0 * lg.lift
        hh = rays.cast_down(sp, probe, max_distance=2.0 * probe)
        sp[:, 1] = np.where(hh.hit, np.maximum(sp[:, 1], hh.points[:, 1]), sp[:, 1])
        target[moved] = sp
    return target


def _over_neighbours(target, sw, up, gap):
    """A swinging foot that would pass too close to its neighbour's foot goes over it."""
    for _ in range(6):
        d = length(target[:, 2:] - target[:, :-2])
        conf = (d < gap) & (sw[:, 2:] | sw[:, :-2])
        if not conf.any():
            break
        f, k = np.nonzero(conf)
        leg = np.where(sw[f, k + 2], k + 2, k)           # the rear one when both swing
        np.add.at(target, (f, leg), up[f, leg] * (1.2 * (gap - d[f, k]))[:, None])
    return target


def _swing_targets(rays, lf: _Frames, cfg: RigConfig, st: _Steps, cidx, contact, p0, p1, u):
    """(F, L, 3) where each foot is asked to be: on its hold while planted, on a lifted,
    obstacle-aware arc while it swings."""
    lg, lay = lf.lg, lf.lay
    sw = ~contact
    step_len = length(p1 - p0)
    lift = lg.lift * np.minimum(1.0, step_len / lg.stride_min)
    arch = np.sin(np.pi * u) ** 2                   # lifts and lands softly
    # every frame inside a swing keeps the foot at least SWING_CLEAR x the rig's lift off the
    # ground: a foot that skims the surface while it moves reads as dragging
    clear = SWING_CLEAR * lg.lift
    inside = sw & (u > 0.0) & (u < 1.0)
    vert = np.where(inside, np.maximum(lift * arch, clear), lift * arch)
    target = np.where(sw[..., None], _swing_arcs(lf, st, cidx, p0, p1, u, vert), p0)
    target = _outside_body(lf, target, sw)
    if np.any(sw):
        target = _above_surface(rays, lf, cfg, target, sw, vert, inside, clear)
        target = _step_over(rays, lf, target, sw)
    target = _retimed(rays, lf, cfg, target, cidx, st, sw)
    # the swing is raised where what lies under the leg (a stair's nosing, a stone) needs it,
    # as one smooth arch per swing rather than frame-by-frame bumps
    extra = _obstacle_lift(rays, lf.hip, target, lf.up, u, inside, cidx, np.zeros(sw.shape),
                           clear, SWING_CEILING * lay.l1 + lay.l2)
    target = target + extra[..., None] * lf.up
    # every swinging foot clear of the nearest surface, walls included (also the frames the
    # re-timing above moved off the old hold, liftoff frames included)
    eps = 1e-6 * lg.lift
    moving = sw & (length(target - p0) > eps) & (length(target - p1) > eps)
    target = _clear_swings(rays, target, inside | moving, clear, 0.25 * (lay.l1 + lay.l2))
    target = _over_neighbours(target, sw, lf.up, NEIGHBOUR_GAP * cfg.body.spacing)
    # a swinging foot whose leg would still reach through the environment (past a wall's
    # corner) is drawn in toward its hip, eased in and out
    target = _pull_in_swings(rays, lf.hip, target, sw, lf.fwd, lf.left, lay, lg.knee_out,
                             BONE_TOL * cfg.body.length)
    # a swinging foot never comes close to its hip: there the leg's plane would swing round
    # with every millimetre the foot moves (a softly clamped minimum reach)
    rel = target - lf.hip
    d = length(rel)
    full = lay.l1 + lay.l2
    d_new = np.where(sw, soft_clamp(d, MIN_REACH * full, full), d)
    return lf.hip + rel * (d_new / np.maximum(d, 1e-12))[..., None]


def walking_legs(bf: BodyFrames, arc: np.ndarray, times: np.ndarray, rays, cfg: RigConfig,
                 judged: slice = slice(None)):
    """Footholds, swings and IK for every walking leg and frame. Returns a dict of arrays.
    judged: the frames that are kept (the rest are margins): only their faults count when
    swings are redone in joint space (all frames by default)."""
    lf = _leg_frames(bf, cfg)
    lay, lg, body, hip = lf.lay, lf.lg, cfg.body, lf.hip
    F, L = lf.shape
    anchor = _anchors(rays, lf, bf)
    clock = gait_clock(arc, times, cfg.locomotion.max_speed, lg.stride_min, lg.stride_max)
    st = _step_events(rays, lf, clock, anchor, times)
    holds = _footholds(rays, lf, cfg, anchor, st)
    holds, cidx, contact = _stances(rays, lf, cfg, st, holds, anchor, times)
    tol = BONE_TOL * body.length
    kept = np.zeros(F, bool)
    kept[judged] = True
    for attempt in range(STUCK_ROUNDS):
        p0, p1, u, td_flag = _swing_progress(lf, st, holds, cidx, contact, clock, times)
        target = _swing_targets(rays, lf, cfg, st, cidx, contact, p0, p1, u)
        # -- IK, all frames x legs
        pole = leg_pole(lay, hip, target, lf.fwd, lf.left, lg.knee_out)
        sol = two_bone_ik(hip, target, pole, lay.l1, lay.l2)
        mid, hinge = _clear_knees(rays, hip, sol.mid, sol.end, sol.hinge, lay.l1, lay.l2, tol)
        q_u = bone_frames(hip, mid, hinge)
        q_t = bone_frames(mid, sol.end, hinge)
        # a planted leg whose bones no knee swivel clears (a foot at the foot of a step, the
        # knee over it), or whose bones as solved turn too fast in a frame, lifts before that
        # frame, and the stances are planned again
        if attempt == STUCK_ROUNDS - 1 or not _lift_stuck(rays, lf, st, cidx, contact, mid,
                                                          sol.end, q_u, q_t, tol):
            break
        holds, cidx, contact = _stances(rays, lf, cfg, st, holds, anchor, times)
    # swings that still break a limit (a joint turning too fast, a bone through something, a
    # moving foot on or in a surface) are redone in joint space (swing.py)
    lim = Limits(contact=0.8 * (SWING_CLEAR * lg.lift), slide=SLIDE * body.length,
                 tol=tol, turn=np.radians(SWING_TURN), gap=SWING_GAP * body.spacing,
                 hard_turn=np.radians(HARD_TURN), hard_gap=HARD_GAP * body.spacing,
                 deep=DEEP * body.length, judged=kept)
    q_u, q_t, mid, feet, swing = joint_space_swings(rays, hip, lf.q, q_u, q_t, mid, sol.end,
                                                    ~contact, lay.side, lay.l1, lay.l2, lim)
    contact = ~swing
    names = tuple(n for pair in zip(lay.upper_names, lay.tip_names) for n in pair)
    positions = np.stack([hip, mid], axis=2).reshape(F, 2 * L, 3)
    rotations = np.stack([q_u, q_t], axis=2).reshape(F, 2 * L, 4)
    return dict(names=names, positions=positions, rotations=rotations, feet=feet,
                targets=target, contacts=contact, touchdown=td_flag, lag=lay.lag,
                touchdowns=st.Ts, liftoffs=st.LOs, holds=holds)


def _lift_stuck(rays, lf: _Frames, st: _Steps, cidx, contact, mid, end, q_u, q_t,
                tol) -> bool:
    """Planted frames whose leg bones (knees mid, feet end, rotations q_u, q_t) pass through
    something (_bones_hit), or turn more than SWING_TURN since the frame before in the same
    stance (_solved_stance_turns), end their stance: the foot lifts off the frame before the
    first of them (st.LOs, never before its touchdown). True when a stance got shorter."""
    lay, hip = lf.lay, lf.hip
    f, l = np.nonzero(contact)
    bad = _bones_hit(rays, hip[f, l], mid[f, l], end[f, l], lay.l1, lay.l2, tol)
    bad |= _solved_stance_turns(lf.q, q_u, q_t, cidx, contact)[f, l] > SWING_TURN
    if not bad.any():
        return False
    f, l = f[bad], l[bad]
    c = cidx[f, l]
    before = st.LOs.copy()
    np.minimum.at(st.LOs, (c, l), f - 1)
    Ts = st.Ts[:len(before)]
    st.LOs[:] = np.maximum(st.LOs, np.minimum(Ts, before))
    return bool(np.any(st.LOs < before))


def _solved_stance_turns(seg_q, q_u, q_t, cidx, contact) -> np.ndarray:
    """(F, L) degrees the bones of the legs as solved (rotations q_u, q_t; knees swivelled:
    _clear_knees) turn since the frame before, where both frames are planted on the same hold
    (0 elsewhere): the largest of each bone's turn in the world, the upper bone's in its
    segment's space (seg_q) and the tip's in the upper bone's. The stance check
    (_stance_turns) measures the plain IK before the knees swivel; a swivel easing in while
    the body jumps adds the two."""
    rel_u = quat_mul(quat_conj(seg_q), q_u)
    rel_t = quat_mul(quat_conj(q_u), q_t)
    step = np.max([quat_angle(q[1:], q[:-1]) for q in (q_u, q_t, rel_u, rel_t)], axis=0)
    out = np.zeros(contact.shape)
    same = contact[1:] & contact[:-1] & (cidx[1:] == cidx[:-1])
    out[1:] = np.where(same, np.degrees(step), 0.0)
    return out


def _obstacle_lift(rays, hip: np.ndarray, base: np.ndarray, up: np.ndarray, u: np.ndarray,
                   inside: np.ndarray, cidx: np.ndarray, vert: np.ndarray, clear: float,
                   cap: float) -> np.ndarray:
    """(F, L) swing lifts raised so the leg clears what lies under its path.

    hip, base : (F, L, 3) hips and the swing path; up : (F, L, 3) segment up
    axes; u : swing progress; inside : frames strictly inside a swing; cidx : (F, L) each
    frame's step cycle. The surface above points along the hip -> foot line (rays down the up
    axis from `cap` above) sets a need: the foot's raise that lifts the line over it (the
    bones lie above that line: the knee bends up), the foot itself by `clear`. Each swing's
    arch sin(pi u) is scaled to meet the largest need of its frames (at most `cap`), so the
    foot rises early before a step's nosing and lands softly after it.
    """
    f, l = np.nonzero(inside)
    if len(f) == 0:
        return vert
    F, L = u.shape
    top = cap + clear
    need = np.zeros(len(f))
    for t in LINE_SAMPLES:
        p = hip[f, l] + t * (base[f, l] - hip[f, l])
        h = rays.first_hit(p + up[f, l] * top, -up[f, l], max_distance=top + clear)
        need = np.maximum(need, np.where(h.hit, (top - h.distance + t * clear) / t, 0.0))
    arch = np.maximum(np.sin(np.pi * u[f, l]), 0.15)
    key = cidx[f, l] * L + l
    peak = np.zeros(int(key.max()) + 1)
    np.maximum.at(peak, key, need / arch)
    out = vert.copy()
    out[f, l] = np.maximum(vert[f, l], np.minimum(peak[key], cap) * np.sin(np.pi * u[f, l]))
    return out


def _clear_swings(rays, target: np.ndarray, inside: np.ndarray, clear: float, reach: float,
                  rounds: int = 3) -> np.ndarray:
    """Feet of frames strictly inside a swing (`inside`, (F, L) bool) moved off the nearest
    surface along its normal until they are at least `clear` metres from every surface; a foot
    inside a solid (RayCaster.inside) with a face within `reach` comes out through that face."""
    target = target.copy()
    f, l = np.nonzero(inside)
    for _ in range(rounds):
        p = target[f, l]
        d, c, tri = rays.closest(p, max(reach, clear))
        found = np.isfinite(d)
        f, l, p, d, c, tri = f[found], l[found], p[found], d[found], c[found], tri[found]
        buried = rays.inside(p)
        fix = buried | (d < clear * (1.0 - 1e-6))
        if not fix.any():
            break
        # only the feet moved can need it again (the others' answers stay the same)
        f, l, p, c, tri, buried = f[fix], l[fix], p[fix], c[fix], tri[fix], buried[fix]
        n = rays.face_normals[tri]
        # out the face's front, unless the foot is in the open behind it (under a one-sided
        # leaf): then away from it. A foot on the face itself (a hold, to rounding) reads as
        # buried under one-sided ground, and goes out the front
        behind = dot(p - c, n) < -1e-3 * clear
        n *= np.where(behind & ~buried, -1.0, 1.0)[:, None]
        # nearest to an edge or a corner (a stair's nosing): away from that point, not along
        # one face's normal (the riser's would push the foot down past the nosing)
        away = p - c
        dist = length(away)
        off_face = ~buried & (dist > 1e-3 * clear) & (dot(away, n) < (1.0 - 1e-6) * dist)
        n[off_face] = away[off_face] / dist[off_face, None]
        target[f, l] = c + n * clear
    return target


def _even_swings(target, hip, q, q_inv, cidx, LOs, Ts, sw, limit):
    """Re-time swings whose largest per-frame turn of the hip->foot direction (segment frame)
    exceeds `limit` [rad]: the same path, walked at an even angular pace between liftoff and
    touchdown (both ends unchanged)."""
    F, L, _ = target.shape
    rel = quat_rotate(q_inv, target - hip)
    d = normalize(rel)
    step = np.arccos(np.clip(dot(d[1:], d[:-1]), -1.0, 1.0))      # (F-1, L)
    big = (step > limit) & (sw[1:] | sw[:-1])
    if not big.any():
        return target
    f, l = np.nonzero(big)
    c = cidx[f + 1, l]
    c = np.where(sw[f + 1, l], c, cidx[f, l])                  # the swing this step belongs to
    spans = []
    for cc, ll in set(zip(c.tolist(), l.tolist())):
        a, b = int(LOs[cc, ll]), int(min(Ts[cc + 1, ll], F - 1))
        if b - a >= 2:
            spans.append((a, b, ll))
    pieces = [(a, b, ll, new) for (a, b, ll), (total, new) in zip(spans,
                                                                 _even_paced(rel, step, spans))
              if not total <= 0]
    return _placed_pieces(target.copy(), hip, q, pieces)


def _even_paced(rel, step, spans) -> list:
    """[(cum, new)] for each span (a, b, leg) of `spans`: the path rel[a..b, leg] (F, L, 3)
    walked at an even pace of its per-frame steps step[a..b-1, leg] (F-1, L): new (b-a+1, 3),
    and cum, the steps' sum. All spans in one batch where every step is finite (each span's
    running sum along its own row, the same bits as one at a time: _even_piece); else one at a
    time."""
    if not spans:
        return []
    a, b, lg = (np.array(x, dtype=np.int64) for x in zip(*spans))
    m = b - a
    n = int(m.max())
    k = np.arange(n + 1)
    at = np.minimum(a[:, None] + k[None, :], len(step) - 1)
    st = step[at[:, :-1], lg[:, None]]
    if not np.isfinite(st).all():
        return [_even_piece(rel[x:y + 1, ll], step[x:y, ll]) for x, y, ll in spans]
    cum = np.zeros((len(m), n + 1))
    np.cumsum(np.where(k[None, :-1] < m[:, None], st, 0.0), axis=1, out=cum[:, 1:])
    total = cum[np.arange(len(m)), m]
    want = total[:, None] * k[None, :] / m[:, None]
    # np.searchsorted(cum, want, "right") of each row (its first m + 1 entries, nondecreasing)
    below = np.where(k[None, :] <= m[:, None], cum, np.inf)
    j = np.clip((below[:, None, :] <= want[:, :, None]).sum(-1) - 1, 0, (m - 1)[:, None])
    c0 = np.take_along_axis(cum, j, 1)
    t = np.clip((want - c0) / np.maximum(np.take_along_axis(cum, j + 1, 1) - c0, 1e-12),
                0.0, 1.0)
    s0 = rel[np.minimum(a[:, None] + j, len(rel) - 1), lg[:, None]]
    s1 = rel[np.minimum(a[:, None] + j + 1, len(rel) - 1), lg[:, None]]
    new = s0 + (s1 - s0) * t[..., None]
    return [(total[i], new[i, :m[i] + 1]) for i in range(len(m))]


def _even_piece(seg, step) -> tuple:
    """(cum, new) of _even_paced for one span: its path seg (n+1, 3), its steps (n,)."""
    cum = np.concatenate([[0.0], np.cumsum(step)])
    want = cum[-1] * np.arange(len(seg)) / (len(seg) - 1)
    j = np.clip(np.searchsorted(cum, want, side="right") - 1, 0, len(seg) - 2)
    t = np.clip((want - cum[j]) / np.maximum(cum[j + 1] - cum[j], 1e-12), 0.0, 1.0)
    return cum[-1], seg[j] + (seg[j + 1] - seg[j]) * t[:, None]


def _placed_pieces(out, hip, q, pieces):
    """`out` (F, L, 3) with frames a+1..b-1 of leg ll set to hip + q applied to new[1:-1], for
    each (a, b, ll, new (b-a+1, 3)) of `pieces` in turn (all rotated in one call)."""
    if not pieces:
        return out
    rot = quat_rotate(np.concatenate([q[a + 1:b, ll] for a, b, ll, _ in pieces]),
                      np.concatenate([new[1:-1] for *_, new in pieces]))
    at = 0
    for a, b, ll, _ in pieces:
        out[a + 1:b, ll] = hip[a + 1:b, ll] + rot[at:at + b - a - 1]
        at += b - a - 1
    return out


def _stance_turns(hip, hold, fwd, left, q_inv, lay, legs, knee_out) -> np.ndarray:
    """(n, W-1) degrees the bones of legs `legs` (n,) with their feet planted at `hold` (n, 3)
    turn between consecutive frames of a window (hip, fwd, left: (n, W, 3); q_inv (n, W, 4) the
    segments' inverse rotations), in the world and the upper bone in its segment's own space
    (a segment turning one way while the planted leg turns the other adds the two), and the
    tip bone in the upper bone's space (the change of the knee angle: a hip that comes a few
    millimetres nearer a planted foot near a straight knee folds it fast): the leg solved as
    two_bone_ik solves it with the knee toward side * cross(fwd, u) + knee_out * side * left,
    each bone's steps as _frame_steps and _joint_steps measure them (compiled to the arccos:
    leg_kernels.leg_traces; the soft clamp's exp and the arccos stay in numpy)."""
    target = np.broadcast_to(hold[:, None, :], hip.shape)
    tr, knee = leg_traces(hip, target, fwd, left, q_inv, lay.side[legs], knee_out, lay.l1,
                          lay.l2, _clamped_reach(hip, target, lay))
    fold = np.degrees(np.abs(np.diff(np.arccos(np.clip(knee, -1.0, 1.0)), axis=1)))
    return np.maximum(_step_degrees(tr).max(axis=1).T, fold)


def _clamped_reach(hip, target, lay) -> np.ndarray:
    """two_bone_ik's soft-clamped reach |target - hip| (...) of bones lay.l1, lay.l2."""
    return reach_clamp(length(target - hip), float(lay.l1), float(lay.l2))


def _step_degrees(tr: np.ndarray) -> np.ndarray:
    """_frame_steps' degrees from its traces."""
    return np.degrees(np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0)))


def _frame_steps(a: np.ndarray, b: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    """(F-1, L) degrees between consecutive frames of bones a -> b with hinge (local +X)."""
    y = normalize(b - a)
    x = normalize(hinge - dot(hinge, y)[..., None] * y)
    z = cross(x, y)
    tr = sum(dot(v[1:], v[:-1]) for v in (x, y, z))
    return _step_degrees(tr)


def _joint_steps(hip, target, q_inv, fwd, left, lay, knee_out, legs=slice(None)):
    """(F-1, L) degrees: the largest per-frame rotation of a leg's upper bone (relative to its
    segment, and in the world) or tip bone (relative to the upper bone, and in the world) that
    the IK gives for these targets (with rig.limbs.leg_pole's knee pole; compiled to the
    arccos: leg_kernels.leg_traces, legs in rows). The tip turns about the same hinge as the
    upper bone: its step relative to the upper bone is the change of the knee angle. legs:
    only these legs' columns (each leg's the same bits as among all)."""
    hip, target, q_inv, fwd, left = (a[:, legs] for a in (hip, target, q_inv, fwd, left))
    sw = (lambda a: np.swapaxes(a, 0, 1))
    tr, knee = leg_traces(sw(hip), sw(target), sw(fwd), sw(left), sw(q_inv), lay.side[legs],
                          knee_out, lay.l1, lay.l2, sw(_clamped_reach(hip, target, lay)))
    steps = _step_degrees(tr)                               # (F-1, bone, L)
    knee = np.arccos(np.clip(knee.T, -1.0, 1.0))
    world = np.maximum(steps[:, 0], steps[:, 1])
    return np.maximum(np.maximum(steps[:, 2], np.degrees(np.abs(np.diff(knee, axis=0)))), world)


def _even_joint_swings(target, hip, q, q_inv, fwd, left, lay, knee_out, cidx, LOs, Ts, sw,
                       limit_deg, step=None, changed=None):
    """Re-time swings in which a leg joint turns by more than `limit_deg` in one frame (from the
    last planted frame to touchdown): the same path (segment frame), walked so that the joint
    rotation per frame is even. Both ends are unchanged. step, changed: a previous call's
    steps (F-1, L) and the legs (L,) bool whose targets it changed since (only those are
    solved again; each leg's steps are its own). Returns (targets, (F, L) bool: the frames
    re-timed, the steps (F-1, L) of the targets given)."""
    F, L, _ = target.shape
    moved = np.zeros((F, L), bool)
    if step is None:
        step = _joint_steps(hip, target, q_inv, fwd, left, lay, knee_out)   # (F-1, L)
    elif changed.any():
        legs = np.nonzero(changed)[0]
        step = step.copy()
        step[:, legs] = _joint_steps(hip, target, q_inv, fwd, left, lay, knee_out, legs)
    big = (step > limit_deg) & (sw[1:] | sw[:-1])
    if not big.any():
        return target, moved, step
    rel = quat_rotate(q_inv, target - hip)
    f, l = np.nonzero(big)
    c = np.where(sw[f + 1, l], cidx[f + 1, l], cidx[f, l])     # the swing this step belongs to
    spans = []
    for cc, ll in set(zip(c.tolist(), l.tolist())):
        a, b = max(int(LOs[cc, ll]) - 1, 0), int(min(Ts[cc + 1, ll], F - 1))
        if b - a >= 2:
            spans.append((a, b, ll))
            moved[a + 1:b, ll] = True
    pieces = [(a, b, ll, new) for (a, b, ll), (_, new) in zip(spans,
                                                             _even_paced(rel, step + 1e-3, spans))]
    return _placed_pieces(target.copy(), hip, q, pieces), moved, step


def _pull_in_swings(rays, hip, target, sw, fwd, left, lay, knee_out, tol):
    """Swinging feet drawn toward their hips (by the smallest of PULL_IN that works) in frames
    where the leg (IK bones, or the straight hip->foot line) would pass through the
    environment; the pull changes by at most PULL_RATE per frame and is zero on planted
    frames (so at most PULL_RATE one frame after liftoff or before touchdown)."""
    F, L, _ = target.shape
    f, l = np.nonzero(sw)
    if len(f) == 0:
        return target
    hp, tg = hip[f, l], target[f, l]
    todo = _leg_blocked(rays, lay, l, hp, tg, fwd[f, l], left[f, l], knee_out, tol)
    if not todo.any():
        return target
    need = np.zeros(len(f))
    for k in PULL_IN:
        i = np.nonzero(todo)[0]
        if len(i) == 0:
            break
        ok = ~_leg_blocked(rays, lay, l[i], hp[i], hp[i] + k * (tg[i] - hp[i]), fwd[f[i], l[i]],
                           left[f[i], l[i]], knee_out, tol)
        need[i[ok]] = 1.0 - k
        todo[i[ok]] = False
    if not need.any():
        return target
    pull = np.zeros((F, L))
    pull[f, l] = need
    pull = _ramp(pull, PULL_RATE)
    # ... and grows from nothing at liftoff and back to nothing at touchdown
    run = np.zeros((F, L))
    for i in range(1, F):
        run[i] = np.where(sw[i], run[i - 1] + 1.0, 0.0)
    back = np.zeros((F, L))
    for i in range(F - 2, -1, -1):
        back[i] = np.where(sw[i], back[i + 1] + 1.0, 0.0)
    pull = np.minimum(pull, PULL_RATE * np.minimum(run, back))
    return hip + (1.0 - pull)[..., None] * (target - hip)


def _leg_blocked(rays, lay, legs, hip, target, fwd, left, knee_out, tol):
    """(n,) bool for flat batches of (frame, leg) samples of legs `legs`: the straight
    hip->foot line or either IK bone (knee pole as in rig.limbs.leg_pole) passes through the
    environment."""
    u = normalize(target - hip)
    s = lay.side[legs][:, None]
    pole = s * cross(fwd, u) + knee_out * s * left
    sol = two_bone_ik(hip, target, pole, lay.l1, lay.l2)
    v = sol.end - hip
    dist = length(v)
    line = rays.occluded(hip, v, max_distance=np.maximum(dist - tol, 0.0))
    return line | _bones_hit(rays, hip, sol.mid, sol.end, lay.l1, lay.l2, tol)


def _bones_hit(rays, hip, mid, end, l1, l2, tol):
    """(n,) bool: either bone of each leg passes through the environment (the last `tol` of the
    tip bone is not tested, so a foot resting on the surface does not count), or within
    GRAZE x `tol` of a surface below or above it (the files' keyframe reduction and rotation
    rounding move a joint by a little: a bone lying flat a hair over the floor would go into
    it, and one passing a hair under an edge near its foot would clip the edge)."""
    low = GRAZE * tol * UP                  # each bone cast as it is, that much lower and higher
    a = rays.occluded(np.concatenate([hip, hip - low, hip + low]), np.tile(mid - hip, (3, 1)),
                      max_distance=l1 - tol)
    b = rays.occluded(np.concatenate([mid, mid - low, mid + low]), np.tile(end - mid, (3, 1)),
                      max_distance=l2 - tol)
    return (a | b).reshape(3, -1).any(axis=0)


def _clear_knees(rays, hip, mid, end, hinge, l1, l2, tol):
    """Swivel knees about the hip->foot axis where a leg bone would pass through the
    environment (the foot stays where it is). Each run of consecutive offending frames of a leg
    gets one swivel angle: the smallest candidate that clears the most of its frames; the angle
    eases in and out over neighbouring frames so the knee glides rather than jumps. An eased
    frame whose partial swivel puts a bone through something joins its run (with the frames
    between), whose angle is then chosen again (up to KNEE_EASE_ROUNDS times). The frames of a
    run that its angle leaves through something get an angle of their own (_split_runs).

    hip, mid, end, hinge : (F, L, 3). Returns (mid, hinge) adjusted.
    """
    F, L, _ = hip.shape
    hit = _bones_hit(rays, hip.reshape(-1, 3), mid.reshape(-1, 3), end.reshape(-1, 3),
                     l1, l2, tol).reshape(F, L)
    if not hit.any():
        return mid, hinge
    axis = normalize(end - hip)
    # runs of offending frames per leg (bridging gaps of up to 4 frames)
    near = maximum_filter1d(hit.astype(np.uint8), 5, axis=0, mode="constant").astype(bool)
    for _ in range(KNEE_EASE_ROUNDS):
        # the swivel eases in and out at most SWIVEL_RATE per frame (full swivel on the runs)
        angle = _run_swivels(rays, hip, mid, end, axis, hit, near, l1, l2, tol)
        angle = _split_runs(rays, hip, mid, end, axis, angle, near, l1, l2, tol)
        fi, li = np.nonzero(~near & (angle != 0.0))
        bad = _swivel_hits(rays, hip, mid, end, axis, angle, fi, li, l1, l2, tol)
        if not bad.any():
            break
        near = _joined(near, fi[bad], li[bad])
    new_mid = _swivel(mid, hip, axis, angle)
    new_hinge = _swivel(hinge, np.zeros_like(hinge), axis, angle)
    return new_mid, new_hinge


def _joined(near: np.ndarray, fi: np.ndarray, li: np.ndarray) -> np.ndarray:
    """`near` (F, L) bool with frames fi of legs li joined to their leg's nearest run of True
    frames (the frames between them set too)."""
    F = len(near)
    idx = np.arange(F)[:, None]
    before = np.maximum.accumulate(np.where(near, idx, -1), axis=0)[fi, li]
    after = np.minimum.accumulate(np.where(near, idx, F)[::-1], axis=0)[::-1][fi, li]
    to = np.where((before < 0) | ((after < F) & (after - fi < fi - before)), after, before)
    out = near.copy()
    for f, l, t in zip(fi, li, to):
        if 0 <= t < F:
            out[min(f, t):max(f, t) + 1, l] = True
        else:
            out[f, l] = True
    return out


def _run_swivels(rays, hip, mid, end, axis, hit, near, l1, l2, tol) -> np.ndarray:
    """(F, L) the swivel of every frame of the runs of `near` (F, L) bool frames of each leg,
    0 elsewhere: per run, the first of KNEE_SWIVELS with the fewest bone hits over its frames
    and the frames its easing in and out swivels part way (no swivel unless one has fewer than
    `hit` (F, L), the hits unswivelled): a knee that clears at 0 and at 20 deg can graze at
    the 4 and 12 deg between, and another side or angle may ease in clean."""
    F, L = near.shape
    run_id = _run_ids(near)
    n_runs = int(run_id.max()) + 1
    f, l = np.nonzero(near)
    r = run_id[f, l]
    ends = np.stack([np.full(n_runs, F), np.zeros(n_runs, int)])   # each run's first, last
    np.minimum.at(ends[0], r, f)
    np.maximum.at(ends[1], r, f)
    leg = np.zeros(n_runs, int)
    leg[r] = l
    angle_run = np.zeros(n_runs)
    best = np.bincount(r, weights=hit[f, l], minlength=n_runs)   # fewest hits per run so far
    for a in KNEE_SWIVELS:
        m = _swivel(mid[f, l], hip[f, l], axis[f, l], a)
        bad = _bones_hit(rays, hip[f, l], m, end[f, l], l1, l2, tol)
        cnt = np.bincount(r, weights=bad, minlength=n_runs)
        cnt += _ramp_hits(rays, hip, mid, end, axis, a, ends, leg, near, l1, l2, tol)
        better = cnt < best
        best[better] = cnt[better]
        angle_run[better] = a
        if not best.any():
            break
    angle = np.zeros((F, L))
    angle[f, l] = angle_run[r]
    return angle


def _ramp_hits(rays, hip, mid, end, axis, a, ends, leg, near, l1, l2, tol) -> np.ndarray:
    """(n_runs,) the frames beside each run (first and last frames `ends` (2, n_runs) of leg
    `leg`) that a swivel `a` eased in and out at SWIVEL_RATE per frame (_eased) swivels part
    way and puts a bone through something (frames of other runs left out)."""
    F = len(near)
    d = np.arange(1, int(np.ceil(abs(a) / SWIVEL_RATE)))
    if len(d) == 0:
        return np.zeros(ends.shape[1])
    fr = np.concatenate([ends[0][:, None] - d, ends[1][:, None] + d], axis=1)     # (n_runs, 2k)
    part = np.sign(a) * (abs(a) - SWIVEL_RATE * np.concatenate([d, d]))
    ri, ci = np.nonzero((fr >= 0) & (fr < F))
    fi, li = fr[ri, ci], leg[ri]
    keep = ~near[fi, li]
    ri, ci, fi, li = ri[keep], ci[keep], fi[keep], li[keep]
    m = _swivel(mid[fi, li], hip[fi, li], axis[fi, li], part[ci])
    bad = _bones_hit(rays, hip[fi, li], m, end[fi, li], l1, l2, tol)
    return np.bincount(ri, weights=bad, minlength=ends.shape[1])


def _run_ids(mask: np.ndarray) -> np.ndarray:
    """(F, L) int: the number of each run of consecutive True frames of each leg of `mask`
    (F, L) bool, counted leg by leg (valid where mask, -1 before a leg's first run)."""
    F, L = mask.shape
    lt = mask.T                                           # (L, F)
    start = lt & ~np.concatenate([np.zeros((L, 1), bool), lt[:, :-1]], 1)
    return np.cumsum(start.ravel()).reshape(L, F).T - 1


def _split_runs(rays, hip, mid, end, axis, angle, near, l1, l2, tol) -> np.ndarray:
    """(F, L) the eased swivels: `angle` (one per run) with the frames of a run that it leaves
    through something given a swivel of their own (per stretch of such frames), where one does
    better there: a knee that must lean further beside a step's corner than over the step in
    the same stance. The easing blends the two; each stretch of swivelled frames keeps its
    runs' single swivels unless the blend puts fewer of its frames through something."""
    fi, li = np.nonzero(near)
    still = np.zeros_like(near)
    still[fi, li] = _swivel_hits(rays, hip, mid, end, axis, angle, fi, li, l1, l2, tol)
    if not still.any():
        return _eased(angle)
    again = _run_swivels(rays, hip, mid, end, axis, still, still, l1, l2, tol)
    whole, split = _eased(angle), _eased(np.where(again != 0.0, again, angle))
    # eased, a split can put neighbouring frames through something: per stretch of swivelled
    # frames, the one with fewer hits
    busy = (whole != 0.0) | (split != 0.0)
    run = _run_ids(busy)
    fi, li = np.nonzero(busy)
    count = []
    for a in (whole, split):
        bad = _swivel_hits(rays, hip, mid, end, axis, a, fi, li, l1, l2, tol)
        count.append(np.bincount(run[fi, li], weights=bad, minlength=int(run.max()) + 1))
    better = np.zeros(busy.shape, bool)
    better[fi, li] = (count[1] < count[0])[run[fi, li]]
    return np.where(better, split, whole)


def _swivel_hits(rays, hip, mid, end, axis, angle, fi, li, l1, l2, tol) -> np.ndarray:
    """(n,) bool: frames fi of legs li put a bone through something with their knee swivelled
    by angle[fi, li]."""
    m = _swivel(mid[fi, li], hip[fi, li], axis[fi, li], angle[fi, li])
    return _bones_hit(rays, hip[fi, li], m, end[fi, li], l1, l2, tol)


def _eased(angle: np.ndarray) -> np.ndarray:
    """(F, L) the knees' swivel angles eased in and out at most SWIVEL_RATE per frame."""
    return (_ramp(np.maximum(angle, 0.0), SWIVEL_RATE)
            - _ramp(np.maximum(-angle, 0.0), SWIVEL_RATE))


def _ramp(a: np.ndarray, rate: float) -> np.ndarray:
    """The smallest function >= a (a >= 0) that changes by at most `rate` per frame along
    axis 0: the cone dilation max_j a[j] - rate * |i - j| (offsets beyond max(a) / rate add
    nothing)."""
    out = np.array(a, dtype=float, copy=True)
    if out.size == 0 or out.max() <= 0.0:
        return out
    for d in range(1, min(int(np.ceil(out.max() / rate)), len(out) - 1) + 1):
        np.maximum(out[d:], a[:-d] - rate * d, out=out[d:])
        np.maximum(out[:-d], a[d:] - rate * d, out=out[:-d])
    return out


def _swivel(p, origin, axis, angle):
    """Rotate points p about the line (origin, unit axis) by angle [rad] (Rodrigues)."""
    v = p - origin
    c = np.cos(angle)[..., None] if np.ndim(angle) else np.cos(angle)
    s_ = np.sin(angle)[..., None] if np.ndim(angle) else np.sin(angle)
    return origin + v * c + cross(axis, v) * s_ + axis * dot(axis, v)[..., None] * (1 - c)


def _spread_neighbours(holds: np.ndarray, Ts: np.ndarray, cidx: np.ndarray, contact: np.ndarray,
                       gap: float, rays, up: np.ndarray, probe: float,
                       level: tuple | None = None, iterations: int = 32) -> np.ndarray:
    """Legs that know where their neighbours are: when two planted feet of neighbouring legs on
    one side come closer than `gap`, the one that landed later steps away from the other (its
    foothold moves along the line between them and is dropped back onto the surface); where
    that would take it off the surface (over a stair's nosing), the other one steps away.

    holds : (C+1, L, 3) footholds; Ts : (C+1, L) their touchdown frames; cidx : (F, L) hold of
    each frame; contact : (F, L) planted; level : (edge, inward (F, L, 3)) or None: a hold on
    level ground is moved off it (is_level, as project_footholds prefers) only when no move
    keeps it level. Legs are ordered L_01, R_01, L_02, ... so leg l's rear neighbour on the
    same side is l + 2. Returns adjusted holds.
    """
    holds = holds.copy()
    F, L = cidx.shape
    # the frames and front legs where both neighbours are planted (fixed over the passes: only
    # the holds move), in np.nonzero's order; only their feet are compared
    f_all, k_all = np.nonzero(contact[:, 2:] & contact[:, :-2])
    cf_all, cr_all = cidx[f_all, k_all], cidx[f_all, k_all + 2]
    d_all = holds[cr_all, k_all + 2] - holds[cf_all, k_all]               # rear - front
    dist_all = length(d_all)                              # np.linalg.norm's bits
    for it in range(iterations):
        conf = np.nonzero(dist_all < gap)[0]
        if len(conf) == 0:
            break
        f, k, d, dist = f_all[conf], k_all[conf], d_all[conf], dist_all[conf]
        front, rear = k, k + 2
        cf, cr = cf_all[conf], cr_all[conf]
        later_rear = Ts[cr, rear] >= Ts[cf, front]
        unit = d / np.maximum(dist, 1e-12)[:, None]
        need = gap - dist
        vec = np.where(later_rear[:, None], unit, -unit) * (need * 1.3 + 0.02 * gap)[:, None]
        late = (np.where(later_rear, cr, cf), np.where(later_rear, rear, front))
        early = (np.where(later_rear, cf, cr), np.where(later_rear, front, rear))
        # first along the line between them: the later foot, else the other one; then (or,
        # in the second half of the passes, first: a push along a crowded side only hands the
        # crowding on) the later foot steps aside, turned about its up axis; all of them
        # keeping level holds level first, then (feet apart matter more) any way
        along = [(late, 0.0), (early, np.pi)]
        aside = [(late, a) for a in SIDESTEP_ANGLES]
        moves = along + aside if it < iterations // 2 else aside + along
        keeps = (level, None) if level is not None else (None,)
        moved = np.zeros(len(f), bool)
        before = holds.copy()
        for keep, ((h_all, l_all), angle) in ((k, m) for k in keeps for m in moves):
            left = ~moved
            if not left.any():
                break
            h, leg = h_all[left], l_all[left]
            u = up[np.minimum(Ts[h, leg], F - 1), leg]
            moved[left] = _push(holds, h, leg, _turned(vec[left], u, angle), need[left], Ts,
                                rays, up, probe, keep)
        # only the pairs of the holds this pass moved (to the bit) change
        changed = np.any(holds.view(np.uint64) != before.view(np.uint64), axis=-1)
        redo = np.nonzero(changed[cf_all, k_all] | changed[cr_all, k_all + 2])[0]
        d_all[redo] = holds[cr_all[redo], k_all[redo] + 2] - holds[cf_all[redo], k_all[redo]]
        dist_all[redo] = length(d_all[redo])
    return holds


#: [rad] directions, from the line between two crowded feet, in which the later one tries to
#: step aside when neither can step along that line
SIDESTEP_ANGLES = np.radians([90.0, -90.0, 45.0, -45.0, 135.0, -135.0])


def _turned(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """(n, 3) vectors v turned by `angle` about the unit axes (n, 3) (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    along = dot(v, axis)[..., None]
    return v * c + cross(axis, v) * s + axis * along * (1.0 - c)


def _push(holds, hold, leg, vec, need, Ts, rays, up, probe, level) -> np.ndarray:
    """Move holds[hold, leg] by vec (n, 3) (per hold the largest push) and drop them back onto
    the surface along the up axis at their touchdown; a move that would leave the surface, or
    (level = (edge, inward (F, L, 3))) take a hold off level ground (is_level: next to a step,
    or beside an overhang such as a leaf's edge a centimetre over the ground), is dropped.
    Updates `holds` in place; returns (n,) bool, the entry's hold moved."""
    F = len(up)
    order = np.argsort(need, kind="stable")
    disp = np.zeros_like(holds)
    disp[hold[order], leg[order]] = vec[order]
    moved = np.any(disp != 0, axis=-1)
    new = holds[moved] + disp[moved]
    frame = np.minimum(Ts[moved], F - 1)
    u = up[frame, np.nonzero(moved)[1]]
    ok = np.zeros(len(new), bool)
    found = new.copy()
    # along the segment's up first; where the body leans (climbing a log's side) that ray can
    # pass the edge the foot stands on, so then along the world's up
    for axis in (u, np.broadcast_to(UP, u.shape)):
        h = rays.first_hit(new + probe * axis, -axis, max_distance=2.0 * probe)
        good = (~ok & h.hit & (np.abs(dot(h.points - holds[moved], u)) < 0.5 * probe)
                & _faces_up(h.normals, u))
        # a top surface in the open, not one inside another solid (a ray that starts inside a
        # branch where it dives into the ground finds the ground inside the branch)
        kk = np.nonzero(good)[0]
        good[kk] = ~rays.inside(h.points[kk] + 0.05 * probe * u[kk])
        found[good] = h.points[good]
        ok |= good
    # a hold that is on no surface the foot can stand on (a fallback next to a log's side)
    # moves as it is, unless that puts it inside a solid
    loose = ~ok
    if loose.any():
        h = rays.first_hit(holds[moved][loose] + probe * u[loose], -u[loose],
                           max_distance=2.0 * probe)
        free = ~(h.hit & _faces_up(h.normals, u[loose])) & ~rays.inside(new[loose])
        ok[np.nonzero(loose)[0][free]] = True
    kk = np.nonzero(ok & ~loose)[0]
    if level is not None and len(kk):
        edge, inward = level
        w = inward[frame[kk], np.nonzero(moved)[1][kk]]
        was = is_level(rays, holds[moved][kk], u[kk], w, edge)
        ok[kk] = ~was | is_level(rays, found[kk], u[kk], w, edge)
    new = found
    sel = np.nonzero(moved)
    keep = ok | ~moved[sel]
    holds[sel[0][keep], sel[1][keep]] = new[keep]
    done = np.zeros(holds.shape[:2], bool)
    done[sel[0][ok], sel[1][ok]] = True
    return done[hold, leg]


def _chain_dirs(side, yaw, pitch, backward):
    """(..., 3) unit directions in the segment frame (see rig.limbs._dir), vectorized."""
    f = -1.0 if backward else 1.0
    return np.stack([side * np.sin(yaw) * np.cos(pitch), np.sin(pitch),
                     f * np.cos(yaw) * np.cos(pitch)], -1)


def whole_cycles(freq: float, period: float | None) -> float:
    """`freq` [Hz], or with a `period` [s] the nearest frequency with a whole number of cycles
    in it (none: 0 Hz), so the motion repeats exactly after `period` (looping cycles)."""
    if period is None:
        return freq
    return round(freq * period) / period


def _chain_clear(rays, q, o, side, yaw1, yaw2, pitch, bend, lengths, back) -> np.ndarray:
    """(F, k) bool: a two-bone chain from o (F, 3) in its segment's frame q (F, 4), its upper
    bone at yaw1 and pitch (F, k), its tip bone at yaw2 and pitch + bend (yaws (F, 1) or
    (F, k)), keeps both bones (and 5 % past them) clear of the environment."""
    F, k = pitch.shape
    o_k = np.broadcast_to(o[:, None], (F, k, 3))
    pose = _chain_pose(np.broadcast_to(q[:, None], (F, k, 4)), o_k, side, (yaw1, yaw2), pitch,
                       bend, lengths[0], back)
    return ~_chain_touches(rays, o_k, *pose, lengths)


def _chain_pose(q, o, s, yaws, pitch, bend, l1, back):
    """(d1, d2, knee) of a chain at pitch (...): its bones' world directions and its knee."""
    d1 = quat_rotate(q, _chain_dirs(s, yaws[0], pitch, back))
    d2 = quat_rotate(q, _chain_dirs(s, yaws[1], pitch + bend, back))
    return d1, d2, o + d1 * l1


def _chain_touches(rays, o, d1, d2, knee, lengths) -> np.ndarray:
    """(...) bool: a chain's bones from o along d1 and from its knee along d2 (..., 3) reach
    the environment within 5 % past their lengths."""
    l1, l2 = lengths
    out = (rays.occluded(o.reshape(-1, 3), d1.reshape(-1, 3), max_distance=l1 * 1.05)
           | rays.occluded(knee.reshape(-1, 3), d2.reshape(-1, 3),
                           max_distance=l2 * 1.05)).reshape(o.shape[:-1])
    if isinstance(rays, NearBodies):    # a crowd's: and other creatures' bodies
        out |= rays.touches(o, o + d1 * (l1 * 1.05)) | rays.touches(knee, knee + d2 * (l2 * 1.05))
    return out


#: shares of the warning's raise tried under an overhang, highest first
WARN_SHARES = (1.0, 0.8, 0.6, 0.4, 0.2, 0.0)
#: the warning's raise gives way to an overhang at most this share of it per frame
WARN_GIVE_RATE = 0.1
#: shares of an antenna's sweep (an ultimate leg's sway) a chain may take where the full one
#: clears only raised, widest first (negative: away from the sweep)
SWEEP_SHARES = (1.0, 0.75, 0.5, 0.25, 0.0, -0.25, -0.5)
#: [frames] the sweep gives way and comes back within this many frames round those
SWEEP_MARGIN = 12
#: a narrower sweep costs this much raise per share it gives up (a quarter of the sweep: 12 deg)
SWEEP_WIDTH_COST = 4.0 * np.radians(12.0)
#: [rad] a frame's turn of the chain's yaw beyond the full sweep's own turn that costs nothing;
#: beyond it, CHAIN_STEEP_COST a radian
SWEEP_GIVE = np.radians(2.0)


def _warning_room(rays, q, o, side, yaws, pitch, bend, lengths, rise) -> np.ndarray:
    """(F,) the share of the warning's raise (rise (F,) rad, on top of pitch (F,)) an ultimate
    leg takes: the largest of WARN_SHARES whose two bones clear the environment (resting under
    a low overhang, a full raise drives the tip into it), eased so it gives way at most
    WARN_GIVE_RATE of the raise per frame. q, o : (F, 4), (F, 3) the segment's rotation and the
    chain's base; yaws: the upper and the tip bone's yaws (F,) each; bend: the tip bone's pitch
    over the upper one's."""
    full = np.where(np.abs(rise) > 1e-12, 1.0, 0.0)
    if not full.any():
        return full
    shares = np.asarray(WARN_SHARES)
    p = pitch[:, None] + shares[None, :] * rise[:, None]                    # (F, k)
    clear = _chain_clear(rays, q, o, side, yaws[0][:, None], yaws[1][:, None], p, bend, lengths,
                         True)
    room = np.where(clear.any(1), shares[np.argmax(clear, 1)], 0.0)
    give = _ramp((full * (1.0 - room))[:, None], WARN_GIVE_RATE)[:, 0]
    return np.clip(full - give, 0.0, 1.0)


def posed_chains(bf: BodyFrames, times: np.ndarray, rays, cfg: RigConfig,
                 warning: np.ndarray | None = None, chain_period: float | None = None):
    """Ultimate legs and antennae: angle-driven two-bone chains, lifted clear of the surface.

    warning      : (F,) float 0..1 or None, Posture 1 strength: the ultimate legs rise from
                   legs.ultimate_raise toward legs.ultimate_warning_raise in proportion (eased
                   over about a quarter of a second)
    chain_period : [s] or None: every sway and grope frequency is rounded to a whole number of
                   cycles in this period (whole_cycles), so the chains repeat after it
    """
    hz = (lambda f: 2 * np.pi * whole_cycles(f, chain_period))
    lg = cfg.legs
    F = len(times)
    fps = (F - 1) / max(float(times[-1] - times[0]), 1e-9) if F > 1 else 30.0
    if warning is None:
        warn = np.zeros(F)
    else:
        warn = gaussian_filter1d(np.clip(np.asarray(warning, float), 0.0, 1.0), 0.12 * fps,
                                 mode="nearest")
    names, pos, rot = [], [], []
    # raises first, then (under a ceiling, where no raise clears: inside a hollow log) dips
    raise_steps = np.radians([0.0, 6.0, 12.0, 20.0, 30.0, 45.0, 60.0, 80.0, -8.0, -16.0, -24.0,
                              -32.0])
    for ch in chains(cfg):
        if ch.kind == "forcipule":
            continue
        q = bf.rotations[:, ch.parent]
        left, up, fwd = _axes(q)
        o = bf.positions[:, ch.parent] + quat_rotate(q, np.broadcast_to(ch.base, (F, 3)))
        s = ch.side
        t = np.asarray(times, float)
        rest1 = ch.dirs[0]
        rest2 = ch.dirs[1]
        yaw1 = np.arctan2(s * rest1[0], abs(rest1[2]))
        pit1 = np.arcsin(np.clip(rest1[1], -1, 1))
        yaw2 = np.arctan2(s * rest2[0], abs(rest2[2]))
        pit2 = np.arcsin(np.clip(rest2[1], -1, 1))
        back = ch.kind == "ultimate"
        if back:                       # a slow sway, out of step with the other side
            dyaw = np.radians(6.0) * np.sin(hz(ULTIMATE_SWAY_HZ[0]) * t + (0.0 if s > 0 else np.pi))
            dpitch = np.radians(3.0) * np.sin(hz(ULTIMATE_SWAY_HZ[1]) * t + (0.5 if s > 0 else 2.0))
        else:                          # antennae sweep side to side and dip to grope the ground
            dyaw = lg.antenna_sweep * np.sin(hz(lg.antenna_rate) * t
                                             + (0.0 if s > 0 else 0.6 * np.pi))
            grope = 0.5 + 0.5 * np.sin(hz(0.5 * lg.antenna_rate) * t + (1.0 if s > 0 else 2.5))
            dpitch = -np.radians(22.0) * grope ** 3
        base_pitch = pit1 + dpitch
        if back:                       # Posture 1: raised in proportion to the warning
            w = _warning_room(rays, q, o, s, (yaw1 + dyaw, yaw2 + dyaw), base_pitch, pit2 - pit1,
                              ch.lengths, warn * (lg.ultimate_warning_raise - pit1))
            base_pitch = base_pitch + w * warn * (lg.ultimate_warning_raise - pit1)
        # candidates: raise the chain until both bones clear the environment
        pitch = base_pitch[:, None] + raise_steps[None, :]            # (F, k)
        ok_all = _chain_clear(rays, q, o, s, yaw1 + dyaw[:, None], yaw2 + dyaw[:, None], pitch,
                              pit2 - pit1, ch.lengths, back)
        if not ok_all[:, 0].all():     # beside a post: sweep less far, not rear over it
            share = _sweep_share(rays, q, o, s, (yaw1, yaw2), dyaw, pitch, raise_steps,
                                 pit2 - pit1, ch.lengths, back, ok_all)
            if (share < 1.0).any():
                dyaw = share * dyaw
                ok_all = _chain_clear(rays, q, o, s, yaw1 + dyaw[:, None], yaw2 + dyaw[:, None],
                                      pitch, pit2 - pit1, ch.lengths, back)
        l1 = ch.lengths[0]
        # none clears: the chain as it is (raising it fully drove it into a ceiling)
        raw = raise_steps[np.where(ok_all.any(1), np.argmax(ok_all, 1), 0)]
        d1, d2, knee = _eased_chain(rays, q, o, s, (yaw1 + dyaw, yaw2 + dyaw), base_pitch,
                                    pit2 - pit1, ch.lengths, back, raise_steps, raw, ok_all)
        # the hinge is the yaw plane's normal, so it never flips however far the chain is
        # raised (a cross product with the segment's up degenerates at a vertical chain)
        yaw = yaw1 + dyaw
        hinge = quat_rotate(q, np.stack([(-1.0 if back else 1.0) * np.cos(yaw), np.zeros(F),
                                         -s * np.sin(yaw)], -1))
        r1, r2 = bone_frames(o, knee, hinge), bone_frames(knee, knee + d2, hinge)
        if not back:
            r1, r2, knee = _turn_limited_antenna(q, o, r1, r2, knee, l1)
        names += list(ch.names)
        pos += [o, knee]
        rot += [r1, r2]
    return names, np.stack(pos, 1), np.stack(rot, 1)


def _sweep_share(rays, q, o, s, rest_yaws, dyaw, pitch, steps, bend, lengths, back, ok_all):
    """(F,) the share of its sway or sweep `dyaw` (F,) a chain takes (negative: away from its
    sweep). Where the full sweep clears only raised (ok_all (F, k): which raises `steps` of
    `pitch` (F, k) clear it; an antenna sweeping into a post or a stem beside a resting head
    must then rear up or jump between raises), and SWEEP_MARGIN frames round, the cheapest
    path (trellis.cheapest_path) through SWEEP_SHARES: a frame's share costs its least raise
    that clears (CHAIN_HIT_COST where none does) and SWEEP_WIDTH_COST for each share of the
    sweep it gives up; a step between frames costs CHAIN_STEEP_COST a radian of the yaw's
    turn beyond the full sweep's own turn and SWEEP_GIVE; the frames outside take the full
    sweep. (A share eased frame by frame crossed, where the sweep turns back, shares that
    clear at no raise: a share away from the sweep clears it going one way and drives the
    chain into the post coming back.) rest_yaws: the two bones' yaws at rest."""
    least = (lambda ok: np.where(ok, np.abs(steps)[None, :], np.inf).min(1))
    F = len(dyaw)
    full = least(ok_all)
    room = np.ones(F)
    need = full > 0.0
    if not need.any():
        return room
    near = maximum_filter1d(need, 2 * SWEEP_MARGIN + 1, mode="constant")
    idx = np.nonzero(near)[0]
    shares = np.asarray(SWEEP_SHARES)
    view = frames_of(rays, idx)
    cost = [full[idx]]
    for share in shares[1:]:
        y = (share * dyaw[idx])[:, None]
        cost.append(least(_chain_clear(view, q[idx], o[idx], s, rest_yaws[0] + y,
                                       rest_yaws[1] + y, pitch[idx], bend, lengths, back)))
    cost = np.where(np.isfinite(cost), cost, CHAIN_HIT_COST).T + SWEEP_WIDTH_COST * (1.0 - shares)
    for at in np.split(np.arange(len(idx)), np.nonzero(np.diff(idx) > 1)[0] + 1):
        run = idx[at]
        room[run] = shares[_share_path(dyaw, shares, cost[at], run[0], run[-1])]
    return room


def _share_path(dyaw, shares, cost, lo, hi) -> np.ndarray:
    """(n,) indices into `shares` of frames lo..hi: the cheapest path (_sweep_share) from the
    full sweep at frame lo - 1 to the full sweep at frame hi + 1 (where they exist)."""
    F = len(dyaw)
    before, after = int(lo > 0), int(hi < F - 1)
    fr = np.arange(lo - before, hi + after + 1)
    first = np.zeros(len(shares))
    first[1:] = np.inf
    layers = [first] * before + list(cost) + [first] * after
    y = shares[None, :] * dyaw[fr, None]                                    # (m, S)

    def edge(k):
        turn = np.abs(y[k][:, None] - y[k + 1][None, :])
        own = abs(dyaw[fr[k + 1]] - dyaw[fr[k]])
        return CHAIN_STEEP_COST * np.maximum(turn - own - SWEEP_GIVE, 0.0)

    return cheapest_path(layers, edge)[0][before:len(fr) - after]


def _eased_chain(rays, q, o, s, yaws, base_pitch, bend, lengths, back, steps, raw, ok_all):
    """(d1, d2 (F, 3) the two bones' directions, knee (F, 3)) of a chain raised (or dipped)
    by `raw` (F,) rad, eased in and out (at most CHAIN_RAISE_RATE per frame), never less raised
    or dipped than what clears: a frame on the way up or down that touches something (a raise
    that clears below and above but not in between) takes the next clearing one of `steps`
    beyond (ok_all (F, k): which clear), up to CHAIN_ROUNDS times; frames that still touch
    (a raise eased down through an overhang's reach) have their raises searched afresh round
    them (_chain_path), and a frame touching even then takes its nearest clearing raise as it
    is (a step of a few degrees, not a bone in the environment)."""
    l1 = lengths[0]
    for it in range(CHAIN_ROUNDS):
        lift = _ramp(np.maximum(raw, 0.0)[:, None], CHAIN_RAISE_RATE)[:, 0]
        lift -= _ramp(np.maximum(-raw, 0.0)[:, None], CHAIN_RAISE_RATE)[:, 0]
        d1, d2, knee = _chain_pose(q, o, s, yaws, base_pitch + lift, bend, l1, back)
        bad = _chain_touches(rays, o, d1, d2, knee, lengths)
        if not bad.any() or it == CHAIN_ROUNDS - 1:
            break
        up = np.where(ok_all & (steps > lift[:, None] + 1e-9), steps, np.inf)
        down = np.where(ok_all & (steps < lift[:, None] - 1e-9), steps, -np.inf)
        nxt_up = np.where(np.isfinite(up.min(1)), up.min(1), raw)   # none: as it is
        nxt_down = np.where(np.isfinite(down.max(1)), down.max(1), raw)
        raw = np.where(bad, np.where(raw >= 0.0, np.maximum(raw, nxt_up),
                                     np.minimum(raw, nxt_down)), raw)
    if bad.any():
        lift, bad = _chain_path(rays, q, o, s, yaws, base_pitch, bend, lengths, back, steps,
                                lift, bad)
        d1, d2, knee = _chain_pose(q, o, s, yaws, base_pitch + lift, bend, l1, back)
    fix = bad & ok_all.any(1)
    if fix.any():
        near = np.argmin(np.where(ok_all[fix], np.abs(steps[None, :] - lift[fix, None]),
                                  np.inf), axis=1)
        f1, f2, fk = _chain_pose(q[fix], o[fix], s, tuple(y[fix] for y in yaws),
                                 base_pitch[fix] + steps[near], bend, l1, back)
        d1, d2, knee = d1.copy(), d2.copy(), knee.copy()
        d1[fix], d2[fix], knee[fix] = f1, f2, fk
    return d1, d2, knee


def _chain_path(rays, q, o, s, yaws, base_pitch, bend, lengths, back, steps, lift, bad):
    """(lift (F,), bad (F,)) a chain's raises `lift` (F,) rad re-chosen round each run of
    frames that touch something (`bad`): over the run and CHAIN_PATH_MARGINS[0] frames either
    side (the frames just outside keep their raises), the cheapest path through the raises on
    a CHAIN_GRID grid (_chain_trellis), and with each wider margin while that path still
    touches or steps faster than CHAIN_STEEP_RATE (a band of raises that touch, to be crossed
    where it opens). A path is taken when it has fewer such faults than the raises it
    replaces; bad: the frames that touch after it."""
    F = len(lift)
    grid = np.arange(steps.min(), steps.max() + 0.5 * CHAIN_GRID, CHAIN_GRID)
    lift, bad = lift.copy(), bad.copy()
    idx = np.nonzero(bad)[0]
    for run in np.split(idx, np.nonzero(np.diff(idx) > 2 * CHAIN_PATH_MARGINS[0])[0] + 1):
        for margin in CHAIN_PATH_MARGINS:
            lo, hi = max(run[0] - margin, 0), min(run[-1] + margin, F - 1)
            fr = np.arange(lo, hi + 1)
            chosen, hits = _chain_trellis(rays, q, o, s, yaws, base_pitch, bend, lengths, back,
                                          grid, lift, lo, hi)
            faults = hits.sum() + _steep(lift, chosen, lo, hi)
            if faults < bad[fr].sum() + _steep(lift, lift[fr], lo, hi):
                lift[fr], bad[fr] = chosen, hits
            if faults == 0 or (lo == 0 and hi == F - 1):
                break
    return lift, bad


def _steep(lift, chosen, lo, hi) -> int:
    """Steps faster than CHAIN_STEEP_RATE of raises `chosen` for frames lo..hi, between the
    raises `lift` of the frames just outside."""
    path = np.concatenate([lift[max(lo - 1, 0):lo], chosen, lift[hi + 1:hi + 2]])
    return int((np.abs(np.diff(path)) > CHAIN_STEEP_RATE + 1e-9).sum())


def _chain_trellis(rays, q, o, s, yaws, base_pitch, bend, lengths, back, grid, lift, lo, hi):
    """(raises (n,), touch (n,) bool) of frames lo..hi (n of them): the cheapest path
    (trellis.cheapest_path) through the raises `grid` at each frame, from the raise of frame
    lo - 1 to that of frame hi + 1 (`lift`, where they exist): a pose whose bones touch
    something costs CHAIN_HIT_COST, a step beyond CHAIN_RAISE_RATE CHAIN_STEEP_COST a radian
    (beyond CHAIN_STEEP_RATE, CHAIN_HIT_COST), a raise away from the eased one its distance."""
    F = len(lift)
    fr = np.arange(lo, hi + 1)
    n = len(fr)
    view = frames_of(rays, fr)
    touch = ~_chain_clear(view, q[fr], o[fr], s, yaws[0][fr, None], yaws[1][fr, None],
                          base_pitch[fr, None] + grid[None, :], bend, lengths, back)   # (n, G)
    cost = list(CHAIN_HIT_COST * touch + np.abs(grid[None, :] - lift[fr, None]))
    # the frames just outside keep their raises: one node each
    before, after = int(lo > 0), int(hi < F - 1)
    layers = [np.zeros(1)] * before + cost + [np.zeros(1)] * after
    values = [lift[lo - 1:lo]] * before + [grid] * n + [lift[hi + 1:hi + 2]] * after

    def edge(k):
        d = np.abs(values[k][:, None] - values[k + 1][None, :])
        over = np.maximum(d - CHAIN_RAISE_RATE, 0.0)
        return CHAIN_STEEP_COST * over + CHAIN_HIT_COST * (d > CHAIN_STEEP_RATE + 1e-9)

    pick = cheapest_path(layers, edge)[0][before:before + n]
    return grid[pick], touch[np.arange(n), pick]


def _turn_limited_antenna(q: np.ndarray, o: np.ndarray, r1: np.ndarray, r2: np.ndarray,
                          knee: np.ndarray, l1: float):
    """An antenna's bone rotations (F, 4) turning at most SPINE_FRAME_TURN a frame, in the world
    and relative to the bone it hangs from (the head q, then its first bone), and its knee
    (F, 3), moved where the first bone was turned less. The sweep is timed in seconds: at a low
    export rate (12 fps) it adds to the head's turn between frames, 35 degrees where the quality
    limit is 30; at 30 fps the limit seldom holds it back."""
    lim = np.radians(SPINE_FRAME_TURN)
    limited = limit_rotation(r1, lim, parent=q)
    moved = np.any(limited != r1, axis=1)
    if moved.any():
        knee = knee.copy()
        knee[moved] = o[moved] + quat_rotate(limited[moved], UP) * l1
    return limited, limit_rotation(r2, lim, parent=limited), knee


def hip_extent(cfg: RigConfig) -> tuple[float, float]:
    """(largest lateral offset, largest drop below the spine) of the hips [m] (no legs: 0, 0)."""
    if not cfg.legs.enabled:
        return 0.0, 0.0
    lay = leg_layout(cfg)
    return float(np.abs(lay.hip[:, 0]).max()), float(-lay.hip[:, 1].min())


def hip_layout(cfg: RigConfig) -> tuple[np.ndarray, np.ndarray]:
    """(hips (L, 3) in their spine joint's frame [m], the joint each hangs from (L,)) of the
    walking legs (no legs: none)."""
    if not cfg.legs.enabled:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    lay = leg_layout(cfg)
    return lay.hip, lay.segment


def hip_line(cfg: RigConfig) -> tuple[float, float]:
    """(largest lateral offset, mean height above the spine) of the walking legs' hips [m]:
    where the run stage measures the room beside them (no legs: 0, 0)."""
    if not cfg.legs.enabled:
        return 0.0, 0.0
    lay = leg_layout(cfg)
    return float(np.abs(lay.hip[:, 0]).max()), float(np.mean(lay.hip[:, 1]))


def _planned_with_margins(bf: BodyFrames, arc: np.ndarray, times: np.ndarray, rays,
                          cfg: RigConfig) -> dict:
    """walking_legs over the bake's frames with margins it then drops: before frame 0 the body
    stands still in its first pose for longer than a swing may last, so every foot has landed
    on a hold by frame 0 (a leg starting mid-swing turns fast and can dip into the ground);
    after the last frame it carries on at its last velocity, so a swing under way at the end
    keeps its pace instead of being squeezed into the frames left."""
    F = len(times)
    dt = float(times[1] - times[0]) if F > 1 else 1.0 / 30.0
    before = int(np.ceil(cfg.legs.settle_time / dt)) + MARGIN_FRAMES
    after = before
    k = np.arange(1, after + 1, dtype=float)
    idx = np.r_[np.zeros(before, int), np.arange(F), np.full(after, F - 1)]
    step = bf.positions[-1] - bf.positions[-2] if F > 1 else np.zeros_like(bf.positions[-1])
    pos = bf.positions[idx].copy()
    pos[before + F:] += k[:, None, None] * step.mean(axis=0)[None, None, :]
    padded = BodyFrames(positions=pos, rotations=bf.rotations[idx], normals=bf.normals[idx],
                        ground=bf.ground[idx])
    d_arc = float(arc[-1] - arc[-2]) if F > 1 else 0.0
    arc2 = np.r_[np.full(before, arc[0]), arc, arc[-1] + k * d_arc]
    times2 = np.r_[times[0] - dt * np.arange(before, 0, -1), times, times[-1] + dt * k]
    keep = slice(before, before + F)
    w = walking_legs(padded, arc2, times2, rays, cfg, judged=keep)
    for key in ("positions", "rotations", "feet", "targets", "contacts", "touchdown"):
        w[key] = w[key][keep]
    for key in ("touchdowns", "liftoffs"):
        w[key] = w[key] - before
    return w


def leg_frames(bf: BodyFrames, arc: np.ndarray, times: np.ndarray, rays, cfg: RigConfig,
               warning: np.ndarray | None = None, chain_period: float | None = None,
               near: NearBodies | None = None) -> LegFrames:
    """All limbs for all frames.

    bf      : the spine's BodyFrames (F frames)
    arc     : (F,) float, metres, the head's arc length along the trail (every segment moves by
              the same amount)
    times   : (F,) float, seconds
    rays    : the environment's RayCaster
    warning : (F,) float 0..1 or None, Posture 1 strength (raises the ultimate legs)
    chain_period : [s] or None, see posed_chains
    near    : in a crowd, the other creatures' bodies the ultimate legs and antennae may reach
              (locomotion.near; it answers for the environment too): they raise clear of them
    """
    w = _planned_with_margins(bf, np.asarray(arc, float), np.asarray(times, float), rays, cfg)
    cn, cp, cq = posed_chains(bf, np.asarray(times, float), rays if near is None else near, cfg,
                              warning=warning, chain_period=chain_period)
    return LegFrames(names=w["names"] + tuple(cn),
                     positions=np.concatenate([w["positions"], cp], axis=1),
                     rotations=np.concatenate([w["rotations"], cq], axis=1),
                     feet=w["feet"], targets=w["targets"], contacts=w["contacts"],
                     touchdown=w["touchdown"], lag=w["lag"])
