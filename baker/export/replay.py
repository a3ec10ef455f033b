"""The reduction player's per-pair arithmetic, compiled with numba (baker.export.reduce._Player).

`play_levels` replays the skeleton joint by joint, parents first, over the (joint, frame) pairs
that can change since the last play (one call a play: the per-level numpy masks and calls cost
as much as the arithmetic did):

- `_keys_of`: the compensated key values (targets) at the key frames to redo;
- `_samples_of` (`_lerp`, `_rotation`): the local values the players play between the stored
  keys: the lerped translation and the slerped rotation (three.js's slerp, rounded to float32
  as the files hold them), and Blender's nlerp of the rotation (component-wise lerp,
  normalized);
- `_poses_of` (`_place`): the world poses as the three players pose them (raw matrices of the
  stored quaternions; a renormalized slerp; Blender's nlerp) from the parents' poses, and the
  errors against the unreduced world positions.

`targets_level` (the key values of the other frames, once at the end) and `blame_moves` (any
pairs, for the blame) share the targets' arithmetic. The refinement's blame (`blame_slots`,
`blame_moves`, `blame_pairs`: reduce._blame) and the unreduced clip's world poses
(`unreduced`: rig.skeleton.forward_kinematics, joints first) are compiled here too.

Each pair is computed on its own with the arithmetic of the numpy kernels it replaces
(baker.export.reduce: `_raw_matrix`, `_slerp`; geometry.transforms: quat_mul, quat_rotate;
sums left to right, or in np.einsum's order where it summed), so a replay of some pairs gives
what a fresh playback of all of them gives. The arrays are the player's, joints first
((J, F, W), matrices (J, F, 3, 3)): a pair's components share a cache line or two, where
component-first arrays had the kernels read and write some forty streams at once (about twice
as slow); the kernels write into them and return nothing, and run on the main
thread once compiled (parallel.compiled_call: thousands of short calls a bake).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from baker.geometry.fused import quat_mul1, quat_rotate1
from baker.parallel import compiled_call

#: a rotation segment whose keys' |dot| reaches this is lerped and normalized (three.js)
NEAR_DOT = 0.9995


def play_levels(x, p, keep_t, keep_r, new_t, new_r, dirty_t, dirty_r, first: bool, moved,
                turned) -> None:
    """One play of the player p (reduce._Player.play) down the skeleton, joint by joint, parents
    first, at the pairs that can change: key values (targets) at the key frames keep_t, keep_r
    (J, F) bool that are new (new_t, new_r) or whose parent moved (or only turned, for
    rotations); the local values played at the frames whose segment changed (dirty_t, dirty_r)
    or starts or ends on a key whose stored value changed (bit for bit); the world poses where
    either changed or the parent's did. Into moved, turned (J, F) bool (zeros on entry): the
    frames whose world position, rotation was recomputed. `first`: nothing played yet (every
    root frame is a target). The keys' segments are p.segments', brought up to date."""
    (prev_t, nxt_t), (prev_r, nxt_r) = p.segments[0][0], p.segments[1][0]
    t = np.asarray(x.times, dtype=np.float32).astype(np.float64)
    compiled_call(_replay, p.order, x.parents, bool(first), keep_t, keep_r, new_t, new_r,
                  dirty_t, dirty_r, prev_t, nxt_t, prev_r, nxt_r, t, bool(x.short), x.t0,
                  x.q0, x.wq0, np.asarray(p.static_t, np.float64),
                  np.asarray(p.static_r, np.float64), p.pos0, p.tt, p.vt, p.tq, p.vq, p.codes,
                  p.tr, p.rr, p.nlerp, p.mat, p.wq, p.wn, p.pos, p.unit, p.blender, p.spread,
                  p.diff, p.err, moved, turned)


def slide_at(feet, both, moved, p) -> None:
    """p.slide (J, F - 1) at the planted frame pairs (f, f + 1) of the joints feet (N,) (both
    (N, F - 1) bool) where frame f or f + 1 moved (J, F) bool: the largest change of the three
    players' errors between the two frames (reduce._Player._slide_at)."""
    compiled_call(_slide, feet, both, moved, p.pos0, p.pos, p.unit, p.blender, p.slide)


@njit(cache=True, nogil=True, error_model="numpy")
def _slide(feet, both, moved, pos0, pos, unit, blender, slide):
    for r in range(len(feet)):
        j = feet[r]
        for f in range(both.shape[1]):
            if both[r, f] and (moved[j, f + 1] or moved[j, f]):
                s = 0.0
                for w in (pos, unit, blender):
                    d0 = (w[j, f + 1, 0] - pos0[j, f + 1, 0]) - (w[j, f, 0] - pos0[j, f, 0])
                    d1 = (w[j, f + 1, 1] - pos0[j, f + 1, 1]) - (w[j, f, 1] - pos0[j, f, 1])
                    d2 = (w[j, f + 1, 2] - pos0[j, f + 1, 2]) - (w[j, f, 2] - pos0[j, f, 2])
                    e = _len(d0, d1, d2)
                    if e > s or e != e:         # np.maximum's (a NaN wins)
                        s = e
                slide[j, f] = s


