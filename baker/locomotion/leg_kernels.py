"""Compiled passes of the legs' planning (baker.locomotion.legs) and joint-space swings
(baker.locomotion.swing), with the same bits as the numpy forms they replace
(tests/unit/test_leg_kernels.py compares them):

- `leg_traces`: legs._stance_turns and legs._joint_steps up to their arccos: a leg's
  two-bone IK over frames (ik.two_bone_ik after its soft clamp, which stays in numpy), the
  trace of each bone's frame-to-frame rotation (legs._frame_steps) for its hip -> knee and
  knee -> foot bones in the world and its upper bone in its segment's space, and the cosine
  of its knee angle;

- `arc_pose`: a candidate of the "arc" family (_Trial.pose) from its slerped poses: the leg
  raised about the body's long axis, then the knee swivelled round the hip -> foot line, the
  leg yawed round the hip and the foot tucked in, as the candidate asks;
- `leg_pose`: swing._pose (the world rotations of a leg's two bones, its knee and foot), with
  the dot products of consecutive entries' rotations that swing._turn_faults turns into angles;
- `crowding`: swing._crowding, the cost of swinging feet near their neighbours' feet;
- `PoseRows`: the rows of swing._Answers, poses told apart by the exact bits of their hip,
  knee and foot, in an open-addressing table (each new pose the next row, in order).

Each formula is transforms' arithmetic element by element (geometry.fused's one-element forms:
quat_mul1, quat_rotate1, quat_about1, cross1, normalize1, minimum1, maximum1; dot's products
summed left to right). sin, cos and sqrt are the C library's in both (numpy's float64 sin and
cos give the same bits here; tests check it). The profiles (x ** 0.25), exp and arccos stay
in numpy, whose SIMD forms differ from the C library's in the last bit.

The kernels write into arrays they are given and return nothing: they are called directly on
the main thread once compiled (parallel.compiled_call).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from baker.geometry.fused import (cross1, maximum1, minimum1, normalize1, quat_about1,
                                  quat_mul1, quat_rotate1)
from baker.parallel import compiled_call


def arc_pose(U, T, side, prof, sin_u, cap, r, swivel, yaw, flex, l1, l2):
    """(U, T) (n, 4) local poses of an "arc" candidate (swing._Trial.pose) from the slerped
    poses U, T (n, 4): U turned by side * min(r * prof, cap) about the segment's +Z, then (when
    non-zero) swivelled by swivel * prof (swing._swivel), yawed by side * yaw * sin_u about +Y,
    and T bent by flex * prof (swing._flex). side, prof, sin_u, cap: (n,) float64 (sin_u
    sin(pi u), read only for a yaw; cap inf for none)."""
    n = len(U)
    U_out, T_out = np.empty((n, 4)), np.empty((n, 4))
    compiled_call(_arc_pose, _c(U), _c(T), _c(side), _c(prof), _c(sin_u), _c(cap), float(r),
                  float(swivel), float(yaw), float(flex), float(l1), float(l2), U_out, T_out)
    return U_out, T_out


def leg_pose(q_seg, hip, U, T, l1, l2):
    """(q_u, q_t, mid, end, dots): swing._pose of local poses U, T (n, 4) on segment rotations
    q_seg (n, 4) and hips (n, 3), and dots (4, n - 1): the dot products of consecutive entries'
    U, T, q_u and q_t, in that order (quat_angle's before its arccos)."""
    n = len(U)
    q_u, q_t = np.empty((n, 4)), np.empty((n, 4))
    mid, end = np.empty((n, 3)), np.empty((n, 3))
    dots = np.empty((4, max(n - 1, 0)))
    compiled_call(_leg_pose, _c(q_seg), _c(hip), _c(U), _c(T), float(l1), float(l2), q_u, q_t,
                  mid, end, dots)
    return q_u, q_t, mid, end, dots


def crowding(end, inner, near, gap, breaking_gap, hard):
    """(n,) swing._crowding: inner * ((d < gap) + (hard - 1) * (d < breaking_gap)) with d the
    distance of each foot end (n, 3) to the nearer of its neighbours' feet near (n, 2, 3) (NaN
    for none: np.nanmin with initial inf); inner (n,) bool."""
    out = np.empty(len(end))
    compiled_call(_crowding, _c(end), np.ascontiguousarray(inner, dtype=np.bool_), _c(near),
                  float(gap), float(breaking_gap), float(hard), out)
    return out


class PoseRows:
    """Rows of poses, each told apart by its 9 float64 words' bits (hip, knee, foot): a pose
    asked about again gets its first row; new poses get the next rows, in the order asked.

    key : (capacity, 9) uint64, the rows' poses (the first `n` rows in use)"""

    def __init__(self):
        self.key = np.zeros((0, 9), np.uint64)
        self.n = 0
        self._table = np.full(16, -1, np.int64)     # slot -> row, -1 empty (a power of 2)
        self._count = np.zeros(1, np.int64)

    def rows(self, hip, mid, end) -> np.ndarray:
        """(m,) int64 the rows of poses hip -> mid -> end (each (m, 3) float64)."""
        key = np.ascontiguousarray(np.concatenate([hip, mid, end], axis=1),
                                   dtype=np.float64).view(np.uint64)
        m = len(key)
        if self.n + m > len(self.key):
            self.key = np.resize(self.key, (max(2 * len(self.key), self.n + m, 1024), 9))
        if 2 * (self.n + m) > len(self._table):       # at most half full
            size = len(self._table)
            while 2 * (self.n + m) > size:
                size *= 4
            self._table = np.full(size, -1, np.int64)
            compiled_call(_rehash, self.key, self.n, self._table)
        out = np.empty(m, np.int64)
        self._count[0] = self.n
        compiled_call(_pose_rows, key, self.key, self._count, self._table, out)
        self.n = int(self._count[0])
        return out


def leg_traces(hip, target, fwd, left, q_inv, side, knee_out, l1, l2, d):
    """(tr (W - 1, 3, n), knee (n, W)) of legs reaching for target over W frames (each row a
    leg, as legs._stance_turns and legs._joint_steps solve them): tr, legs._frame_steps'
    traces (the sum of the dot products of consecutive frames' bone axes x, y, z) of the bones
    hip -> knee, knee -> foot (world) and the upper bone in its segment's space (q_inv); knee,
    the cosine of the knee angle in the segment's space (the upper bone's direction dotted with
    the tip bone's) before its clip and arccos. hip, target, fwd, left (n, W, 3), q_inv (n, W,
    4), side (n,) +1 left, -1 right; d (n, W) the soft-clamped reach (ik.soft_clamp of
    |target - hip|); the knee bends toward side * cross(fwd, u) + knee_out * side * left
    (rig.limbs.leg_pole)."""
    n, W = hip.shape[:2]
    tr = np.empty((max(W - 1, 0), 3, n))
    knee = np.empty((n, W))
    compiled_call(_leg_traces, _c(hip), _c(target), _c(fwd), _c(left), _c(q_inv), _c(side),
                  float(knee_out), float(l1), float(l2), _c(d), tr, knee)
    return tr, knee


def _c(a) -> np.ndarray:
    """a as a C-contiguous float64 array (itself when it is one)."""
    return np.ascontiguousarray(a, dtype=np.float64)


_OPTS = dict(cache=True, nogil=True, error_model="numpy")


@njit(**_OPTS)
def _foot_length(ux, uy, uz, uw, tx, ty, tz, tw, k0, k1, k2, l2):
    """|knee k + the tip bone (length l2) of the leg U, T|: the lengths swing._flex compares."""
    q = quat_mul1(ux, uy, uz, uw, tx, ty, tz, tw)
    f = quat_rotate1(q[0], q[1], q[2], q[3], 0.0, l2, 0.0)
    f0, f1, f2 = k0 + f[0], k1 + f[1], k2 + f[2]
    return math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)


