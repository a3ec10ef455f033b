"""Follow-the-leader body: every segment sits on the head's trail at its fixed arc length behind
the head, a clearance above the surface, oriented by the surface normal and facing the segment
ahead. Vectorized over frames and segments, with one batch of ray casts for the whole bake.

The trail is the head's path projected onto the surface below (Embree rays). Its height profile is
smoothed along the trail and kept inside a band around the surface, so the spine rides over
creases and small steps without kinks: neighbouring joints keep their spacing, and every joint
stays between 0 and 2x the clearance above the surface below it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.ndimage import gaussian_filter1d, label, maximum_filter1d

from baker.environment.rays import RayCaster
from baker.geometry import polyline
from baker.geometry.conventions import UP
from baker.geometry.transforms import (frames_to_quat, limit_rotation, normalize, quat_angle,
                                       quat_rotate)
from baker.locomotion.cobra import limit_lift
from baker.locomotion.trail_kernels import (gaussian_weights, interp_rows, linspace_to_zero,
                                            trail_pass)
from baker.locomotion.trail_kernels import place_chain as place_compiled
from baker.parallel import compiled_call


#: the smoothed trail stays at most this many clearances below the surface under it (so a
#: joint rides at least 1 - BELOW clearances above it, on convex crests too)
BELOW = 0.5
#: slope (rise over run) at which the bound a step puts on the trail falls away (35 degrees)
STEP_FALL = 0.7
#: the trail rounds the head path's kinks over this many segment spacings (Gaussian sigma)
ROUND = 1.5
#: hips stay at least this many clearances above the surface under them
HIP_CLEAR = 0.6
#: smoothing scale (in segment spacings) of the reference height raised (cobra) joints ride on
RAISED_SMOOTH = 3.0
#: a raised joint rises at most this fraction of a spacing above the joint behind it (the
#: neck's pitch over its reference stays below asin of it, so the chord placement stays
#: well-conditioned)
RAISED_RISE = 0.75
#: [deg/s] fastest turn of the head's facing (where its trail folds back)
HEAD_TURN_RATE = 540.0
#: [deg/s] fastest turn of a trunk joint's facing: 24 degrees a frame at 30 fps, above what
#: walking and the bend slow-down ask for; only a fold of the trail reaches it
TRUNK_TURN_RATE = 720.0
#: [deg] a cobra ramp turning a spine joint more than this in a frame rises more slowly (the
#: quality limit is 30 degrees; the legs' joints hang on the spine's)
LIFT_TURN = 24.0
#: [deg] the most any spine joint turns in a frame, whatever the trail does under it (a hook
#: of the trail over a stone's edge turns, pitches and rolls the tail at once); above LIFT_TURN
#: so a cobra ramp that turns a joint too fast is still found and slowed
SPINE_FRAME_TURN = 26.0
#: at most this many halvings of a ramp's rate
LIFT_ROUNDS = 3


@dataclass(frozen=True)
class BodyFrames:
    """positions : (F, S, 3) float64 metres, world; rotations : (F, S, 4) xyzw world;
    normals : (F, S, 3) unit surface normals under each joint; ground : (F, S) surface heights;
    lift : (F, S) cobra lift applied to each joint, metres (None: no lift requested);
    arcs : (F, S) each joint's 3D arc length on its trail (None: not kept)."""

    positions: np.ndarray
    rotations: np.ndarray
    normals: np.ndarray
    ground: np.ndarray
    lift: np.ndarray | None = None
    arcs: np.ndarray | None = None


def project_to_surface(rays: RayCaster, points: np.ndarray, probe: float):
    """Drop points onto the floor nearest to them below or just above.

    points : (n, 3) float, within `probe` metres of the surface (above or below it)
    Two downward rays per point, one from `probe` above it and one from a tenth of that. A hit
    counts as floor when there is at least `probe` of free space above it and the space just
    above it is not inside a solid (so the underside of an overhang, or a surface buried inside
    another solid where meshes interpenetrate or touch, is not); among floors, the one closer in height to the point wins (beside an overhang, the
    inside of a hollow log near its wall, that is the floor under it, not the overhang).
    returns (surface points (n, 3), up-facing unit normals (n, 3), hit (n,) bool); points that
    miss keep their position and get UP as the normal.
    """
    n = len(points)
    far = rays.cast_down(points, probe, max_distance=3.0 * probe)
    near = rays.cast_down(points, 0.1 * probe, max_distance=2.1 * probe)
    up = np.tile(UP, (n, 1))

    def floor(h):
        ok = h.hit.copy()
        if ok.any():
            above = h.points[ok] + 1e-4 * UP
            t, _ = rays.cast(above, up[ok], probe)
            # free space above, and not a face buried in another solid (coincident faces can
            # hide the solid's own face from the upward ray)
            ok[ok] = ~np.isfinite(t) & ~rays.inside(above)
        return ok

    f_ok, n_ok = floor(far), floor(near)
    closer = np.abs(near.points[:, 1] - points[:, 1]) < np.abs(far.points[:, 1] - points[:, 1])
    # rank: a floor beats a non-floor; then the closer in height
    use_near = near.hit & (~far.hit | (n_ok & ~f_ok) | ((n_ok == f_ok) & closer))
    hit = far.hit | near.hit
    hp = np.where(use_near[:, None], near.points, far.points)
    hn = np.where(use_near[:, None], near.normals, far.normals)
    out = points.copy()
    nrm = np.tile(UP, (n, 1))
    out[hit] = hp[hit]
    h = hn[hit]
    h[h[:, 1] < 0] *= -1.0
    nrm[hit] = h
    return out, nrm, hit