def play_channels(values, prev, nxt, static, times, rotation: bool) -> np.ndarray:
    """(F, C, W) float32: every channel as the players evaluate it at every frame (what the
    player's `_sample` plays, rounded to float32 as the files hold it): values (F, C, W)
    float32 the stored values, prev, nxt (C, F) each frame's key frames (reduce._segments),
    static (C, W) the values of channels with no key, times (F,) the key times (as float32);
    the translation's lerp, or the rotation's slerp (three.js's)."""
    out = np.empty(values.shape, np.float32)
    t = np.asarray(times, dtype=np.float32).astype(np.float64)
    compiled_call(_play, np.ascontiguousarray(values, np.float32), prev, nxt,
                  np.asarray(static, np.float64), t, bool(rotation), out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _play(values, prev, nxt, static, t, rotation, out):
    f_count, c_count, width = values.shape
    for c in range(c_count):
        for f in range(f_count):
            p, n, a, fixed, last = _span(prev, nxt, c, f, t, f_count)
            if fixed:
                for k in range(width):
                    out[f, c, k] = np.float32(static[c, k])
            elif last:
                for k in range(width):
                    out[f, c, k] = values[p, c, k]
            elif rotation:
                s0, s1, s2, s3 = _slerp(
                    np.float64(values[p, c, 0]), np.float64(values[p, c, 1]),
                    np.float64(values[p, c, 2]), np.float64(values[p, c, 3]),
                    np.float64(values[n, c, 0]), np.float64(values[n, c, 1]),
                    np.float64(values[n, c, 2]), np.float64(values[n, c, 3]), a)
                out[f, c, 0], out[f, c, 1] = np.float32(s0), np.float32(s1)
                out[f, c, 2], out[f, c, 3] = np.float32(s2), np.float32(s3)
            else:
                for k in range(width):
                    v0, v1 = np.float64(values[p, c, k]), np.float64(values[n, c, k])
                    out[f, c, k] = np.float32((v1 - v0) * a + v0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _span(prev, nxt, j, f, t, f_count):
    """(p, n, alpha, fixed, last) of the pair (j, f) (reduce._around)."""
    p, n = prev[j, f], nxt[j, f]
    fixed, last = p < 0, n >= f_count
    p = min(max(p, 0), f_count - 1)
    if last:
        n = p
    span = t[n] - t[p]
    a = (t[f] - t[p]) / span if span > 0.0 else 0.0
    return p, n, a, fixed, last


@njit(cache=True, nogil=True, error_model="numpy")
def _replay(order, parents, first, keep_t, keep_r, new_t, new_r, dirty_t, dirty_r, prev_t,
            nxt_t, prev_r, nxt_r, t, short, t0, q0, wq0, static_t, static_r, pos0, tt, vt, tq, vq,
            codes, tr, rr, nlerp, mat, wq, wn, pos, unit, blender, spread, diff, err, moved,
            turned):
    f_count = keep_t.shape[1]
    target_t, target_r = np.zeros(f_count, np.bool_), np.zeros(f_count, np.bool_)
    changed_t, changed_r = np.zeros(f_count, np.bool_), np.zeros(f_count, np.bool_)
    for j in order:
        pj = parents[j]
        root = pj < 0
        # a child's translation targets follow its parent's world position and rotation, its
        # rotation targets the parent's world rotation alone; new keys get theirs
        for f in range(f_count):
            target_t[f] = ((first if root else moved[pj, f]) or new_t[j, f]) and keep_t[j, f]
            target_r[f] = ((first if root else turned[pj, f]) or new_r[j, f]) and keep_r[j, f]
        _keys_of(j, pj, target_t, target_r, short, t0, q0, wq0, pos0, pos, mat, wq, tt, vt, tq,
                 vq, codes, changed_t, changed_r)
        _samples_of(j, pj, first, dirty_t, dirty_r, changed_t, changed_r, prev_t, nxt_t, prev_r,
                    nxt_r, t, vt, vq, static_t, static_r, tr, rr, nlerp, moved, turned)
        _poses_of(j, pj, turned[j], moved[j], rr, nlerp, tr, mat, wq, wn, pos, unit, blender,
                  pos0, spread, diff, err)


@njit(cache=True, nogil=True, error_model="numpy")
def _samples_of(j, pj, first, dirty_t, dirty_r, changed_t, changed_r, prev_t, nxt_t, prev_r,
                nxt_r, t, vt, vq, static_t, static_r, tr, rr, nlerp, moved, turned):
    """The played local values of joint j at the frames whose segment changed (dirty_t,
    dirty_r) or starts or ends on a key whose stored value changed (changed_t, changed_r (F,)),
    and the frames whose world rotation (turned) and position (moved) are to be redone: those,
    and those of the parent pj. (The spans are found here, not in the helpers: numba compiles
    the helpers' own index arithmetic over the arrays many times slower.)"""
    f_count = dirty_t.shape[1]
    root = pj < 0
    seg = (-1, -1)                              # the rotation segment whose arc is `arc`
    arc = (0.0, 0.0, 0.0, 0.0, False, False, 0.0, 0.0)
    # most replays change no stored key of a joint: then the keys around a frame are not read
    any_t, any_r = _any(changed_t), _any(changed_r)
    for f in range(f_count):
        st = dirty_t[j, f] or any_t and (
            changed_t[min(max(prev_t[j, f], 0), f_count - 1)] or
            changed_t[min(nxt_t[j, f], f_count - 1)])
        sr = dirty_r[j, f] or any_r and (
            changed_r[min(max(prev_r[j, f], 0), f_count - 1)] or
            changed_r[min(nxt_r[j, f], f_count - 1)])
        if st:
            p, n, a, fixed, last = _span(prev_t, nxt_t, j, f, t, f_count)
            _lerp(vt, static_t, j, f, p, n, a, fixed, last, tr)
        if sr:
            p, n, a, fixed, last = _span(prev_r, nxt_r, j, f, t, f_count)
            if not (fixed or last) and (p, n) != seg:   # the frames of a segment share it
                seg = (p, n)
                arc = _arc(np.float64(vq[j, p, 0]), np.float64(vq[j, p, 1]),
                           np.float64(vq[j, p, 2]), np.float64(vq[j, p, 3]),
                           np.float64(vq[j, n, 0]), np.float64(vq[j, n, 1]),
                           np.float64(vq[j, n, 2]), np.float64(vq[j, n, 3]))
            _rotation(vq, static_r, j, f, p, n, a, fixed, last, rr, nlerp, arc)
        turned[j, f] = sr or (first if root else turned[pj, f])
        moved[j, f] = st or turned[j, f] or (first if root else moved[pj, f])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _any(flags):
    """Whether any of flags (F,) bool is set."""
    for f in range(len(flags)):
        if flags[f]:
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lerp(vt, static_t, j, f, p, n, a, fixed, last, tr):
    """tr at (j, f): the lerp of the stored translation keys p, n at alpha a, as float32."""
    for k in range(3):
        if fixed:
            v = static_t[j, k]
        elif last:
            v = np.float64(vt[j, p, k])
        else:
            v0, v1 = np.float64(vt[j, p, k]), np.float64(vt[j, n, k])
            v = (v1 - v0) * a + v0
        tr[j, f, k] = np.float64(np.float32(v))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _rotation(vq, static_r, j, f, p, n, a, fixed, last, rr, nlerp, arc):
    """rr, nlerp at (j, f): the slerp (as float32) and the normalized lerp of the stored keys
    p, n at alpha a (three.js's slerp and Blender's component-wise lerp); arc: the slerp's
    segment (`_arc` of the two keys)."""
    x0, y0, z0, w0 = (np.float64(vq[j, p, 0]), np.float64(vq[j, p, 1]),
                      np.float64(vq[j, p, 2]), np.float64(vq[j, p, 3]))
    if fixed:
        s0, s1, s2, s3 = static_r[j, 0], static_r[j, 1], static_r[j, 2], static_r[j, 3]
        l0, l1, l2, l3 = s0, s1, s2, s3
    elif last:
        s0, s1, s2, s3 = x0, y0, z0, w0
        l0, l1, l2, l3 = x0, y0, z0, w0
    else:
        x1, y1, z1, w1 = (np.float64(vq[j, n, 0]), np.float64(vq[j, n, 1]),
                          np.float64(vq[j, n, 2]), np.float64(vq[j, n, 3]))
        l0, l1 = (x1 - x0) * a + x0, (y1 - y0) * a + y0
        l2, l3 = (z1 - z0) * a + z0, (w1 - w0) * a + w0
        s0, s1, s2, s3 = _arc_at(x0, y0, z0, w0, arc, a)
    rr[j, f, 0], rr[j, f, 1] = np.float64(np.float32(s0)), np.float64(np.float32(s1))
    rr[j, f, 2], rr[j, f, 3] = np.float64(np.float32(s2)), np.float64(np.float32(s3))
    m = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2 + l3 * l3)
    nlerp[j, f, 0], nlerp[j, f, 1], nlerp[j, f, 2], nlerp[j, f, 3] = l0 / m, l1 / m, l2 / m, \
        l3 / m


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _slerp(x0, y0, z0, w0, x1, y1, z1, w1, t):
    """reduce._slerp of one pair."""
    return _arc_at(x0, y0, z0, w0, _arc(x0, y0, z0, w0, x1, y1, z1, w1), t)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _arc(x0, y0, z0, w0, x1, y1, z1, w1):
    """What the slerp from (x0, y0, z0, w0) to (x1, y1, z1, w1) does at any alpha (one
    segment's frames share it): the second key the short way round, whether it equals the
    first (`same`: played as stored), whether it is near (lerped and normalized), else the
    angle theta between them and its sine."""
    d = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    if d < 0.0:
        x1, y1, z1, w1, d = -x1, -y1, -z1, -w1, -d
    same = x0 == x1 and y0 == y1 and z0 == z1 and w0 == w1
    near = d >= NEAR_DOT
    theta = s = 0.0
    if not (same or near):
        theta = np.arccos(min(d, 1.0))
        s = np.sin(theta)
    return x1, y1, z1, w1, same, near, theta, s


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _arc_at(x0, y0, z0, w0, arc, t):
    """The slerp at alpha t from (x0, y0, z0, w0) along `arc` (`_arc`)."""
    x1, y1, z1, w1, same, near, theta, s = arc
    if same:
        return x0, y0, z0, w0
    if near:
        wa, wb = 1.0 - t, t
    else:
        wa, wb = np.sin((1.0 - t) * theta) / s, np.sin(t * theta) / s
    ox, oy, oz, ow = x0 * wa + x1 * wb, y0 * wa + y1 * wb, z0 * wa + z1 * wb, w0 * wa + w1 * wb
    if near:
        m = np.sqrt(ox * ox + oy * oy + oz * oz + ow * ow)
        ox, oy, oz, ow = ox / m, oy / m, oz / m, ow / m
    return ox, oy, oz, ow


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _qmul(a, b, ja, jb, fa, out, jo):
    """out[jo, fa] = a[ja, fa] b[jb, fa] (geometry.transforms.quat_mul's terms, left to
    right)."""
    a0, a1, a2, a3 = a[ja, fa, 0], a[ja, fa, 1], a[ja, fa, 2], a[ja, fa, 3]
    b0, b1, b2, b3 = b[jb, fa, 0], b[jb, fa, 1], b[jb, fa, 2], b[jb, fa, 3]
    out[jo, fa, 0] = a3 * b0 + a0 * b3 + a1 * b2 - a2 * b1
    out[jo, fa, 1] = a3 * b1 - a0 * b2 + a1 * b3 + a2 * b0
    out[jo, fa, 2] = a3 * b2 + a0 * b1 - a1 * b0 + a2 * b3
    out[jo, fa, 3] = a3 * b3 - a0 * b0 - a1 * b1 - a2 * b2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _qrot(q, jq, f, v0, v1, v2):
    """q[jq, f] rotating (v0, v1, v2) (geometry.transforms.quat_rotate: v + w t + qv x t,
    t = 2 qv x v)."""
    x, y, z, w = q[jq, f, 0], q[jq, f, 1], q[jq, f, 2], q[jq, f, 3]
    t0, t1, t2 = (y * v2 - z * v1) * 2.0, (z * v0 - x * v2) * 2.0, (x * v1 - y * v0) * 2.0
    return (t0 * w + v0 + (y * t2 - z * t1), t1 * w + v1 + (z * t0 - x * t2),
            t2 * w + v2 + (x * t1 - y * t0))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _raw(x, y, z, w):
    """reduce._raw_matrix of the stored quaternion (x, y, z, w): its rows (m00, m01, m02),
    (m10, m11, m12), (m20, m21, m22), as scalars (the compiler keeps them in registers; a (3, 3)
    scratch array it reloads after every store to the player's arrays)."""
    xx, yy, zz = x * x, y * y, z * z
    m00, m11, m22 = 1 - (yy + zz) * 2, 1 - (xx + zz) * 2, 1 - (xx + yy) * 2
    m01, m10 = (x * y - z * w) * 2, (x * y + z * w) * 2
    m02, m20 = (x * z + y * w) * 2, (x * z - y * w) * 2
    m12, m21 = (y * z - x * w) * 2, (y * z + x * w) * 2
    return (m00, m01, m02), (m10, m11, m12), (m20, m21, m22)


@njit(cache=True, nogil=True, error_model="numpy")
def _poses_of(j, pj, turned, moved, rr, nlerp, tr, mat, wq, wn, pos, unit, blender, pos0,
              spread, diff, err):
    """World poses of joint j as the three players pose them: rotations at the frames
    `turned`, positions (and errors) at the frames `moved` (F,) bool (the matrix of the stored
    quaternion (raw), the renormalized one, Blender's nlerp, under the parent pj's)."""
    f_count = turned.shape[0]
    root = pj < 0
    for f in range(f_count):
        if turned[f]:
            x, y, z, w = rr[j, f, 0], rr[j, f, 1], rr[j, f, 2], rr[j, f, 3]
            m0, m1, m2 = _raw(x, y, z, w)
            n = np.sqrt(x * x + y * y + z * z + w * w)
            if root:
                for b in range(3):
                    mat[j, f, 0, b], mat[j, f, 1, b], mat[j, f, 2, b] = m0[b], m1[b], m2[b]
                for k in range(4):
                    wq[j, f, k] = rr[j, f, k] / n
                    wn[j, f, k] = nlerp[j, f, k]
            else:
                for a in range(3):
                    p0, p1, p2 = mat[pj, f, a, 0], mat[pj, f, a, 1], mat[pj, f, a, 2]
                    for b in range(3):
                        mat[j, f, a, b] = p0 * m0[b] + p1 * m1[b] + p2 * m2[b]
                for k in range(4):          # the unit rotation, then the product
                    wq[j, f, k] = rr[j, f, k] / n
                _qmul(wq, wq, pj, j, f, wq, j)
                _qmul(wn, nlerp, pj, j, f, wn, j)
        if moved[f]:
            _place(j, pj, f, root, tr, mat, wq, wn, pos, unit, blender, pos0, spread, diff, err)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _place(j, pj, f, root, tr, mat, wq, wn, pos, unit, blender, pos0, spread, diff, err):
    """Positions of the pair (j, f) as the three players pose them, their spread and the
    worst one's error against the unreduced position."""
    v0, v1, v2 = tr[j, f, 0], tr[j, f, 1], tr[j, f, 2]
    if root:
        p0, p1, p2 = v0, v1, v2
        u0, u1, u2 = v0, v1, v2
        b0, b1, b2 = v0, v1, v2
    else:
        p0 = mat[pj, f, 0, 0] * v0 + mat[pj, f, 0, 1] * v1 + mat[pj, f, 0, 2] * v2 + pos[pj, f, 0]
        p1 = mat[pj, f, 1, 0] * v0 + mat[pj, f, 1, 1] * v1 + mat[pj, f, 1, 2] * v2 + pos[pj, f, 1]
        p2 = mat[pj, f, 2, 0] * v0 + mat[pj, f, 2, 1] * v1 + mat[pj, f, 2, 2] * v2 + pos[pj, f, 2]
        u0, u1, u2 = _qrot(wq, pj, f, v0, v1, v2)
        u0, u1, u2 = u0 + unit[pj, f, 0], u1 + unit[pj, f, 1], u2 + unit[pj, f, 2]
        b0, b1, b2 = _qrot(wn, pj, f, v0, v1, v2)
        b0, b1, b2 = b0 + blender[pj, f, 0], b1 + blender[pj, f, 1], b2 + blender[pj, f, 2]
    pos[j, f, 0], pos[j, f, 1], pos[j, f, 2] = p0, p1, p2
    unit[j, f, 0], unit[j, f, 1], unit[j, f, 2] = u0, u1, u2
    blender[j, f, 0], blender[j, f, 1], blender[j, f, 2] = b0, b1, b2
    spread[j, f] = max(_len(u0 - p0, u1 - p1, u2 - p2), _len(b0 - p0, b1 - p1, b2 - p2))
    q0, q1, q2 = pos0[j, f, 0], pos0[j, f, 1], pos0[j, f, 2]
    d0, d1, d2 = p0 - q0, p1 - q1, p2 - q2
    e = _len(d0, d1, d2)
    for w0, w1, w2 in ((u0, u1, u2), (b0, b1, b2)):
        c0, c1, c2 = w0 - q0, w1 - q1, w2 - q2
        ec = _len(c0, c1, c2)
        if ec > e:
            d0, d1, d2, e = c0, c1, c2, ec
    diff[j, f, 0], diff[j, f, 1], diff[j, f, 2] = d0, d1, d2
    err[j, f] = e


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _len(a, b, c):
    return np.sqrt(a * a + b * b + c * c)


def targets_level(level, parents, target_t, target_r, short: bool, x, p):
    """The key values of the joints `level` (reduce._Player._targets): translations at the
    frames target_t, rotations at the frames target_r (L, F) bool, into p.tt, p.vt and p.tq,
    p.vq (and p.codes when `short`: requantized only where tq changed). Returns ((L, F),
    (L, F)) bool: the frames whose stored value vt, vq changed (bit for bit)."""
    changed_t = np.zeros(target_t.shape, dtype=bool)
    changed_r = np.zeros(target_r.shape, dtype=bool)
    compiled_call(_targets, level, parents, target_t, target_r, bool(short), x.t0, x.q0, x.wq0,
                  p.pos0, p.pos, p.mat, p.wq, p.tt, p.vt, p.tq, p.vq, p.codes, changed_t,
                  changed_r)
    return changed_t, changed_r


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _differ(a, b):
    """Whether the float32 values a and b differ in any bit (-0.0 from 0.0, too)."""
    return a != b or np.copysign(1.0, a) != np.copysign(1.0, b)


@njit(cache=True, nogil=True, error_model="numpy")
def _targets(level, parents, target_t, target_r, short, t0, q0, wq0, pos0, pos, mat, wq, tt, vt,
             tq, vq, codes, changed_t, changed_r):
    for r in range(len(level)):
        _keys_of(level[r], parents[level[r]], target_t[r], target_r[r], short, t0, q0, wq0, pos0,
                 pos, mat, wq, tt, vt, tq, vq, codes, changed_t[r], changed_r[r])


@njit(cache=True, nogil=True, error_model="numpy")
def _keys_of(j, pj, target_t, target_r, short, t0, q0, wq0, pos0, pos, mat, wq, tt, vt, tq, vq,
             codes, changed_t, changed_r):
    """The key values of joint j (parent pj): translations at the frames target_t, rotations at
    the frames target_r (F,) bool, into tt, vt and tq, vq (and codes when `short`: requantized
    only where tq changed); changed_t, changed_r (F,): whether vt, vq changed there (bit for
    bit), False elsewhere."""
    f_count = target_t.shape[0]
    root = pj < 0
    q, c = np.empty(4), np.empty(4, np.int16)
    for f in range(f_count):
        changed_t[f] = changed_r[f] = False
        if target_t[f]:
            x0, x1, x2 = _target_t(root, t0, pos0, pos, mat, j, pj, f)
            tt[j, f, 0], tt[j, f, 1], tt[j, f, 2] = x0, x1, x2
            for k, v in enumerate((np.float32(x0), np.float32(x1), np.float32(x2))):
                changed_t[f] |= _differ(vt[j, f, k], v)
                vt[j, f, k] = v
        if target_r[f]:
            _target_q(root, q0, wq0, wq, j, pj, f, q)
            same = True
            for k in range(4):
                same &= tq[j, f, k] == q[k]
                tq[j, f, k] = q[k]
            if short and same:
                continue                    # the codes of this target are stored
            if short:
                _quantize(q, c)
            for k in range(4):
                if short:
                    v = np.float32(max(np.float64(c[k]) / SHORT_MAX, -1.0))
                    codes[j, f, k] = c[k]
                else:
                    v = np.float32(q[k] / np.sqrt(dot4(q, q)))
                changed_r[f] |= _differ(vq[j, f, k], v)
                vq[j, f, k] = v


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _target_t(root, t0, pos0, pos, mat, j, pj, f):
    """The local translation of (j, f) that puts it on its unreduced world position under its
    parent's played pose ; t0 at a root."""
    if root:
        return t0[j, f, 0], t0[j, f, 1], t0[j, f, 2]
    return _solve3(mat, pj, f, pos0[j, f, 0] - pos[pj, f, 0], pos0[j, f, 1] - pos[pj, f, 1],
                   pos0[j, f, 2] - pos[pj, f, 2])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dot4(a, b):
    """a . b of two 4-vectors, summed left to right."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _solve3(mat, pj, f, v0, v1, v2):
    """x with m x = v, m the matrix mat[pj, f], by Cramer's rule (the matrices are near
    rotations, well conditioned)."""
    m00, m01, m02 = mat[pj, f, 0, 0], mat[pj, f, 0, 1], mat[pj, f, 0, 2]
    m10, m11, m12 = mat[pj, f, 1, 0], mat[pj, f, 1, 1], mat[pj, f, 1, 2]
    m20, m21, m22 = mat[pj, f, 2, 0], mat[pj, f, 2, 1], mat[pj, f, 2, 2]
    # the rows of adj(m): the columns' cross products (reduce._cross's arithmetic)
    a0, a1, a2 = m11 * m22 - m21 * m12, m21 * m02 - m01 * m22, m01 * m12 - m11 * m02
    b0, b1, b2 = m12 * m20 - m22 * m10, m22 * m00 - m02 * m20, m02 * m10 - m12 * m00
    c0, c1, c2 = m10 * m21 - m20 * m11, m20 * m01 - m00 * m21, m00 * m11 - m10 * m01
    det = a0 * m00 + a1 * m10 + a2 * m20
    return ((a0 * v0 + a1 * v1 + a2 * v2) / det, (b0 * v0 + b1 * v1 + b2 * v2) / det,
            (c0 * v0 + c1 * v1 + c2 * v2) / det)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _target_q(root, q0, wq0, wq, j, pj, f, q):
    """q = the unit local rotation of (j, f) that gives its unreduced world rotation under its
    parent's played one, on the clip's side; q0 at a root."""
    if root:
        for k in range(4):
            q[k] = q0[j, f, k]
        return
    a0, a1, a2, a3 = -wq[pj, f, 0], -wq[pj, f, 1], -wq[pj, f, 2], wq[pj, f, 3]
    b0, b1, b2, b3 = wq0[j, f, 0], wq0[j, f, 1], wq0[j, f, 2], wq0[j, f, 3]
    q[0] = a3 * b0 + a0 * b3 + a1 * b2 - a2 * b1
    q[1] = a3 * b1 - a0 * b2 + a1 * b3 + a2 * b0
    q[2] = a3 * b2 + a0 * b1 - a1 * b0 + a2 * b3
    q[3] = a3 * b3 - a0 * b0 - a1 * b1 - a2 * b2
    if q[0] * q0[j, f, 0] + q[1] * q0[j, f, 1] + q[2] * q0[j, f, 2] + q[3] * q0[j, f, 3] < 0:
        for k in range(4):
            q[k] = -q[k]
    n = np.sqrt(dot4(q, q))
    for k in range(4):
        q[k] /= n


#: normalized SHORT's largest code
SHORT_MAX = 32767


@njit(cache=True, nogil=True, error_model="numpy")
def _quantize(q, out):
    """out = reduce.quantize_rotations of the quaternion q (4,): of the 16 codes that round
    each component down or up, the one of the least cost, in _quantize's arithmetic."""
    n = np.sqrt(dot4(q, q))
    s, c = np.empty(4), np.empty(4)
    for k in range(4):
        s[k] = q[k] / n * SHORT_MAX
        c[k] = np.floor(s[k])
    cc, sc = dot4(c, c), dot4(s, c)
    u3 = q[3] / n
    lever = 1.0 - u3 * u3
    s2 = np.float64(SHORT_MAX) ** 2
    best, at = np.inf, 0
    for code in range(16):
        bc, bs, count = 0.0, 0.0, 0.0
        for k in range(4):              # the components rounded up, in order (_bit_sums)
            if code >> k & 1:
                bc += c[k]
                bs += s[k]
                count += 1.0
        n2 = (bc * 2.0 + cc + count) / s2
        d = (bs + sc) / s2
        cost = max(n2 - d * d, 0.0) / n2
        stretch = abs(n2 - 1.0)
        cost += stretch * stretch * lever
        if cost < best:
            best, at = cost, code
    for k in range(4):
        out[k] = np.int16(min(max(c[k] + (at >> k & 1), -SHORT_MAX), SHORT_MAX))