@njit(**_OPTS)
def _arc_pose(U, T, side, prof, sin_u, cap, r, swivel, yaw, flex, l1, l2, U_out, T_out):
    for i in range(U.shape[0]):
        s = side[i]
        a = quat_about1(0.0, 0.0, 1.0, s * minimum1(r * prof[i], cap[i]))
        u = quat_mul1(a[0], a[1], a[2], a[3], U[i, 0], U[i, 1], U[i, 2], U[i, 3])
        t = (T[i, 0], T[i, 1], T[i, 2], T[i, 3])
        if swivel != 0.0:                   # swing._swivel
            k = quat_rotate1(u[0], u[1], u[2], u[3], 0.0, l1, 0.0)
            ut = quat_mul1(u[0], u[1], u[2], u[3], t[0], t[1], t[2], t[3])
            e = quat_rotate1(ut[0], ut[1], ut[2], ut[3], 0.0, l2, 0.0)
            f0, f1, f2 = k[0] + e[0], k[1] + e[1], k[2] + e[2]
            d = maximum1(math.sqrt(f0 * f0 + f1 * f1 + f2 * f2), 1e-12)
            a = quat_about1(f0 / d, f1 / d, f2 / d, swivel * prof[i])
            u = quat_mul1(a[0], a[1], a[2], a[3], u[0], u[1], u[2], u[3])
        if yaw != 0.0:
            a = quat_about1(0.0, 1.0, 0.0, s * yaw * sin_u[i])
            u = quat_mul1(a[0], a[1], a[2], a[3], u[0], u[1], u[2], u[3])
        if flex != 0.0:                     # swing._flex
            k = quat_rotate1(u[0], u[1], u[2], u[3], 0.0, l1, 0.0)
            angle = flex * prof[i]
            a = quat_about1(1.0, 0.0, 0.0, 1.0 * angle)
            t_in = quat_mul1(a[0], a[1], a[2], a[3], t[0], t[1], t[2], t[3])
            a = quat_about1(1.0, 0.0, 0.0, -1.0 * angle)
            t_out = quat_mul1(a[0], a[1], a[2], a[3], t[0], t[1], t[2], t[3])
            n_in = _foot_length(u[0], u[1], u[2], u[3], t_in[0], t_in[1], t_in[2], t_in[3],
                                k[0], k[1], k[2], l2)
            n_out = _foot_length(u[0], u[1], u[2], u[3], t_out[0], t_out[1], t_out[2],
                                 t_out[3], k[0], k[1], k[2], l2)
            t = t_in if n_in <= n_out else t_out
        for c in range(4):
            U_out[i, c] = u[c]
            T_out[i, c] = t[c]


