"""Quaternion (xyzw) and frame helpers, vectorized over leading axes.

scipy's Rotation is imported where it is used: baker.config imports this module, and the CLI's
option errors come before scipy is imported (issue 15)."""

import functools
import math

import numpy as np


def normalize(v: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """Unit vectors along the last axis. Zero vectors stay zero.

    v : (..., n) float
    """
    v = np.asarray(v)
    if v.dtype == np.float64 and v.shape[-1:] in ((3,), (4,)):
        n = np.sqrt(dot(v, v))[..., None]      # np.linalg.norm's bits (see dot)
    else:
        n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) np.sum(a * b, axis=-1): for float64 3- and 4-vectors the products summed left to
    right, as numpy sums a 3- or 4-long last axis (the same bits; np.linalg.norm sums the
    squares so too), without its reduction's cost (several times the products')."""
    p = np.multiply(a, b)
    if p.dtype != np.float64 or p.shape[-1:] not in ((3,), (4,)):
        return np.sum(p, axis=-1)
    out = np.add(p[..., 0], p[..., 1])
    for k in range(2, p.shape[-1]):
        out += p[..., k]
    return out


def length(v: np.ndarray) -> np.ndarray:
    """(...) np.linalg.norm(v, axis=-1): for float64 vectors the square root of dot(v, v), the
    same bits without the reduction's cost."""
    v = np.asarray(v)
    return np.sqrt(dot(v, v)) if v.dtype == np.float64 else np.linalg.norm(v, axis=-1)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of 3-vectors (..., 3), broadcast: np.cross's arithmetic (the same bits)
    without its axis handling, which costs more than the products on small batches; each
    component is written into the result in place (no stacking: several times faster on
    large batches)."""
    a = _float64(a)
    b = _float64(b)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    o = np.multiply(a1, b2, out=out[..., 0])
    o -= a2 * b1
    o = np.multiply(a2, b0, out=out[..., 1])
    o -= a0 * b2
    o = np.multiply(a0, b1, out=out[..., 2])
    o -= a1 * b0
    return out


def _float64(a) -> np.ndarray:
    """np.asarray(a, dtype=np.float64), without its call for what already is one."""
    return a if type(a) is np.ndarray and a.dtype == np.float64 else np.asarray(a, np.float64)


def frames_to_quat(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Rotations that map the rest frame (+Z forward, +Y up) onto the given frame.

    forward : (..., 3) float, need not be unit
    up      : (..., 3) float, approximate up; made orthogonal to forward
    returns : (..., 4) float, xyzw unit quaternions
    """
    f = normalize(forward)
    left = normalize(np.cross(up, f))
    u = np.cross(f, left)
    m = np.stack([left, u, f], axis=-1)  # columns: images of X, Y, Z
    return frame_quats(m)


@functools.lru_cache(maxsize=1)
def _takes_assume_valid() -> bool:
    """Whether this scipy's Rotation.from_matrix takes `assume_valid` (its newer releases)."""
    import inspect

    from scipy.spatial.transform import Rotation

    return "assume_valid" in inspect.signature(Rotation.from_matrix).parameters


#: frame_quats converts a matrix without scipy's validation when no entry of M M^T differs from
#: the identity's by this much (scipy orthogonalizes a matrix only beyond 1e-12)
ORTHONORMAL = 1e-14


def frame_quats(m: np.ndarray) -> np.ndarray:
    """(..., 4) xyzw quaternions of rotation matrices m (..., 3, 3) (Rotation.from_matrix).

    scipy validates each matrix (a determinant, and M M^T against the identity: the matrices
    off by more than 1e-12 are orthogonalized first), which costs about 20 times the
    conversion. The frames made here (unit columns, orthogonal by construction) are mostly
    orthonormal to a few ulps: those within ORTHONORMAL of it are converted without the
    validation, which leaves them as they are (the same bits); the others (a frame made from
    nearly parallel vectors, a zero column, NaN) go through the validated call, which decides
    as before (a ValueError for a zero determinant)."""
    from scipy.spatial.transform import Rotation

    shape = m.shape[:-2]
    flat = np.asarray(m, dtype=np.float64).reshape(-1, 3, 3)
    if len(flat) == 0 or not _takes_assume_valid():
        return Rotation.from_matrix(flat).as_quat().reshape(*shape, 4)
    off = flat @ np.swapaxes(flat, -1, -2)
    off[:, _DIAG, _DIAG] -= 1.0
    with np.errstate(invalid="ignore"):
        ok = np.abs(off).max(axis=(1, 2)) < ORTHONORMAL       # NaN: not ok
    if ok.all():
        q = Rotation.from_matrix(flat, assume_valid=True).as_quat()
    else:
        q = np.empty((len(flat), 4))
        if ok.any():
            q[ok] = Rotation.from_matrix(flat[ok], assume_valid=True).as_quat()
        q[~ok] = Rotation.from_matrix(flat[~ok]).as_quat()
    return q.reshape(*shape, 4)