@dataclass(frozen=True)
class Trail:
    """The head's trail on the surface, resampled uniformly in horizontal arc length.

    points  : (T, 3) float64, metres, world; y is the smoothed surface height
    normals : (T, 3) float64, smoothed unit surface normals
    ground  : (T,) float64, raw surface height under each point
    cum     : (T,) float64, 3D arc length along `points`
    cum_h   : (T,) float64, horizontal arc length of each point
    high    : (T,) float64, a much smoother height profile on or above `points` (the reference
              a raised joint rides on: a lifted neck keeps its shape over bumps and rims)
    """

    points: np.ndarray
    normals: np.ndarray
    ground: np.ndarray
    cum: np.ndarray
    cum_h: np.ndarray
    high: np.ndarray | None = None

    def arc_at(self, horizontal_arc: np.ndarray) -> np.ndarray:
        """3D arc length at given horizontal arc lengths (exact, piecewise linear)."""
        return np.interp(horizontal_arc, self.cum_h, self.cum)


def build_trail(path: np.ndarray, rays: RayCaster, *, probe: float, spacing: float,
                clearance: float, resolution: float | None = None, hips: tuple = (0.0, 0.0)
                ) -> Trail:
    """Project the head's path onto the surface and smooth its height profile.

    path       : (n, 3) float, head positions oldest first (heights approximate, within `probe`)
    spacing    : metres between spine joints; the smoothing scale
    clearance  : metres; joints ride a clearance above the trail, at least half a clearance
                 above the surface
    resolution : horizontal sample spacing (default spacing / 8)
    hips       : (lateral offset, drop below the joint) of the hips [m]: the surface under them,
                 on either side of the path, keeps the trail high enough that they stay
                 HIP_CLEAR clearances above it (a body across a stair's nosing)
    """
    res = resolution or spacing / 8.0
    flat = path.copy()
    flat[:, 1] = 0.0
    cum_h0 = polyline.arc_lengths(flat)
    n = max(int(np.ceil(cum_h0[-1] / res)), 1) + 1
    s = np.linspace(0.0, cum_h0[-1], n)
    pts = polyline.sample(path, cum_h0, s)
    # the body follows the head's path with its kinks rounded (a slide along an edge or a turn
    # on the spot bends the path sharper than the turning radius; every joint would turn there)
    pts[:, [0, 2]] = straight_ended_smooth(pts[:, [0, 2]], ROUND * spacing / res)
    ground_pts, normals, _ = project_to_surface(rays, pts, probe)
    ground = ground_pts[:, 1]
    sigma = 2.0 * spacing / res
    # the smoothed ground, raised by smooth bumps wherever it would take a joint closer than
    # the step bound allows (creases, rims, step edges): a profile with bounded curvature, so
    # a joint passing over a step turns gradually instead of in one frame
    lo = np.maximum(step_lower_bound(ground, res, spacing, clearance),
                    _hip_bound(rays, pts, ground_pts, probe, clearance, *hips))
    smooth = gaussian_filter1d(ground, sigma, mode="nearest")
    y = smooth + smooth_envelope(np.maximum(lo - smooth, 0.0), sigma)
    pts = ground_pts.copy()
    pts[:, 1] = y
    normals = normalize(gaussian_filter1d(normals, 0.5 * sigma, axis=0, mode="nearest"))
    return _trail(pts, normals, ground, s, RAISED_SMOOTH * spacing / res)


def _trail(points: np.ndarray, normals: np.ndarray, ground: np.ndarray, cum_h: np.ndarray,
           high_sigma: float) -> Trail:
    """The Trail of `points` (their heights final): its 3D arc lengths, and the smooth profile
    raised joints ride on (smooth_envelope over `high_sigma` samples)."""
    return Trail(points=points, normals=normals, ground=ground,
                 cum=polyline.arc_lengths(points), cum_h=cum_h,
                 high=smooth_envelope(points[:, 1], high_sigma))


