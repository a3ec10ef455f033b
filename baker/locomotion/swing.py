"""Joint-space swings: the fallback for swings whose foot-space path breaks a limit.

legs.py plans each swing as a foot path (an arc around the hip, lifted, then pushed off walls,
raised over obstacles, re-timed) and solves it with two-bone IK. Near walls, on stairs and in
tight turns those corrections can fight each other: the leg then turns too far in one frame,
a bone passes through something, the foot goes into a surface, skims along one, or crowds a
neighbour's foot.

Such a swing is replaced by one in the leg's own joint space: the upper bone's rotation
(relative to its segment) and the tip bone's (relative to the upper bone) slerp from the last
planted pose to the touchdown pose at an even pace, while the whole leg is raised about the
body's long axis (through the hip) by a bump raise * profile(u). Of the candidate raises and
profiles, the first that keeps every frame of the swing within all limits wins; when none does,
the one with the fewest offending frames, and the planned swing stays when it has no more
than that. Both ends are the planted poses, so stances are untouched. All swings, candidates
and frames are checked in flat batches (one ray batch per candidate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.geometry.transforms import (quat_about, quat_angle, quat_conj, quat_mul, quat_rotate,
                                       quat_slerp)

#: raises of the whole leg about the body's long axis tried, smallest first [rad]
RAISES = np.radians([4.0, 8.0, 12.0, 16.0, 24.0, 32.0, 45.0, 60.0])
#: knee swivels about the hip -> foot line tried when raising alone does not clear [rad]
SWIVELS = np.radians([25.0, -25.0, 50.0, -50.0])
#: the cost of a joint turning too fast in a frame, against 1 for any other fault
TURN_WEIGHT = 100.0
#: raise profiles over the swing's progress u: a plain bump, and one that rises sooner
PROFILES = (lambda u: np.sin(np.pi * u), lambda u: np.sqrt(np.sin(np.pi * u)))
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
    """

    contact: float
    slide: float
    tol: float
    turn: float
    gap: float


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
    """World upper/tip rotations and the knee and foot of local poses U, T."""
    q_u = quat_mul(q_seg, U)
    q_t = quat_mul(q_u, T)
    mid = hip + quat_rotate(q_u, l1 * _Y)
    end = mid + quat_rotate(q_t, l2 * _Y)
    return q_u, q_t, mid, end


def _swivel(U, T, angle, l1, l2):
    """Upper-bone local rotations U (n, 4) turned by `angle` (n,) about the hip -> foot line
    (segment frame): the knee swings round, the foot stays."""
    foot = quat_rotate(U, l1 * _Y) + quat_rotate(quat_mul(U, T), l2 * _Y)
    axis = foot / np.maximum(np.linalg.norm(foot, axis=-1, keepdims=True), 1e-12)
    return quat_mul(quat_about(axis, angle), U)


def _faults(rays, lim: Limits, hip, q_seg, U, T, l1, l2, inner, same, near_feet):
    """(n,) float cost per entry of flat swing frames (consecutive entries of one swing are
    consecutive frames; `same[k]`: entries k and k+1 belong to one swing):
    a bone through the environment; an inner frame's foot inside a solid or within `gap` of a
    neighbour's foot
    (near_feet (n, 2, 3), NaN for none); a joint turning more than `turn` to the next entry; a
    foot touching a surface in this and the next entry while it slides more than `slide`. Each
    fault costs 1, a turn TURN_WEIGHT: a joint never turns too fast for a cleaner swing."""
    q_u, q_t, mid, end = _pose(q_seg, hip, U, T, l1, l2)
    bad = rays.first_hit(hip, mid - hip, max_distance=l1 - 1e-9).hit
    bad |= rays.first_hit(mid, end - mid, max_distance=max(l2 - lim.tol, 0.0)).hit
    with np.errstate(invalid="ignore"):
        gap = np.nanmin(np.linalg.norm(near_feet - end[:, None], axis=2), axis=1, initial=np.inf)
    bad |= inner & (gap < lim.gap)
    d = rays.closest(end, lim.contact)[0]
    k = np.nonzero(inner)[0]
    bad[k] |= rays.inside(end[k])
    cost = bad.astype(float)
    if len(U) > 1:
        steps = np.maximum.reduce([quat_angle(x[:-1], x[1:]) for x in (U, T, q_u, q_t)])
        touch = d < lim.contact
        slide = np.linalg.norm(np.diff(end, axis=0), axis=1)
        cost[:-1] += same & touch[:-1] & touch[1:] & (slide > lim.slide)
        cost[:-1] += TURN_WEIGHT * (same & (steps > lim.turn))
    return cost