_DIAG = np.arange(3)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a*b of xyzw quaternions, broadcast over leading axes (each component
    written into the result in place, not stacked)."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    same = a.shape == b.shape and a.dtype == b.dtype
    out = np.empty(a.shape if same else np.broadcast_shapes(a.shape, b.shape),
                   dtype=a.dtype if same else np.result_type(a, b))
    # each sum left to right, accumulated in its column of the result
    o = np.multiply(aw, bx, out=out[..., 0])
    o += ax * bw
    o += ay * bz
    o -= az * by
    o = np.multiply(aw, by, out=out[..., 1])
    o -= ax * bz
    o += ay * bw
    o += az * bx
    o = np.multiply(aw, bz, out=out[..., 2])
    o += ax * by
    o -= ay * bx
    o += az * bw
    o = np.multiply(aw, bw, out=out[..., 3])
    o -= ax * bx
    o -= ay * by
    o -= az * bz
    return out


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse for unit quaternions), xyzw."""
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle [rad] of the rotation between unit xyzw quaternions a and b (..., 4)."""
    d = np.abs(dot(a, b))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def limit_rotation(q: np.ndarray, max_angle: float,
                   parent: np.ndarray | None = None) -> np.ndarray:
    """Unit quaternions (F, 4) that follow `q` but turn at most `max_angle` radians a frame:
    where q turns faster, each frame slerps from the previous output toward q's by the most
    it may. Frames are processed one by one only from the first too-fast turn until the output
    has caught up again; elsewhere the output is q itself.

    parent : optional (F, 4) rotations of the joint ahead in a chain, themselves turning at
    most `max_angle` a frame: the output then turns at most `max_angle` a frame relative to
    them too. Where the slerped rotation turns too far against the parent, a frame's output is
    the rotation nearest q's, within both limits, on the arc toward q's from the midpoint
    between the previous output and the previous output carried along by the parent's turn."""
    F = len(q)
    if F < 2:
        return q
    fast = quat_angle(q[:-1], q[1:]) > max_angle
    if parent is not None:
        carry = quat_mul(parent[1:], quat_conj(parent[:-1]))     # the parent's turn a frame
        local = quat_mul(quat_conj(parent), q)
        fast |= quat_angle(local[:-1], local[1:]) > max_angle
    fast = np.flatnonzero(fast)
    if len(fast) == 0:
        return q
    out = q.copy()
    f = int(fast[0]) + 1
    while f < F:
        prev = out[f - 1]
        carried = None if parent is None else quat_mul(carry[f - 1], prev)
        a = float(quat_angle(prev, q[f]))
        if a <= max_angle and (carried is None
                               or float(quat_angle(carried, q[f])) <= max_angle):
            nxt = fast[fast >= f]
            if len(nxt) == 0:
                break
            f = max(f + 1, int(nxt[0]) + 1)
            continue
        out[f] = quat_slerp(prev, q[f], min(max_angle / max(a, 1e-12), 1.0))
        if carried is not None and float(quat_angle(carried, out[f])) > max_angle:
            out[f] = _nearest_within(prev, carried, q[f], max_angle)
        f += 1
    return out


#: the fractions of the way from the feasible midpoint toward the wanted rotation that
#: limit_rotation tries at once in a chain (the last it may take is kept)
_CHAIN_STEPS = np.linspace(0.0, 1.0, 257)