def raised_for_hips(trail: Trail, bf: BodyFrames, rays, hips: np.ndarray, segment: np.ndarray,
                    clearance: float, spacing: float) -> Trail | None:
    """The trail raised where a placed joint's hip comes within half of HIP_CLEAR clearances
    of an up-facing surface under it, or is inside a solid whose top is within two spacings
    above it, by what takes it back to HIP_CLEAR above (None: no hip does).

    build_trail keeps the hips clear on either side of the path; a joint's hips lie across its
    own facing, the chord to the joint ahead, which in a tight turn or over a fold of the path
    can be most of a right angle off the path's: they then pass over ground the path's sides
    never sampled (the corner of a platform beside the walked floor). The bound is put at the
    joints' arc lengths (bf.arcs), so a second placement lifts them there.

    hips : (L, 3) the hips in their joint's frame; segment : (L,) the joint each hangs from
    """
    q = bf.rotations[:, segment]
    origin = bf.positions[:, segment]
    hip = origin + quat_rotate(q, np.broadcast_to(hips, q.shape[:-1] + (3,)))
    want = HIP_CLEAR * clearance
    # down from the joint's own height (it is clear of the surface) at the hip's ground point
    o = hip.reshape(-1, 3).copy()
    o[:, 1] = origin[..., 1].ravel()
    reach = np.maximum(o[:, 1] - hip[..., 1].ravel(), 0.0) + want
    h = rays.cast_down(o, 0.0, max_distance=reach)
    deficit = np.where(h.hit & (np.abs(h.normals[:, 1]) > 0.5),
                       h.points[:, 1] + want - hip[..., 1].ravel(), 0.0)
    bad = deficit > 0.5 * want
    if bad.any():
        # a floor: nothing over it up to the joint's height, and not the underside of a solid
        # the ray started in (a shelf's edge level with the joint, beside the body)
        i = np.flatnonzero(bad)
        above = h.points[i] + 1e-4 * UP
        t, _ = rays.cast(above, np.tile(UP, (len(i), 1)),
                         np.maximum(o[i, 1] - above[:, 1], 1e-6))
        bad[i] = ~np.isfinite(t) & ~rays.inside(above)
    # a hip already inside a solid (a body crossing a step's edge askew: its joint over the
    # ramp below the top, the hip over the top's corner) is not seen from the joint's height,
    # a ray started inside the step: its way out straight up, within two spacings, is the top
    hp = hip.reshape(-1, 3)
    t, _ = rays.cast(hp, np.broadcast_to(UP, hp.shape), 2.0 * spacing)
    i = np.flatnonzero(np.isfinite(t) & ~bad)
    if len(i):
        i = i[rays.inside(hp[i])]
        deficit[i] = t[i] + want
        bad[i] = True
    if not bad.any():
        return None
    arcs = bf.arcs[:, segment].ravel()[bad]
    need = np.zeros(len(trail.cum))
    k = np.clip(np.searchsorted(trail.cum, arcs), 0, len(need) - 1)
    np.maximum.at(need, k, deficit[bad])
    res = float(trail.cum_h[1] - trail.cum_h[0]) if len(trail.cum_h) > 1 else spacing / 8.0
    # the joint's arc is kept to within a few samples: its neighbours get the bound too
    need = maximum_filter1d(need, size=2 * max(int(round(0.25 * spacing / res)), 1) + 1)
    pts = trail.points.copy()
    pts[:, 1] += smooth_envelope(need, 2.0 * spacing / res)
    return _trail(pts, trail.normals, trail.ground, trail.cum_h, RAISED_SMOOTH * spacing / res)


def straight_ended_smooth(xy: np.ndarray, sigma: float, axis: int = 0,
                          reach: int | None = None) -> np.ndarray:
    """Gaussian smoothing (sigma in samples) along `axis` of paths whose ends carry on as
    straight lines (each end extended by the path's point reflection about it, `reach` samples,
    default the kernel's 4 sigma), so a path that runs straight into its end keeps its pace
    there: padding with the end point itself bunches the last samples up, and a body following
    the trail slowed down over its last frames (to 63 % of its speed in the last frame of a
    default bake)."""
    xy = np.moveaxis(xy, axis, 0)
    k = min(int(4.0 * sigma + 0.5) if reach is None else reach, len(xy) - 1)
    if k < 1:
        out = gaussian_filter1d(xy, sigma, axis=0, mode="nearest")
    else:
        padded = np.concatenate([2.0 * xy[0] - xy[k:0:-1], xy, 2.0 * xy[-1] - xy[-2:-k - 2:-1]])
        out = gaussian_filter1d(padded, sigma, axis=0, mode="nearest")[k:k + len(xy)]
    return np.moveaxis(out, 0, axis)