def joint_space_swings(rays, hip, q_seg, q_u, q_t, mid, end, swing, side, l1, l2, lim: Limits,
                       rounds: int = 2):
    """Swings that break a limit, replaced by joint-space swings (see the module docstring).

    hip   : (F, L, 3) hips; q_seg : (F, L, 4) each leg's segment rotation (world)
    q_u, q_t : (F, L, 4) world rotations of the upper and tip bones (bones along local +Y)
    mid, end : (F, L, 3) the planner's knees and feet
    swing : (F, L) bool, frames in which the foot is not planted
    side  : (L,) +1 left, -1 right; l1, l2 : bone lengths
    Legs are ordered L_01, R_01, L_02, ...: leg l's neighbours on its side are l - 2 and l + 2.
    Neighbours never change in the same pass (legs of odd and even segments take turns,
    `rounds` times), so each one is judged against the other's latest feet.
    returns (q_u, q_t, mid, end), each (F, L, ...)
    """
    U = quat_mul(quat_conj(q_seg), q_u)
    T = quat_mul(quat_conj(q_u), q_t)
    U0 = U.copy()
    leg, a, b = _runs(swing)
    for _ in range(rounds):
        for parity in (0, 1):
            mine = (leg // 2) % 2 == parity
            if mine.any():
                _redo(rays, lim, hip, q_seg, U, T, side, l1, l2, leg[mine], a[mine], b[mine])
    # frames left as planned keep the planner's exact numbers (no round trip through rotations)
    q_u2, q_t2, mid2, end2 = _pose(q_seg, hip, U, T, l1, l2)
    redone = np.any(U != U0, axis=-1)[..., None]
    return (np.where(redone, q_u2, q_u), np.where(redone, q_t2, q_t),
            np.where(redone, mid2, mid), np.where(redone, end2, end))


def _redo(rays, lim, hip, q_seg, U_all, T_all, side, l1, l2, leg, a, b) -> None:
    """Swings (leg, a, b) that break a limit get the best joint-space candidate, in place in
    the local poses U_all, T_all (F, L, 4)."""
    feet = _pose(q_seg, hip, U_all, T_all, l1, l2)[3]
    n_swing = len(leg)
    length = b - a + 1
    sid = np.repeat(np.arange(n_swing), length)
    start = np.repeat(np.cumsum(length) - length, length)
    f = np.repeat(a, length) + (np.arange(len(sid)) - start)
    lg = leg[sid]
    u = (f - a[sid]) / (b - a)[sid]
    inner = (u > 0.0) & (u < 1.0)
    pad = np.full((len(feet), 2, 3), np.nan)
    padded = np.concatenate([pad, feet, pad], axis=1)
    near = np.stack([padded[f, lg], padded[f, lg + 4]], axis=1)        # legs l - 2, l + 2
    qs, hp, U0, T0 = q_seg[f, lg], hip[f, lg], U_all[f, lg], T_all[f, lg]
    bad = _faults(rays, lim, hp, qs, U0, T0, l1, l2, inner, sid[1:] == sid[:-1], near)
    best = np.bincount(sid, weights=bad, minlength=n_swing)
    redo = best > 0
    if not redo.any():
        return
    k = np.nonzero(redo[sid])[0]
    sk = sid[k]
    first, last = start[k], start[k] + length[sk] - 1
    Us, Ts = quat_slerp(U0[first], U0[last], u[k]), quat_slerp(T0[first], T0[last], u[k])
    chosen_U, chosen_T = U0[k].copy(), T0[k].copy()
    axis = np.broadcast_to(_Z, (len(k), 3))
    same = sk[1:] == sk[:-1]
    candidates = [(p, r, 0.0) for p in PROFILES for r in RAISES]
    candidates += [(PROFILES[0], r, sv) for sv in SWIVELS for r in RAISES[::2]]
    for profile, r, swivel in candidates:
        todo = redo & (best > 0)
        if not todo.any():
            break
        U = quat_mul(quat_about(axis, side[lg[k]] * r * profile(u[k])), Us)
        if swivel:
            U = _swivel(U, Ts, swivel * profile(u[k]), l1, l2)
        cost = _faults(rays, lim, hp[k], qs[k], U, Ts, l1, l2, inner[k], same, near[k])
        score = np.bincount(sk, weights=cost, minlength=n_swing)
        take = todo & (score < best)
        best[take] = score[take]
        sel = take[sk]
        chosen_U[sel], chosen_T[sel] = U[sel], Ts[sel]
    inside = inner[k]
    fk, lk = f[k][inside], lg[k][inside]
    U_all[fk, lk] = chosen_U[inside]
    T_all[fk, lk] = chosen_T[inside]