@njit(**_OPTS)
def _leg_pose(q_seg, hip, U, T, l1, l2, q_u, q_t, mid, end, dots):
    n = U.shape[0]
    for i in range(n):
        u = quat_mul1(q_seg[i, 0], q_seg[i, 1], q_seg[i, 2], q_seg[i, 3],
                  U[i, 0], U[i, 1], U[i, 2], U[i, 3])
        t = quat_mul1(u[0], u[1], u[2], u[3], T[i, 0], T[i, 1], T[i, 2], T[i, 3])
        k = quat_rotate1(u[0], u[1], u[2], u[3], 0.0, l1, 0.0)
        m0, m1, m2 = hip[i, 0] + k[0], hip[i, 1] + k[1], hip[i, 2] + k[2]
        e = quat_rotate1(t[0], t[1], t[2], t[3], 0.0, l2, 0.0)
        for c in range(4):
            q_u[i, c] = u[c]
            q_t[i, c] = t[c]
        mid[i, 0], mid[i, 1], mid[i, 2] = m0, m1, m2
        end[i, 0], end[i, 1], end[i, 2] = m0 + e[0], m1 + e[1], m2 + e[2]
    for i in range(n - 1):
        dots[0, i] = _dot4(U, i)
        dots[1, i] = _dot4(T, i)
        dots[2, i] = _dot4(q_u, i)
        dots[3, i] = _dot4(q_t, i)