def trail_ends(paths: np.ndarray, cums: np.ndarray, ends: np.ndarray, extent: float,
               spacing: float, resolution: float | None = None, rows: np.ndarray | None = None,
               starts: np.ndarray | None = None) -> np.ndarray:
    """The last `extent` metres of several heads' trails, as build_trail makes them from the
    paths so far: each path resampled every `resolution` (default spacing / 8) of horizontal arc
    length, its kinks rounded and its heights smoothed as build_trail rounds and smooths them
    (a turn on the spot or a dithering head leaves a cusp the body's trail does not have), then
    sampled every `resolution` of the trail's own arc length, as place_chain walks it.

    paths : (N, T, 3) float, head paths, oldest first (heights within the probe)
    cums  : (N, T) float, their horizontal arc lengths (non-decreasing)
    ends  : (n,) int, the index of each path's last point (the head)
    rows  : (n,) int, the paths taken (default all); starts : (n,) int, the index of each one's
            first point (default 0: each path then taken to its last point, T - 1, its arc
            lengths held at the head's after the head); with starts, each path is taken from
            there to its head and its arc lengths measured from there (the paths are read
            where they lie: a crowd's kept paths need no copy of their windows)
    returns (n, m, 3) float, oldest first, the head's point last; a trail shorter than
    `extent` is held at its first point before it
    """
    res = resolution or spacing / 8.0
    sigma = ROUND * spacing / res
    pad = int(4.0 * max(sigma, 2.0 * spacing / res) + 0.5)     # what smoothing a start reaches
    n = len(ends)
    rows = np.arange(n) if rows is None else np.asarray(rows, dtype=np.intp)
    ends = np.asarray(ends, dtype=np.intp)
    # each row's knots: its arc lengths from its first point to its last (`stops`), less
    # `base`, held at the head's after the head
    if starts is None:
        starts, stops, base = np.zeros(n, np.intp), np.full(n, cums.shape[1] - 1), np.zeros(n)
    else:
        starts, stops = np.asarray(starts, dtype=np.intp), ends
        base = cums[rows, starts]
    first, total = cums[rows, starts] - base, cums[rows, ends] - base
    span = np.full(n, 2.0 * extent + 2.0 * pad * res)
    m = max(int(np.ceil(extent / res)), 1) + 1
    out = np.empty((n, m, 3))
    todo = np.arange(n)
    w_xz, w_y = gaussian_weights(sigma), gaussian_weights(2.0 * spacing / res)
    while len(todo):
        # a dithering head's raw arc length is longer than its trail's: look farther back
        w = int(np.ceil(span[todo[0]] / res)) + 1
        s = total[todo, None] + linspace_to_zero(float(-span[todo[0]]), w)[None, :]
        k = min(pad, w - 1)
        # resampled (_interp_rows), x and z smoothed with straight ends (straight_ended_smooth,
        # reach pad), y smoothed: compiled, the same bits (locomotion.trail_kernels)
        pts, arc = np.empty((len(todo), w, 3)), np.empty((len(todo), w))
        shifts = _row_shifts(np.column_stack([first[todo], total[todo]]))
        trail_pass(np.maximum(s, 0.0), cums, paths, rows[todo], starts[todo], ends[todo],
                   stops[todo], base[todo], shifts, w_xz, w_y, k, pts, arc)
        short = (s[:, 0] > 0.0) & (arc[:, -1] - arc[:, k] < extent)
        done, again = todo, todo[:0]
        if short.any():                  # (rare: no copies of the rows when every one is done)
            done, again, arc, pts = todo[~short], todo[short], arc[~short], pts[~short]
        q = arc[:, -1:] + linspace_to_zero(-float(extent), m)[None, :]
        out[done] = _interp_rows(q, arc, pts)
        todo = again
        span[todo] *= 2.0
    return out


def _row_shifts(xp: np.ndarray) -> np.ndarray:
    """(n,) the offsets _interp_rows adds to each row of knots xp (n, b) (and its keys) so
    that the rows follow one another, at least 1 apart (read from each row's first and last
    knots alone)."""
    width = float((xp[:, -1] - xp[:, 0]).max()) + 1.0
    return width * np.arange(len(xp)) - xp[:, 0]


