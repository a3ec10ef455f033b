"""Joint-space swings: the fallback for swings whose foot-space path breaks a limit.

legs.py plans each swing as a foot path (an arc around the hip, lifted, then pushed off walls,
raised over obstacles, re-timed) and solves it with two-bone IK. Near walls, on stairs and in
tight turns those corrections can fight each other: the leg then turns too far in one frame,
a bone passes through something, or the foot ends up in or on a surface while it moves.

Such a swing is replaced by one in the leg's own joint space: the upper bone's rotation
(relative to its segment) and the tip bone's (relative to the upper bone) slerp from the last
planted pose to the touchdown pose, at an even pace, while the whole leg is raised about the
body's long axis (through the hip) by a bump raise * sin(pi u). Of the RAISES, the smallest that
keeps every frame of the swing within all limits wins; when none does, the one with the fewest
offending frames. Both ends of the swing are the planted poses, so the stance is untouched.
All swings, candidates and frames are checked in flat batches (one ray batch per candidate).
"""

from __future__ import annotations

import numpy as np

from baker.geometry.proximity import closest_on_mesh
from baker.geometry.transforms import (quat_about, quat_angle, quat_conj, quat_mul, quat_rotate,
                                       quat_slerp)

#: raises of the whole leg about the body's long axis tried, smallest first [rad]
RAISES = np.radians([0.0, 8.0, 16.0, 25.0, 35.0, 50.0, 65.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


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
    """World upper/tip rotations and the knee and foot of local poses U, T (flat (n, 4))."""
    q_u = quat_mul(q_seg, U)
    q_t = quat_mul(q_u, T)
    mid = hip + quat_rotate(q_u, l1 * _Y)
    end = mid + quat_rotate(q_t, l2 * _Y)
    return q_u, q_t, mid, end


def _frame_faults(rays, hip, mid, end, moving, l1, l2, clear, reach, tol):
    """(n,) bool: a bone passes through the environment, or a moving foot is within `clear`
    of a surface or behind one (inside a solid: on the far side of the nearest face from the
    hip)."""
    a = rays.first_hit(hip, mid - hip, max_distance=l1 - 1e-9).hit
    b = rays.first_hit(mid, end - mid, max_distance=max(l2 - tol, 0.0)).hit
    bad = a | b
    k = np.nonzero(moving)[0]
    if len(k):
        d, c, tri = closest_on_mesh(end[k], rays.vertices, rays.faces, max(reach, clear))
        found = np.isfinite(d)
        n = np.zeros((len(k), 3))
        n[found] = rays.face_normals[tri[found]]
        toward = np.sum(n * (hip[k] - np.where(found[:, None], c, 0.0)), -1) < 0.0
        n[toward] *= -1.0
        behind = found & (np.sum((end[k] - np.where(found[:, None], c, 0.0)) * n, -1) < 0.0)
        bad[k] |= behind | (d < clear * (1.0 - 1e-3))
    return bad


def _step_faults(q_seg, q_u, q_t, U, T, same, limit):
    """(n,) bool: entry k turns a joint by more than `limit` [rad] between it and entry k+1
    (only where `same`: both entries belong to one swing), in the joint's own space or in the
    world."""
    out = np.zeros(len(U), bool)
    if len(U) < 2:
        return out
    steps = np.maximum.reduce([quat_angle(x[:-1], x[1:]) for x in (U, T, q_u, q_t)])
    out[:-1] = same & (steps > limit)
    return out


def joint_space_swings(rays, hip, q_seg, q_u, q_t, swing, side, l1, l2, *, clear, reach, tol,
                       limit):
    """Swings that break a limit, replaced by joint-space swings (see the module docstring).

    hip   : (F, L, 3) hips; q_seg : (F, L, 4) each leg's segment rotation (world)
    q_u, q_t : (F, L, 4) world rotations of the upper and tip bones (bones along local +Y)
    swing : (F, L) bool, frames in which the foot is not planted
    side  : (L,) +1 left, -1 right; l1, l2 : bone lengths
    clear : a moving foot stays this far from every surface; reach : how far to look for the
            surface a foot might be behind; tol : the foot's last bit that may touch
    limit : largest turn of any joint per frame [rad], local and world
    returns (q_u, q_t, mid, end), each (F, L, ...)
    """
    q_u, q_t = q_u.copy(), q_t.copy()
    leg, a, b = _runs(swing)
    n_swing = len(leg)
    if n_swing == 0:
        return (q_u, q_t) + _pose(q_seg, hip, quat_mul(quat_conj(q_seg), q_u),
                                  quat_mul(quat_conj(q_u), q_t), l1, l2)[2:]
    length = b - a + 1
    sid = np.repeat(np.arange(n_swing), length)
    start = np.repeat(np.cumsum(length) - length, length)
    f = np.repeat(a, length) + (np.arange(len(sid)) - start)
    lg = leg[sid]
    u = (f - a[sid]) / (b - a)[sid]
    same = sid[1:] == sid[:-1]
    inner = (u > 0.0) & (u < 1.0)
    qs, hp = q_seg[f, lg], hip[f, lg]
    U0 = quat_mul(quat_conj(qs), q_u[f, lg])
    T0 = quat_mul(quat_conj(q_u[f, lg]), q_t[f, lg])
    _, _, mid0, end0 = _pose(qs, hp, U0, T0, l1, l2)
    moving0 = inner & (np.linalg.norm(end0 - end0[start], axis=1) > 1e-6 * l2) & (
        np.linalg.norm(end0 - end0[start + length[sid] - 1], axis=1) > 1e-6 * l2)
    bad = _frame_faults(rays, hp, mid0, end0, moving0, l1, l2, clear, reach, tol)
    bad |= _step_faults(qs, q_u[f, lg], q_t[f, lg], U0, T0, same, limit)
    redo = np.bincount(sid, weights=bad, minlength=n_swing) > 0
    if not redo.any():
        return (q_u, q_t) + _pose(q_seg, hip, quat_mul(quat_conj(q_seg), q_u),
                                  quat_mul(quat_conj(q_u), q_t), l1, l2)[2:]
    # candidates for the swings to redo, all at once
    k = np.nonzero(redo[sid])[0]
    sk = sid[k]
    Ua, Ub = U0[start[k]], U0[start[k] + length[sk] - 1]
    Ta, Tb = T0[start[k]], T0[start[k] + length[sk] - 1]
    Us, Ts = quat_slerp(Ua, Ub, u[k]), quat_slerp(Ta, Tb, u[k])
    # the planned swing stays unless a candidate has fewer offending frames
    best_score = np.where(redo, np.bincount(sid, weights=bad, minlength=n_swing), 0.0)
    chosen_U, chosen_T = U0[k].copy(), T0[k].copy()
    axis = np.broadcast_to(_Z, (len(k), 3))
    for r in RAISES:
        lift = quat_about(axis, side[lg[k]] * r * np.sin(np.pi * u[k]))
        U = quat_mul(lift, Us)
        q1, q2, m1, e1 = _pose(qs[k], hp[k], U, Ts, l1, l2)
        faults = _frame_faults(rays, hp[k], m1, e1, inner[k], l1, l2, clear, reach, tol)
        faults |= _step_faults(qs[k], q1, q2, U, Ts, sk[1:] == sk[:-1], limit)
        score = np.bincount(sk, weights=faults, minlength=n_swing)
        take = redo & (score < best_score)
        best_score[take] = score[take]
        sel = take[sk]
        chosen_U[sel], chosen_T[sel] = U[sel], Ts[sel]
        if not (redo & (best_score > 0)).any():
            break
    inside = inner[k]
    fk, lk = f[k][inside], lg[k][inside]
    q_u[fk, lk] = quat_mul(q_seg[fk, lk], chosen_U[inside])
    q_t[fk, lk] = quat_mul(q_u[fk, lk], chosen_T[inside])
    U_all = quat_mul(quat_conj(q_seg), q_u)
    T_all = quat_mul(quat_conj(q_u), q_t)
    _, _, mid, end = _pose(q_seg, hip, U_all, T_all, l1, l2)
    return q_u, q_t, mid, end