@njit(**_OPTS)
def _dot4(x, i):
    """transforms.dot of rows i and i + 1 of x (n, 4)."""
    d = x[i, 0] * x[i + 1, 0]
    d += x[i, 1] * x[i + 1, 1]
    d += x[i, 2] * x[i + 1, 2]
    d += x[i, 3] * x[i + 1, 3]
    return d


@njit(**_OPTS)
def _crowding(end, inner, near, gap, breaking_gap, hard, out):
    for i in range(end.shape[0]):
        d = np.inf
        for k in range(near.shape[1]):
            x = near[i, k, 0] - end[i, 0]
            y = near[i, k, 1] - end[i, 1]
            z = near[i, k, 2] - end[i, 2]
            v = math.sqrt(x * x + y * y + z * z)
            if v < d:                       # NaN (no neighbour) never is
                d = v
        near_miss = 1.0 if d < gap else 0.0
        breaks = 1.0 if d < breaking_gap else 0.0
        out[i] = (1.0 if inner[i] else 0.0) * (near_miss + (hard - 1.0) * breaks)


_FNV_START = np.uint64(0xCBF29CE484222325)
_FNV_PRIME = np.uint64(0x100000001B3)


@njit(**_OPTS)
def _slot(key, i, mask):
    """The first table slot of row i of key (n, 9) uint64: FNV-1a over its 9 words."""
    h = _FNV_START
    for c in range(9):
        h = (h ^ key[i, c]) * _FNV_PRIME
    return np.int64(h & np.uint64(mask))


@njit(**_OPTS)
def _rehash(store, n, table):
    mask = len(table) - 1
    for r in range(n):
        slot = _slot(store, r, mask)
        while table[slot] >= 0:
            slot = (slot + 1) & mask
        table[slot] = r


@njit(**_OPTS)
def _pose_rows(key, store, count, table, out):
    mask = len(table) - 1
    n = count[0]
    for i in range(key.shape[0]):
        slot = _slot(key, i, mask)
        while True:
            r = table[slot]
            if r < 0:                       # a new pose: the next row
                for c in range(9):
                    store[n, c] = key[i, c]
                table[slot] = n
                out[i] = n
                n += 1
                break
            same = True
            for c in range(9):
                if store[r, c] != key[i, c]:
                    same = False
                    break
            if same:
                out[i] = r
                break
            slot = (slot + 1) & mask
    count[0] = n


@njit(**_OPTS)
def _bone_axes(a0, a1, a2, b0, b1, b2, h0, h1, h2, out, k):
    """legs._frame_steps' axes of the bone a -> b with hinge h: y along it, x the hinge made
    orthogonal, z = x cross y, into out[k:k + 9] (x, y, z)."""
    y = normalize1(b0 - a0, b1 - a1, b2 - a2)
    dh = h0 * y[0] + h1 * y[1] + h2 * y[2]
    x = normalize1(h0 - dh * y[0], h1 - dh * y[1], h2 - dh * y[2])
    z = cross1(x[0], x[1], x[2], y[0], y[1], y[2])
    out[k], out[k + 1], out[k + 2] = x
    out[k + 3], out[k + 4], out[k + 5] = y
    out[k + 6], out[k + 7], out[k + 8] = z