def _interp_rows(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """np.interp row by row, the rows shifted apart as one flat call would have them (compiled:
    trail_kernels.interp_rows): x (n, a), xp (n, b) non-decreasing rows, fp (n, b, d)
    -> (n, a, d) (each row's values clamped to its ends)."""
    n = len(x)
    out = np.empty((n, x.shape[1], fp.shape[2]))
    if n:
        interp_rows(x, xp, fp, _row_shifts(xp), out)
    return out


def chain_on(trails: np.ndarray, lift: np.ndarray, spacing: float,
             resolution: float | None = None) -> np.ndarray:
    """Follow-the-leader placement on trails as place_chain does it: the head at each trail's
    last point, every other joint on the trail exactly `spacing` behind the joint ahead (the
    chord, so across a fold of the trail it is not the arc length), each raised by its lift.
    Compiled (_chain_on; parallel.compiled_call).

    trails : (n, m, 3) float, oldest first, a point every `resolution` (default spacing / 8)
             of horizontal arc length (trail_ends); lift : (n, S) float [m]
    returns (n, S, 3) float; a joint past a trail's start is at its start
    """
    res = resolution or spacing / 8.0
    n, m, _ = trails.shape
    out = np.empty((n, lift.shape[1], 3))
    # bracket within four spacings back, as place_chain does (the trail can fold back)
    look = min(int(round(4.0 * spacing / res)) + 1, m)
    compiled_call(_chain_on, np.ascontiguousarray(trails, dtype=np.float64),
                  np.ascontiguousarray(lift, dtype=np.float64), float(spacing), look, out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _chain_on(trails, lift, spacing, look, out):
    """chain_on's loops. Each joint, from the joint ahead (prev): the first of the `look`
    trail samples behind the last one used (a sample before the trail's start is its start)
    that lies more than `spacing` from prev (the last of them when none does), and the point
    on the segment from the sample before it (prev itself for the first) at exactly `spacing`
    from prev (the end of the segment when none is). The samples are raised by the joint's
    lift (x + lift * UP, component by component). The dot products add x, z and then y, in
    that order on every CPU (numpy's einsum, which the vectorized placement before this used,
    adds them so on AVX machines: there the bits are the same as before).
    """
    n, m = trails.shape[0], trails.shape[1]
    S = lift.shape[1]
    cand = np.empty((look, 3))
    for r in range(n):
        up = lift[r, 0]
        out[r, 0, 0] = trails[r, m - 1, 0] + up * 0.0
        out[r, 0, 1] = trails[r, m - 1, 1] + up * 1.0
        out[r, 0, 2] = trails[r, m - 1, 2] + up * 0.0
        at = m - 2                        # the first sample behind the joint ahead
        for i in range(1, S):
            up = lift[r, i]
            px, py, pz = out[r, i - 1, 0], out[r, i - 1, 1], out[r, i - 1, 2]
            first = look
            for c in range(look):
                k = max(at - c, 0)
                cand[c, 0] = trails[r, k, 0] + up * 0.0
                cand[c, 1] = trails[r, k, 1] + up * 1.0
                cand[c, 2] = trails[r, k, 2] + up * 0.0
                vx, vy, vz = cand[c, 0] - px, cand[c, 1] - py, cand[c, 2] - pz
                if np.sqrt(vx * vx + vy * vy + vz * vz) > spacing:
                    first = c
                    break
            j = min(first, look - 1)
            ax, ay, az = cand[j, 0], cand[j, 1], cand[j, 2]
            if j > 0:
                bx, by, bz = cand[j - 1, 0], cand[j - 1, 1], cand[j - 1, 2]
            else:
                bx, by, bz = px, py, pz
            dx, dy, dz = ax - bx, ay - by, az - bz
            ex, ey, ez = bx - px, by - py, bz - pz
            qa = (dx * dx + dz * dz) + dy * dy
            qb = 2.0 * ((dx * ex + dz * ez) + dy * ey)
            qc = ((ex * ex + ez * ez) + ey * ey) - spacing * spacing
            disc = qb * qb - 4.0 * qa * qc
            den = 2.0 * qa
            t = (-qb + np.sqrt(_np_max(disc, 0.0))) / _np_max(den, 1e-18)
            t = _np_min(_np_max(0.0, t), 1.0) if first < look else 1.0
            out[r, i, 0] = bx + t * dx
            out[r, i, 1] = by + t * dy
            out[r, i, 2] = bz + t * dz
            at = max(at - j, 0)


@njit(cache=True, nogil=True, inline="always")
def _np_max(a, b):
    """np.maximum(a, b) of two floats: a NaN wins, and a when the two are equal (signed zeros)."""
    return a if (a >= b or a != a) else b


@njit(cache=True, nogil=True, inline="always")
def _np_min(a, b):
    """np.minimum(a, b) of two floats: a NaN wins, and a when the two are equal (signed zeros)."""
    return a if (a <= b or a != a) else b


def _hip_bound(rays, pts: np.ndarray, ground_pts: np.ndarray, probe: float, clearance: float,
               offset: float, drop: float) -> np.ndarray:
    """(T,) lowest trail height that keeps hips `offset` metres either side of the path (and
    `drop` below their joint) HIP_CLEAR clearances above the surface under them (-inf where
    there is nothing under them or no offset)."""
    out = np.full(len(pts), -np.inf)
    if offset <= 0.0 or len(pts) < 2:
        return out
    t = np.gradient(pts, axis=0)
    t[:, 1] = 0.0
    side = normalize(np.cross(UP, t))
    # both sides in one batch of rays
    g, _, hit = project_to_surface(rays, np.concatenate([ground_pts + offset * side,
                                                         ground_pts - offset * side]), probe)
    n = len(pts)
    for g_s, hit_s in ((g[:n], hit[:n]), (g[n:], hit[n:])):
        need = g_s[:, 1] + drop + HIP_CLEAR * clearance - clearance
        out = np.where(hit_s & (g_s[:, 1] < ground_pts[:, 1] + probe), np.maximum(out, need), out)
    return out


def smooth_envelope(y: np.ndarray, sigma: float, rounds: int = 6) -> np.ndarray:
    """(T,) a smooth profile on or above y: Gaussian-smoothed upper envelopes (max filter over
    half a sigma), raised by smooth bumps where y still pokes through, `rounds` times; whatever
    remains (a tiny residual) is clipped."""
    k = max(int(round(0.5 * sigma)), 1) * 2 + 1
    high = gaussian_filter1d(maximum_filter1d(y, size=k, mode="nearest"), sigma, mode="nearest")
    for _ in range(rounds):
        gap = np.maximum(y - high, 0.0)
        if gap.max() <= 0.0:
            break
        high += gaussian_filter1d(maximum_filter1d(gap, size=k, mode="nearest"), sigma,
                                  mode="nearest")
    return np.maximum(high, y)


def step_lower_bound(ground: np.ndarray, res: float, spacing: float,
                     clearance: float) -> np.ndarray:
    """(T,) the lowest the smoothed trail may go at each sample: BELOW clearances under the
    surface, and more near a step.

    A step is where the ground jumps by more than half a clearance between neighbouring samples
    (a 60 degree slope rises a third of that). Within a quarter spacing of the step the trail
    stays within 0.75 clearance under the step's top (so its chords never cut the edge; a joint
    is a quarter clearance above it). Beyond, that bound falls away at STEP_FALL (the body goes
    down a step over about a spacing, not in one sample), asks for at most 0.9 clearance above
    the surface once half a spacing away, and fades out over the half spacing before two
    spacings, so the bound has no jump anywhere.
    """
    base = ground - BELOW * clearance
    e = np.nonzero(np.abs(np.diff(ground)) > 0.5 * clearance)[0]
    if len(e) == 0:
        return base
    top = np.full(len(ground), -np.inf)
    hi = np.maximum(ground[e], ground[e + 1])
    np.maximum.at(top, e, hi)
    np.maximum.at(top, e + 1, hi)
    flat, reach, fade = 0.25 * spacing, 2.0 * spacing, 0.5 * spacing
    cap = ground + 0.9 * clearance
    out = base.copy()
    for m in range(0, int(np.ceil((flat + reach) / res)) + 1):
        d = max(m * res - flat, 0.0)
        w = min(max((reach - d) / fade, 0.0), 1.0)
        if w <= 0.0:
            break
        for src, dst in ((slice(m, None), slice(None, len(top) - m)),
                         (slice(None, len(top) - m), slice(m, None))):
            need = top[src] - 0.75 * clearance
            # the cap gives way to the step's own need at the step, fading over half a spacing
            c = cap[dst] + np.maximum(need - cap[dst], 0.0) * max(1.0 - d / fade, 0.0)
            want = np.minimum(need - STEP_FALL * d, c)
            lift = np.maximum(want - base[dst], 0.0)
            np.maximum(out[dst], base[dst] + w * lift, out=out[dst])
    return out


def limit_turn(dirs: np.ndarray, axes: np.ndarray, max_angle: float) -> np.ndarray:
    """Directions (F, 3) that follow `dirs` but turn at most `max_angle` radians a frame,
    swinging about `axes` (F, 3, unit) when the turn is a full reversal. Frames are processed
    one by one only from the first too-fast turn until the output has caught up again."""
    d = normalize(np.asarray(dirs, dtype=np.float64))
    F = len(d)
    if F < 2:
        return d
    cos_lim = math.cos(max_angle)
    fast = np.nonzero(np.einsum("ij,ij->i", d[:-1], d[1:]) < cos_lim)[0]
    if len(fast) == 0:
        return d
    out = d.copy()
    f = int(fast[0]) + 1
    while f < F:
        prev, want = out[f - 1], d[f]
        c = float(np.dot(prev, want))
        if c >= cos_lim:
            out[f] = want
            nxt = fast[fast >= f]
            if len(nxt) == 0:
                break
            f = max(f + 1, int(nxt[0]) + 1)
            continue
        axis = np.cross(prev, want)
        n = float(np.linalg.norm(axis))
        axis = axis / n if n > 1e-9 else axes[f] / max(float(np.linalg.norm(axes[f])), 1e-12)
        # Rodrigues: prev rotated by max_angle about axis
        out[f] = (prev * math.cos(max_angle) + np.cross(axis, prev) * math.sin(max_angle)
                  + axis * float(np.dot(axis, prev)) * (1.0 - math.cos(max_angle)))
        f += 1
    return out


def place_chain(trail: Trail, head_arc: np.ndarray, offset: np.ndarray, spacing: float,
                raised: np.ndarray | None = None):
    """Follow-the-leader placement: the head at its arc length on the trail, every other joint
    on the trail exactly `spacing` (3D) behind the joint ahead, each raised by its offset.

    offset : (F, S) metres above the trail (clearance + any cobra lift)
    raised : (F, S) 0..1 or None: how much each joint rides on the trail's smooth `high`
             profile instead of its surface-following height (a raised joint's reference)
    returns (positions (F, S, 3), arc lengths on the trail (F, S))
    On a smooth trail this is the joint's fixed arc length behind the head to within a
    fraction of a percent; where the trail bends over a crease or a small step, keeping the
    chord exact keeps the body's segments rigid.
    """
    F, S = offset.shape
    offset = np.array(offset, dtype=np.float64, copy=True)
    pos = np.empty((F, S, 3))
    arc = np.empty((F, S))
    w = np.zeros((F, S)) if raised is None or trail.high is None else raised
    rise = (trail.high - trail.points[:, 1]) if trail.high is not None else np.zeros(len(trail.cum))
    # compiled, with the numpy form's arithmetic (tests/unit/test_trail_kernels.py): for each
    # frame and joint, the first of 33 arc steps back (up to four spacings: the trail can fold
    # back on itself over a crease or in a tight turn) whose point is a spacing from the joint
    # ahead, then 16 bisections of the arc; a raised joint (`raised`) first kept at most
    # RAISED_RISE spacings below the joint ahead at its arc, so a point a spacing behind
    # exists on its trail (a joint riding the smooth profile less than the one ahead, over a
    # dip, would otherwise hang straight down from it, short of the trail)
    place_compiled(trail.points, trail.cum, rise, head_arc, offset, w,
                   np.linspace(0.0, 4.0 * spacing, 33), spacing,
                   None if raised is None else RAISED_RISE * spacing, pos, arc)
    return pos, arc


def step_over_lips(trail: Trail, head_arc: np.ndarray, rays, height: float, max_slope: float,
                   reach: float, depth: float) -> np.ndarray:
    """(F,) head arcs moved off the steep strips of the trail, so no frame samples the head
    over a face steeper than `max_slope` [rad] (a ray straight down from it meets that face).

    Seen from above, a riser leaning a little off vertical is a strip a few millimetres wide
    that the head crosses in about a frame while it climbs the riser; it is sampled over it in
    roughly half of the crossings. Each such frame moves to the nearest arc, within `reach`
    metres along the trail, whose ray meets a walkable face: the head steps over the lip between
    two frames instead of being drawn on it. Frames with no such arc in reach (a head on a
    long steep slope) keep theirs. `head_arc` is non-decreasing (the head's arc along its own
    trail) and stays so.

    height : metres above the trail the rays start (the head's clearance); depth : how far
    they look [m]
    """
    head_arc = np.asarray(head_arc, dtype=np.float64)
    steep = _steep_under(trail, head_arc, rays, height, max_slope, depth)
    if not steep.any():
        return head_arc
    idx = np.nonzero(steep)[0]
    step = 0.05 * reach
    d = np.arange(-reach, reach + 0.5 * step, step)
    d = d[np.lexsort((-d, np.abs(d)))]      # nearest first; ahead before behind
    cand = np.clip(head_arc[idx, None] + d[None, :], trail.cum[0], trail.cum[-1])
    ok = ~_steep_under(trail, cand.ravel(), rays, height, max_slope, depth).reshape(cand.shape)
    found = ok.any(axis=1)
    out = head_arc.copy()
    out[idx[found]] = cand[found, np.argmax(ok[found], axis=1)]
    # the head's arc only grows: a frame moved back behind the one before it (or forward past
    # the next) takes that frame's arc, which is clear of the strip too
    return np.maximum.accumulate(out)


def _steep_under(trail: Trail, arc: np.ndarray, rays, height: float, max_slope: float,
                 depth: float) -> np.ndarray:
    """(n,) bool: a ray straight down from `height` above the trail at each arc meets a face
    steeper than `max_slope`."""
    pts = polyline.sample(trail.points, trail.cum, arc)
    h = rays.cast_down(pts, height, max_distance=depth)
    cos = np.abs(np.nan_to_num(h.normals[:, 1], nan=1.0))
    return h.hit & (cos < math.cos(max_slope))


def eroded(a: np.ndarray, rate: float | np.ndarray) -> np.ndarray:
    """The largest function <= a that changes by at most `rate` per frame along axis 0: the
    cone erosion min_j a[j] + rate * |i - j|. `rate` is a scalar or one per column."""
    a = np.asarray(a, dtype=np.float64)
    t = (np.arange(len(a), dtype=np.float64).reshape((-1,) + (1,) * (a.ndim - 1))
         * np.asarray(rate, dtype=np.float64))
    ahead = t + np.minimum.accumulate(a - t, axis=0)
    behind = np.flip(np.minimum.accumulate(np.flip(a + t, axis=0), axis=0), axis=0) - t
    return np.minimum(ahead, behind)


def limit_rise(lift: np.ndarray, rise: float) -> np.ndarray:
    """(F, S) lifts with each joint at most `rise` metres above the joint behind it (from the
    tail forward: a steeper curve is lowered at the front)."""
    out = np.array(lift, dtype=np.float64, copy=True)
    for i in range(out.shape[1] - 2, -1, -1):
        np.minimum(out[:, i], out[:, i + 1] + rise, out=out[:, i])
    return out


def body_frames(trail: Trail, head_arc: np.ndarray, spacing: float, segments: int,
                clearance: float, *, lift: np.ndarray | None = None, rays=None,
                ceiling_margin: float = 0.0, fps: int = 30, ramp_time: float = 0.4) -> BodyFrames:
    """Place the spine on the trail.

    head_arc : (F,) float, 3D arc length of the head along the trail at each frame
    lift     : (F, S) optional cobra lift per joint (metres), limited by upward rays on `rays`
    A cobra ramp that would turn a spine joint more than LIFT_TURN in a frame rises (or
    settles) more slowly, for up to LIFT_ROUNDS halvings of its rate.
    """
    F = len(head_arc)
    ramp = 1.0 / max(ramp_time * fps, 1.0)
    if lift is None or lift.max(initial=0.0) <= 0.0:
        lift = np.zeros((F, segments))
        return _turn_limited(_placed(trail, head_arc, spacing, clearance, lift, None, fps))
    s0 = head_arc[:, None] - spacing * np.arange(segments)[None, :]
    flat = polyline.sample(trail.points, trail.cum, s0) + clearance * UP
    lift = limit_lift(flat, lift, spacing, rays, ceiling_margin, int(round(ramp_time * fps)))
    lift = limit_rise(lift, RAISED_RISE * spacing)
    bf = _placed(trail, head_arc, spacing, clearance, lift, _raised(lift, ramp), fps)
    rate = np.abs(np.diff(lift, axis=0)).max(axis=0, initial=0.0)
    for _ in range(LIFT_ROUNDS):
        turn = np.degrees(quat_angle(bf.rotations[:-1], bf.rotations[1:])).max(axis=1)
        rate = 0.5 * rate
        slower = limit_rise(eroded(lift, rate), RAISED_RISE * spacing)
        slow = _fast_ramps(lift, slower, turn > LIFT_TURN)
        if not slow.any():
            break
        lift = np.where(slow[:, None], slower, lift)
        # the slowed frames are placed again on their own, and the joints' directions taken
        # over all frames (a joint's turn limit runs frame by frame)
        again = _points(trail, head_arc[slow], spacing, clearance, lift[slow],
                        _raised(lift, ramp)[slow])
        pos, normals, ground, arcs = (_spliced(a, b, slow) for a, b in
                                      zip((bf.positions, bf.normals, bf.ground, bf.arcs), again))
        bf = BodyFrames(positions=pos, rotations=_oriented(trail, head_arc, pos, normals,
                                                           spacing, fps),
                        normals=normals, ground=ground, lift=lift, arcs=arcs)
    return _turn_limited(bf)


def _turn_limited(bf: BodyFrames) -> BodyFrames:
    """The spine with no joint turning more than SPINE_FRAME_TURN in a frame, in the world or
    relative to the joint ahead (its positions as they are): where the trail folds into a cusp
    two neighbouring joints would swing round it in opposite senses, each at the limit, and
    turn twice the limit against each other."""
    lim = math.radians(SPINE_FRAME_TURN)
    rot = bf.rotations
    for j in range(rot.shape[1]):     # head to tail: each joint after the one ahead of it
        rot[:, j] = limit_rotation(rot[:, j], lim, parent=rot[:, j - 1] if j else None)
    return bf


def _spliced(a: np.ndarray, b: np.ndarray, rows: np.ndarray) -> np.ndarray:
    out = a.copy()
    out[rows] = b
    return out


def _raised(lift: np.ndarray, ramp: float) -> np.ndarray:
    """(F, S) 0..1: how much each joint rides the trail's smooth profile: fully from a quarter
    of the highest lift, changing by at most a full ride over the cobra's ramp (`ramp` per
    frame): over a dip the profile is several spacings above the trail, and the joints would
    rise into it in a few frames, a wave of turns down the neck."""
    return eroded(np.clip(4.0 * lift / max(float(lift.max()), 1e-12), 0.0, 1.0), ramp)


def _fast_ramps(lift: np.ndarray, slower: np.ndarray, turned: np.ndarray) -> np.ndarray:
    """(F,) bool: the frames of every lift ramp that turns a joint too fast (`turned`, (F-1,)
    per frame step) and that the `slower` lift would change: the runs of frames where the two
    differ, taken whole so the slower ramp joins the lift on either side of it."""
    runs, n = label((slower < lift - 1e-9).any(axis=1))
    if n == 0 or not turned.any():
        return np.zeros(len(lift), dtype=bool)
    bad = np.zeros(len(lift), dtype=bool)
    bad[1:] |= turned
    bad[:-1] |= turned
    hit = np.unique(runs[bad & (runs > 0)])
    return np.isin(runs, hit) & (runs > 0)


def _placed(trail: Trail, head_arc: np.ndarray, spacing: float, clearance: float,
            lift: np.ndarray, raised: np.ndarray | None, fps: int) -> BodyFrames:
    """The spine at the given frames (every frame from the first: the joints' directions are
    limited frame by frame), each joint `clearance + lift` above the trail."""
    pos, normals, ground, arcs = _points(trail, head_arc, spacing, clearance, lift, raised)
    rot = _oriented(trail, head_arc, pos, normals, spacing, fps)
    return BodyFrames(positions=pos, rotations=rot, normals=normals, ground=ground, lift=lift,
                      arcs=arcs)


def _points(trail: Trail, head_arc: np.ndarray, spacing: float, clearance: float,
            lift: np.ndarray, raised: np.ndarray | None):
    """(positions (F, S, 3), normals (F, S, 3), ground heights (F, S), arc lengths (F, S)) of
    the spine's joints at the given frames, each on its own."""
    pos, s = place_chain(trail, head_arc, clearance + lift, spacing, raised=raised)
    normals = normalize(polyline.sample(trail.normals, trail.cum, s))
    return pos, normals, np.interp(s, trail.cum, trail.ground), s


def _oriented(trail: Trail, head_arc: np.ndarray, pos: np.ndarray, normals: np.ndarray,
              spacing: float, fps: int) -> np.ndarray:
    """(F, S, 4) the joints' rotations (xyzw) over consecutive frames: each faces the joint
    ahead, the head along its trail, a fold's reversal swung round over a few frames."""
    forward = np.empty_like(pos)
    forward[:, 1:] = pos[:, :-1] - pos[:, 1:]
    # the head faces along its trail: the chord from half a spacing behind it (the tangent of
    # a single trail segment flips at the trail's millimetre-scale kinks, where it folds back)
    behind = polyline.sample(trail.points, trail.cum, np.maximum(head_arc - 0.5 * spacing, 0.0))
    head_dir = polyline.sample(trail.points, trail.cum, head_arc) - behind
    ahead = pos[:, 0] - pos[:, 1]
    forward[:, 0] = np.where(np.linalg.norm(head_dir, axis=1, keepdims=True) > 0.25 * spacing,
                             head_dir, ahead)
    # where the trail folds back on itself (a reversal in a dead end) the head swings round
    # over a few frames instead of flipping in one
    forward[:, 0] = limit_turn(forward[:, 0], normals[:, 0], np.radians(HEAD_TURN_RATE) / fps)
    # ... and so does every joint behind it as it passes the fold (its chord to the joint ahead
    # reverses there: 114-135 degrees in a frame where the head turned back at the start line)
    trunk_rate = np.radians(TRUNK_TURN_RATE) / fps
    chords = forward[:, 1:].copy()
    forward[:, 1:] = normalize(chords)
    f = forward[:, 1:]
    folding = np.any(np.einsum("fjk,fjk->fj", f[:-1], f[1:]) < math.cos(trunk_rate), axis=0)
    for i in np.flatnonzero(folding) + 1:     # only the joints that pass a fold
        forward[:, i] = limit_turn(chords[:, i - 1], normals[:, i], trunk_rate)
    return frames_to_quat(forward, normals)