def _nearest_within(a: np.ndarray, b: np.ndarray, want: np.ndarray, max_angle: float):
    """The rotation within `max_angle` of both unit quaternions a and b (4,), no more than
    `max_angle` apart, that lies furthest toward `want` on the arc from their midpoint."""
    mid = quat_slerp(a, b, 0.5)
    tries = quat_slerp(np.broadcast_to(mid, (len(_CHAIN_STEPS), 4)), want, _CHAIN_STEPS)
    ok = np.flatnonzero((quat_angle(tries, a) <= max_angle) & (quat_angle(tries, b) <= max_angle))
    return tries[ok[-1]] if len(ok) else mid


def quat_slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation from unit quaternions a to b (..., 4) at t (...), the short way
    round; nearly equal rotations fall back to a normalized lerp."""
    d = dot(a, b)
    b = np.where((d < 0.0)[..., None], -b, b)
    d = np.abs(d)
    t = np.asarray(t, dtype=np.float64)[..., None]
    theta = np.arccos(np.clip(d, 0.0, 1.0))[..., None]
    s = np.sin(theta)
    small = s < 1e-6
    wa = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / np.where(small, 1.0, s))
    wb = np.where(small, t, np.sin(t * theta) / np.where(small, 1.0, s))
    return normalize(wa * a + wb * b)


def quat_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit xyzw quaternions of rotations by `angle` [rad] (...) about unit `axis` (..., 3)."""
    h = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    return np.concatenate([np.asarray(axis, dtype=np.float64) * np.sin(h), np.cos(h)], axis=-1)


#: quat_rotate's batches of at least this many vectors are rotated in one compiled pass
#: (geometry.fused, the same bits)
FUSED_ROTATE = 64


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4), xyzw."""
    sq, sv = np.shape(q)[:-1], np.shape(v)[:-1]
    shape = sq if sq == sv else np.broadcast_shapes(sq, sv)
    if math.prod(shape) >= FUSED_ROTATE:
        from baker.geometry import fused

        return fused.quat_rotate(np.asarray(q), np.asarray(v), shape)
    qv = q[..., :3]
    w = q[..., 3:4]
    t = cross(qv, v)
    t *= 2.0
    out = w * t                 # v + w * t + cross(qv, t), summed in that order in place
    if np.shape(v) == out.shape or np.broadcast_shapes(np.shape(v), out.shape) == out.shape:
        out = np.add(v, out, out=out)
    else:
        out = v + out
    out += cross(qv, t)
    return out


def make_sign_continuous(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip quaternion signs so consecutive keys along `axis` have a non-negative dot product.

    q : (F, ..., 4) quaternions; returns a copy.
    """
    q = np.moveaxis(np.array(q, copy=True), axis, 0)
    for i in range(1, q.shape[0]):
        d = np.sum(q[i] * q[i - 1], axis=-1)
        q[i][d < 0] *= -1.0
    return np.moveaxis(q, 0, axis)


def trs_to_matrix(t: np.ndarray, q: np.ndarray, s: np.ndarray | None = None) -> np.ndarray:
    """4x4 matrices (row-major, column vectors) from translation, xyzw rotation, scale.

    t : (..., 3), q : (..., 4), s : (..., 3) or None -> (..., 4, 4)
    """
    shape = t.shape[:-1]
    from scipy.spatial.transform import Rotation

    r = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(*shape, 3, 3)
    if s is not None:
        r = r * s[..., None, :]
    m = np.zeros(shape + (4, 4))
    m[..., :3, :3] = r
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def light_rotation(direction_to_sun: np.ndarray) -> np.ndarray:
    """xyzw rotations whose local -Z points along the light (= -direction_to_sun).

    direction_to_sun : (..., 3) -> (..., 4)
    """
    d = normalize(np.asarray(direction_to_sun, dtype=np.float64))
    up = np.where(np.abs(d[..., 1:2]) < 0.999, np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    q = frames_to_quat(d, up)      # maps +Z onto the sun direction, so -Z onto the light
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def direction_from_angles(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Unit vectors toward the sun. Azimuth is measured from +Z toward +X, elevation from the
    horizon, both in radians. Shapes broadcast; returns (..., 3)."""
    az, el = np.broadcast_arrays(np.asarray(azimuth, float), np.asarray(elevation, float))
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)