def blame_slots(ki, fi, chains, shape) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (ancestor, frame) pairs of the offending pairs (ki, fi) (reduce._blame):
    (slot (J * F,) int64, each pair's row among them or -1; i (N,) int64, the pairs' flat
    indices j * F + f, in the order of their rows)."""
    j_count, f_count = shape
    slot = np.full(j_count * f_count, -1, np.int64)
    i = np.empty(min(j_count * f_count, len(ki) * chains.shape[1]), np.int64)
    count = np.zeros(1, np.int64)
    compiled_call(_slots, np.ascontiguousarray(ki, np.int64), np.ascontiguousarray(fi, np.int64),
                  chains, f_count, slot, i, count)
    return slot, i[:count[0]]


@njit(cache=True, nogil=True, error_model="numpy")
def _slots(ki, fi, chains, f_count, slot, i, count):
    n = 0
    for v in range(len(ki)):
        for d in range(chains.shape[1]):
            a = chains[ki[v], d]
            if a < 0:
                break                       # past the root
            at = a * f_count + fi[v]
            if slot[at] < 0:
                slot[at] = n
                i[n] = at
                n += 1
    count[0] = n


def blame_pairs(ki, fi, chains, slot, diff, pos, c_t, rv, wp, share: float, out: list) -> None:
    """reduce._blame's shares, of the offending pairs (ki, fi): each channel on a pair's chain
    (its translations' and its strict ancestors' rotations) projected on the pair's error
    direction (diff); those with at least `share` of the pair's largest, and over 0, are
    candidates at the pair's frame, their scores raised to it: into out = [translation
    candidates, scores, rotation candidates, scores] (J, F). c_t (N, 3): the translation
    channels' world moves at the rows `slot` gives (blame_slots); rv (N, 3) the rotation
    channels' error as rotation vectors, turned into the world's by wp (N, 4) (blame_moves).
    The projections are summed in np.einsum's order, (x0 y0 + x2 y2) + x1 y1 (its two
    accumulators), as the numpy blame summed them."""
    compiled_call(_blame, np.ascontiguousarray(ki, np.int64), np.ascontiguousarray(fi, np.int64),
                  chains, slot, diff, pos, c_t, rv, wp, float(share), *out)


@njit(cache=True, nogil=True, error_model="numpy")
def _blame(ki, fi, chains, slot, diff, pos, c_t, rv, wp, share, cand_t, score_t, cand_r,
           score_r):
    f_count = diff.shape[1]
    depth = chains.shape[1]
    ct, cr = np.empty(depth), np.empty(depth)
    omega = np.empty(rv.shape)
    for r in range(len(rv)):
        omega[r, 0], omega[r, 1], omega[r, 2] = quat_rotate1(
            wp[r, 0], wp[r, 1], wp[r, 2], wp[r, 3], rv[r, 0], rv[r, 1], rv[r, 2])
    for v in range(len(ki)):
        k, f = ki[v], fi[v]
        e0, e1, e2 = diff[k, f, 0], diff[k, f, 1], diff[k, f, 2]
        m = _len(e0, e1, e2)
        if not (m >= 1e-300 or m != m):     # np.maximum's (a NaN wins)
            m = 1e-300
        e0, e1, e2 = e0 / m, e1 / m, e2 / m
        top = -np.inf
        n = depth
        for d in range(depth):
            a = chains[k, d]
            if a < 0:
                n = d
                break                       # past the root
            r = slot[a * f_count + f]
            ct[d] = (c_t[r, 0] * e0 + c_t[r, 2] * e2) + c_t[r, 1] * e1      # np.einsum's order
            cr[d] = -np.inf
            if d > 0:                       # the arm from the ancestor a to k, across e
                h0, h1, h2 = pos[k, f, 0] - pos[a, f, 0], pos[k, f, 1] - pos[a, f, 1], \
                    pos[k, f, 2] - pos[a, f, 2]
                r0, r1, r2 = h1 * e2 - h2 * e1, h2 * e0 - h0 * e2, h0 * e1 - h1 * e0
                cr[d] = (omega[r, 0] * r0 + omega[r, 2] * r2) + omega[r, 1] * r1
            top = _top(_top(top, ct[d]), cr[d])
        bar = share * top
        for d in range(n):
            a = chains[k, d]
            _candidate(ct[d], bar, a, f, cand_t, score_t)
            _candidate(cr[d], bar, a, f, cand_r, score_r)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _top(top, c):
    """The larger of top and c, np.max's (a NaN wins)."""
    return c if c > top or c != c else top


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _candidate(c, bar, a, f, cand, score):
    """A share c over 0 and at least bar makes (a, f) a candidate, its score raised to c."""
    if c > 0 and c >= bar:
        cand[a, f] = True
        if c > score[a, f]:
            score[a, f] = c