@njit(**_OPTS)
def _leg_traces(hip, target, fwd, left, q_inv, side, knee_out, l1, l2, d_all, tr, knee):
    n, W = hip.shape[0], hip.shape[1]
    ll = l1 * l1 - l2 * l2
    axes = np.empty((2, 27))                # this frame's and the previous frame's bone axes
    for i in range(n):
        s = side[i]
        for f in range(W):
            t0, t1, t2 = target[i, f, 0], target[i, f, 1], target[i, f, 2]
            r0, r1, r2 = hip[i, f, 0], hip[i, f, 1], hip[i, f, 2]
            v0, v1, v2 = t0 - r0, t1 - r1, t2 - r2
            u = normalize1(v0, v1, v2)      # the pole's; the IK's too, the foot off the hip
            c = cross1(fwd[i, f, 0], fwd[i, f, 1], fwd[i, f, 2], u[0], u[1], u[2])
            ks = knee_out * s
            p0 = s * c[0] + ks * left[i, f, 0]
            p1 = s * c[1] + ks * left[i, f, 1]
            p2 = s * c[2] + ks * left[i, f, 2]
            # ik.two_bone_ik, element by element
            if not math.sqrt(v0 * v0 + v1 * v1 + v2 * v2) > 1e-12:
                a = cross1(p0, p1, p2, 0.0, 0.0, 1.0)
                u = normalize1(a[0] + 1e-9, a[1] + 1e-9, a[2] + 1e-9)
            d = d_all[i, f]
            dp = p0 * u[0] + p1 * u[1] + p2 * u[2]
            w0, w1, w2 = p0 - dp * u[0], p1 - dp * u[1], p2 - dp * u[2]
            wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if wn > 1e-9:
                m = maximum1(wn, 1e-300)
                w0, w1, w2 = w0 / m, w1 / m, w2 / m
            else:
                if abs(u[1]) < 0.9:
                    a = cross1(u[0], u[1], u[2], 0.0, 1.0, 0.0)
                else:
                    a = cross1(u[0], u[1], u[2], 1.0, 0.0, 0.0)
                w0, w1, w2 = normalize1(a[0], a[1], a[2])
            a_ = (ll + d * d) / (2.0 * d)
            h = math.sqrt(maximum1(l1 * l1 - a_ * a_, 0.0))
            m0 = (r0 + a_ * u[0]) + h * w0
            m1 = (r1 + a_ * u[1]) + h * w1
            m2 = (r2 + a_ * u[2]) + h * w2
            e = normalize1((r0 + d * u[0]) - m0, (r1 + d * u[1]) - m1, (r2 + d * u[2]) - m2)
            e0, e1, e2 = m0 + e[0] * l2, m1 + e[1] * l2, m2 + e[2] * l2
            g = cross1(u[0], u[1], u[2], w0, w1, w2)                    # the hinge
            qx, qy, qz, qw = q_inv[i, f, 0], q_inv[i, f, 1], q_inv[i, f, 2], q_inv[i, f, 3]
            lm = quat_rotate1(qx, qy, qz, qw, m0 - r0, m1 - r1, m2 - r2)
            lg = quat_rotate1(qx, qy, qz, qw, g[0], g[1], g[2])
            le = quat_rotate1(qx, qy, qz, qw, e0 - r0, e1 - r1, e2 - r2)
            y = normalize1(lm[0], lm[1], lm[2])
            k = normalize1(le[0] - lm[0], le[1] - lm[1], le[2] - lm[2])
            knee[i, f] = (y[0] * k[0] + y[1] * k[1]) + y[2] * k[2]
            cur = axes[f % 2]
            _bone_axes(r0, r1, r2, m0, m1, m2, g[0], g[1], g[2], cur, 0)
            _bone_axes(m0, m1, m2, e0, e1, e2, g[0], g[1], g[2], cur, 9)
            _bone_axes(0.0, 0.0, 0.0, lm[0], lm[1], lm[2], lg[0], lg[1], lg[2], cur, 18)
            if f > 0:
                prev = axes[(f - 1) % 2]
                for b in range(3):
                    t = 0.0
                    for v in range(3):
                        k = 9 * b + 3 * v
                        t = t + ((cur[k] * prev[k] + cur[k + 1] * prev[k + 1])
                                 + cur[k + 2] * prev[k + 2])
                    tr[f - 1, b, i] = t