def unreduced(order, parents, translations, rotations) -> tuple:
    """The unreduced clip joints first, float64: local t0 (J, F, 3), q0 (J, F, 4) from the
    clip's (F, J, 3) translations and (F, J, 4) rotations, and the world positions pos0 and
    rotations wq0 that rig.skeleton.forward_kinematics gives (its arithmetic, pair by pair:
    geometry.fused's quat_rotate1 and quat_mul1), in one pass over the joints `order` (parents
    first) instead of its frames-first arrays and their transposing copies."""
    f_count, j_count = translations.shape[:2]
    out = (np.empty((j_count, f_count, 3)), np.empty((j_count, f_count, 4)),
           np.empty((j_count, f_count, 3)), np.empty((j_count, f_count, 4)))
    compiled_call(_unreduced, order, parents, translations, rotations, *out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _unreduced(order, parents, translations, rotations, t0, q0, pos0, wq0):
    for j in order:
        pj = parents[j]
        for f in range(translations.shape[0]):
            for k in range(3):
                t0[j, f, k] = np.float64(translations[f, j, k])
            for k in range(4):
                q0[j, f, k] = np.float64(rotations[f, j, k])
            if pj < 0:
                for k in range(3):
                    pos0[j, f, k] = t0[j, f, k]
                for k in range(4):
                    wq0[j, f, k] = q0[j, f, k]
                continue
            x, y, z, w = wq0[pj, f, 0], wq0[pj, f, 1], wq0[pj, f, 2], wq0[pj, f, 3]
            r0, r1, r2 = quat_rotate1(x, y, z, w, t0[j, f, 0], t0[j, f, 1], t0[j, f, 2])
            pos0[j, f, 0], pos0[j, f, 1] = pos0[pj, f, 0] + r0, pos0[pj, f, 1] + r1
            pos0[j, f, 2] = pos0[pj, f, 2] + r2
            wq0[j, f, 0], wq0[j, f, 1], wq0[j, f, 2], wq0[j, f, 3] = quat_mul1(
                x, y, z, w, q0[j, f, 0], q0[j, f, 1], q0[j, f, 2], q0[j, f, 3])


def blame_moves(i, x, p) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """At the pairs i (N,) (flat indices j * F + f), from the player p's current poses (for
    the blame, reduce._blame_block): the world offset of each translation channel's error (the played
    minus the target local translation, in its parent's world frame) c_t (N, 3), each rotation
    channel's error err_q (N, 4) (the played local rotation times the target's conjugate) and
    the parent's world rotation wp (N, 4) (identity at a root), which turns err_q's rotation
    vector into the world's. The targets are those `targets_level` gives there."""
    out = np.empty((len(i), 3)), np.empty((len(i), 4)), np.empty((len(i), 4))
    compiled_call(_moves, np.ascontiguousarray(i, dtype=np.int64), x.parents, x.t0, x.q0,
                  x.wq0, p.pos0, p.pos, p.mat, p.wq, p.tr, p.rr, *out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _moves(i, parents, t0, q0, wq0, pos0, pos, mat, wq, tr, rr, c_t, err_q, wp):
    f_count = t0.shape[1]
    q = np.empty(4)
    for n in range(len(i)):
        j, f = i[n] // f_count, i[n] % f_count
        pj = parents[j]
        root = pj < 0
        x, y, z, w = (0.0, 0.0, 0.0, 1.0) if root else (wq[pj, f, 0], wq[pj, f, 1],
                                                         wq[pj, f, 2], wq[pj, f, 3])
        wp[n, 0], wp[n, 1], wp[n, 2], wp[n, 3] = x, y, z, w
        a0, a1, a2 = _target_t(root, t0, pos0, pos, mat, j, pj, f)
        c_t[n, 0], c_t[n, 1], c_t[n, 2] = quat_rotate1(
            x, y, z, w, tr[j, f, 0] - a0, tr[j, f, 1] - a1, tr[j, f, 2] - a2)
        _target_q(root, q0, wq0, wq, j, pj, f, q)
        err_q[n, 0], err_q[n, 1], err_q[n, 2], err_q[n, 3] = quat_mul1(
            rr[j, f, 0], rr[j, f, 1], rr[j, f, 2], rr[j, f, 3], -q[0], -q[1], -q[2], q[3])


def segments(keep) -> tuple[np.ndarray, np.ndarray]:
    """(prev, nxt), each (C, F) int64, of the key frames keep (C, F) bool (reduce._segments)."""
    keep = np.asarray(keep, dtype=bool)
    prev, nxt = np.empty(keep.shape, np.int64), np.empty(keep.shape, np.int64)
    compiled_call(_segment_rows, keep, prev, nxt)
    return prev, nxt


@njit(cache=True, nogil=True, error_model="numpy")
def _segment_rows(keep, prev, nxt):
    scratch = np.empty(keep.shape[1], np.bool_)      # where they changed: not asked for
    for c in range(keep.shape[0]):
        _segment_row(keep, c, prev, nxt, scratch)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _segment_row(keep, c, prev, nxt, dirty):
    """prev, nxt of row c of keep, in place; dirty (F,) set where either changed."""
    f_count = keep.shape[1]
    at = -1
    for f in range(f_count):
        if keep[c, f]:
            at = f
        if prev[c, f] != at:
            dirty[f] = True
            prev[c, f] = at
    at = f_count
    for f in range(f_count - 1, -1, -1):
        if nxt[c, f] != at:
            dirty[f] = True
            nxt[c, f] = at
        if keep[c, f]:
            at = f


def resegment(segments: tuple, played: np.ndarray, keep: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Bring `segments` (reduce._segments of the keys `played`, (C, F)) and `played` up to
    `keep`, in place, redoing only the channels whose keys changed (reduce._resegment).
    Returns ((C, F) bool the frames whose segment changed, (C, F) bool the new keys)."""
    dirty, new = np.zeros(keep.shape, dtype=bool), np.zeros(keep.shape, dtype=bool)
    compiled_call(_resegment, keep, played, segments[0], segments[1], dirty, new)
    return dirty, new


@njit(cache=True, nogil=True, error_model="numpy")
def _resegment(keep, played, prev, nxt, dirty, new):
    for c in range(keep.shape[0]):
        same = True
        for f in range(keep.shape[1]):
            if keep[c, f] != played[c, f]:
                same = False
                break
        if same:
            continue
        for f in range(keep.shape[1]):
            new[c, f] = keep[c, f] and not played[c, f]
            played[c, f] = keep[c, f]
        _segment_row(keep, c, prev, nxt, dirty[c])


def violations(err, spread, tight, slide, bounds: tuple) -> np.ndarray:
    """(J, F) bool: the pairs over a bound (reduce._Player.play): err over bounds[0] or spread
    over bounds[1]; where tight (J, F) bool (or None), err over bounds[2]; and both frames of
    a planted pair whose slide (J, F - 1) (or None) is over bounds[3]."""
    viol = np.empty(err.shape, dtype=bool)
    none = np.zeros((0, 0), dtype=bool)
    compiled_call(_violations, err, spread, none if tight is None else tight,
                  np.zeros((0, 0)) if slide is None else slide, tight is not None,
                  slide is not None, *(float(b) for b in bounds), viol)
    return viol


@njit(cache=True, nogil=True, error_model="numpy")
def _violations(err, spread, tight, slide, has_tight, has_slide, tol, spread_max, tight_max,
                slide_max, viol):
    for j in range(err.shape[0]):
        for f in range(err.shape[1]):
            viol[j, f] = err[j, f] > tol or spread[j, f] > spread_max or \
                (has_tight and tight[j, f] and err[j, f] > tight_max)
        if has_slide:
            for f in range(err.shape[1] - 1):
                if slide[j, f] > slide_max:
                    viol[j, f] = viol[j, f + 1] = True
