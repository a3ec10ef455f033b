"""Error-bounded keyframe reduction: drop the keys that interpolation reproduces.

A clip keys every joint at every frame. Players interpolate glTF LINEAR samplers (and USD time
samples) between keys: lerp for translations and scales, slerp for rotations. `reduce_clip`
keeps, per joint and channel, only the frames needed so that the played-back pose stays within a
**world-space** tolerance of the unreduced pose, at every joint (feet and antenna tips included)
and every original frame:

    clip = reduce_clip(clip, skeleton.parents, 0.00025, contacts=planted, rest=rest)
    clip.keys.rotations.frames(j)      # kept frame indices of joint j's rotation, or None (static)
    clip.keys.rotations.values         # (F, J, 4) the values the files store at those frames

Per-channel tolerances do not bound the world error: a spine joint's rotation error moves every
joint below it, and the errors of the 20 spine joints add up at the tail and the feet. So:

- **Compensated keys.** A joint's key values are not its own unreduced local TRS but the local
  TRS that puts it exactly on its unreduced world pose *given its reduced parent* (computed level
  by level down the skeleton). A parent's interpolation error then stops at the child's keys
  instead of travelling down the chain.
- **Local pass** (top-down Douglas-Peucker, all channels at once). A channel within its local
  tolerance of one constant value is **static**: no keys; the exporters write its value as the
  node's TRS (or a 1-key channel). The rest get keys at the worst frame of every segment until
  each is within its local tolerance: `LOCAL_SHARE * tol` metres for a translation,
  `LOCAL_SHARE * tol / lever` radians for a rotation (lever: the farthest a joint below it gets
  from it, at least its own bone); a joint with more than `DEPTH_SHARED` ancestors (a very long
  body) shares that among them: times `DEPTH_SHARED / depth`.
- **World refinement.** The reduced clip is played as three players would: three.js and UsdSkel
  (float32 key values and times; three.js's slerp, which normalizes only between nearly equal
  keys; matrices built from the stored quaternion without normalizing it), a player that
  normalizes the slerped quaternion (scipy's Slerp, baker.inspect), and Blender (component-wise
  lerp, normalized). Each is posed and compared with the unreduced world positions. For each
  joint off by more than the tolerance in any of them, the channels on its chain are blamed by
  their linearized share of its error vector (a translation's world offset, or a rotation's
  world error x the arm to that joint, projected on the error's direction); those with at least
  `BLAME_SHARE` of the largest share get a key at their worst blamed frame of each segment.
  Repeat until no joint is off. Every round adds a key, so it ends (at worst with every frame a
  key, which reproduces the clip).
- **Bytes.** A channel keeping so many keys that a time accessor of its own would cost more than
  keying every frame (which shares the clip's full time accessor) is keyed at every frame (before
  and after the refinement, which then checks again).

Speed (the same keys as a plain implementation): the local pass splits each channel's segments
in compiled code (baker.export.keyfit) and keys a channel at every frame at once when more of its
frames than `_promote`'s bound miss even between their neighbours; the refinement's playback
(`_Player`) is kept between rounds and replays only the (joint, frame) pairs whose keys, stored
key values (bit for bit: a recomputed key that quantizes to the same code changes nothing) or
parent changed, world rotations and positions apart, and computes key values at key frames only
(those of the other frames, which the files store but no player reads, once at the end). The
player's per-pair arithmetic (key values, sampling, posing, errors), the blame's and the
unreduced clip's world poses are compiled too (baker.export.replay), level by level over the
pairs a mask selects, each pair computed on its own with the arithmetic of the numpy kernels
here (sums over 3 or 4 components written out left to right), so a replay gives what a fresh
playback gives, bit for bit (tests/export/test_reduce.py checks it).

Rigid bones: a joint whose unreduced local translation keeps one length while it turns (a spine
joint, a spacing from the joint ahead) keeps it within `LENGTH_SHARE` of it when played. The
world error alone lets a joint and its parent each be off by up to the tolerance, their distance
by twice it: 4 % of a spine spacing at the default tolerance, where the limit is 2 %. A played
translation off by more, once every joint is within the tolerance, is keyed at that frame; where
it is a key already (its compensated value is off by its parent's error), its parent's chain is
(compensated keys put the chain exactly on its unreduced pose there).

Planted feet: with `contacts` (frames where a joint is planted), a foot that does not move in the
original may not slide in the reduced clip: between two planted frames its error may change by at
most `PLANTED_SLIDE * tol` (the refinement treats a larger change like an error over the bound).

16-bit rotations (`short_rotations=True`): glTF core allows rotation sampler outputs as normalized
SHORT (code / 32767), half the bytes of float. The codes (`quantize_rotations`: rounded so the
stored quaternion, used unnormalized by three.js and UsdSkel, still gives a rotation matrix) are
what the reduction plays, so the world bound includes the rounding, and compensation keeps it from
adding up down the chain. The USD stores the same played values. When the rounding alone (every
frame keyed) would use more than half the tolerance, rotations stay float.

Node tracks (prey, sun) are not part of the skeleton: each channel is held to the tolerance on its
own (rotations and scales times the skeleton's extent as the lever); so are joint scales (a bake's
are ones: static).

What the players do (checked in their sources): glTF 2.0 LINEAR is lerp, and slerp for
rotations. three.js (QuaternionLinearInterpolant -> Quaternion.slerpFlat) slerps the short way
round without normalizing, lerps and normalizes when dot >= 0.9995, evaluates a key time on the
segment that starts there and returns the last key as stored; Matrix4.compose uses the quaternion
as stored. USD interpolates time samples linearly (`Usd_Interpolate`, pxr/usd/usd/
interpolators.cpp): `GfLerp` for vectors (float3 translations, half3 scales), `GfSlerp` for quatf
(short way round; a plain lerp when 1 - dot <= 1e-5), element by element for arrays of equal
size; UsdSkel.MakeTransform does not normalize. The USD writer stores the played value of every
joint at every frame any joint keeps, so USD plays what three.js plays.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from baker.clip import Clip
from baker.errors import ExportError
from baker.export import keyfit, replay

#: local pass: the share of the tolerance each channel gets on its own
LOCAL_SHARE = 0.5
#: local pass: joints with more ancestors than this (a long body's tail and feet, whose
#: ancestors' errors between keys add up) get LOCAL_SHARE times DEPTH_SHARED / their depth
DEPTH_SHARED = 32
#: world refinement: channels contributing at least this share of the largest contribution to
#: an offending joint's error get a key
BLAME_SHARE = 0.8
#: joints at their tight frames (a bone within the tolerance of the environment) keep within
#: this share of the tolerance
TIGHT_SHARE = 0.1
#: rigid bones: the largest change of a played bone's length, as a fraction of its length (the
#: quality limit on the spine's spacing is 2 %)
LENGTH_SHARE = 0.015
#: a joint's translation is a rigid bone when its length varies by less than this fraction (its
#: float32 components round it by a few millionths)
RIGID_SPREAD = 1e-5
#: planted joints: largest change of the reduced joint's error between two planted frames, as a
#: fraction of the tolerance
PLANTED_SLIDE = 0.5
#: the players (three.js/UsdSkel, a renormalizing slerp, Blender's nlerp) may disagree by at most
#: this [m] at any joint and frame: half the 1e-4 m the project holds its players to
PLAYER_SPREAD_M = 5e-5
#: safety stop of the world refinement (each round adds at least one key)
MAX_ROUNDS = 10_000
#: a clip of more frames than this after its first is refined in pieces of at most as many
#: (reduce_plan's `split`, piece_bounds): 30 s at 30 fps
PIECE_FRAMES = 900
#: normalized SHORT: stored code c decodes to c / SHORT_MAX
SHORT_MAX = 32767
#: bytes of one value in the GLB: translation/scale VEC3 float, rotation VEC4 float or SHORT
VALUE_BYTES = {"translation": 12, "rotation": 16, "rotation_short": 8, "scale": 12}
TIME_BYTES = 4


@dataclass(frozen=True)
class Keys:
    """The kept keys of C channels of one kind (translation, rotation or scale).

    keep   : (C, F) bool, frame f is a key of channel c. A channel with no key is **static**:
             its value is `static[c]` at every frame. An animated channel keeps its first and
             last frame.
    values : (F, C, W) float32, the value channel c stores at frame f (only key frames are
             written). For joints these are *compensated*: computed against the reduced parent
             (see the module docstring), not the clip's own local values.
    static : (C, W) float32, the value of each static channel (W = 3, or 4 for xyzw rotations);
             rows of animated channels are unused
    codes  : (F, C, 4) int16 normalized-SHORT codes of rotation values (values ==
             dequantize_rotations(codes)), or None for float storage
    """

    keep: np.ndarray
    values: np.ndarray
    static: np.ndarray
    codes: np.ndarray | None = None

    @property
    def is_static(self) -> np.ndarray:
        """(C,) bool, the channels with no key."""
        return ~self.keep.any(axis=1)

    @property
    def count(self) -> int:
        """Keys kept over all channels (a static channel counts none)."""
        return int(self.keep.sum())

    def frames(self, c: int) -> np.ndarray | None:
        """(K,) int64 kept frame indices of channel c, ascending, or None when it is static."""
        return self._frames[c]

    @cached_property
    def _frames(self) -> list:
        """frames(c) of every channel, found at once on first use (the exporters ask for every
        channel; one pass over `keep` instead of one per channel). `keep` does not change once
        the Keys is made."""
        rows, cols = np.nonzero(self.keep)
        ends = np.cumsum(np.bincount(rows, minlength=len(self.keep)))
        return [f if len(f) else None for f in np.split(cols.astype(np.int64), ends[:-1])]

    def play(self, times: np.ndarray, rotation: bool) -> np.ndarray:
        """(F, C, W) float32: every channel as a player evaluates it at every frame (`sample`
        rounded to float32, the same bits: compiled, baker.export.replay.play_channels)."""
        return replay.play_channels(self.values, *_segments(self.keep), self.static, times,
                                    rotation)


@dataclass(frozen=True)
class TrackKeys:
    """Kept keys of one NodeTrack: a one-channel Keys per path the track animates (None where
    the track has no such path). The values are the track's own."""

    translations: Keys | None = None
    rotations: Keys | None = None
    scales: Keys | None = None

    def parts(self) -> list[tuple[str, Keys]]:
        """(path, Keys) of the animated paths: "translation", "rotation", "scale"."""
        return [(p, k) for p, k in (("translation", self.translations),
                                    ("rotation", self.rotations), ("scale", self.scales))
                if k is not None]


@dataclass(frozen=True)
class ClipKeys:
    """The result of keyframe reduction, stored on `Clip.keys`.

    translations, rotations, scales : Keys over the clip's J joints
    tracks          : one TrackKeys per clip.tracks entry, in order
    tolerance_m     : [m] the world-space bound the keys were chosen for
    max_error_m     : [m] the largest world-space joint position error of the reduced clip over
                      every joint and frame, the worst of the three players the refinement
                      plays it as (<= tolerance_m)
    max_slide_m     : [m] the largest change of a planted joint's error between two planted
                      frames (0 without contacts)
    short_rotations : animated rotations are stored as normalized SHORT (Keys.codes)
    max_spread_m    : [m] the largest distance between the players' poses of a joint (<=
                      PLAYER_SPREAD_M)
    """

    translations: Keys
    rotations: Keys
    scales: Keys
    tracks: tuple[TrackKeys, ...]
    tolerance_m: float
    max_error_m: float
    max_slide_m: float = 0.0
    short_rotations: bool = False
    max_spread_m: float = 0.0

    def count(self) -> int:
        """Keys kept over every channel of the clip (joints and tracks)."""
        n = self.translations.count + self.rotations.count + self.scales.count
        return n + sum(k.count for t in self.tracks for _, k in t.parts())


# ------------------------------------------------------------------------------- values


_BITS = ((np.arange(16)[None, :] >> np.arange(4)[:, None]) & 1).astype(np.float64)   # (4, 16)


def quantize_rotations(q: np.ndarray) -> np.ndarray:
    """(..., 4) int16 normalized-SHORT codes of xyzw unit quaternions q (..., 4). Of the 16 codes
    that round each component down or up, the one that best keeps q's rotation *and* its matrix:
    three.js and UsdSkel build the rotation matrix from the stored quaternion without
    normalizing it, so a code of length s gives s^2 R + (1 - s^2) I, off by |s^2 - 1| |R - I|."""
    q = np.asarray(q, dtype=np.float64)
    flat = q.reshape(-1, 4)
    if len(flat) > _CHUNK:          # in blocks: they keep the (16, N) temporaries in cache
        return np.concatenate([_quantize(flat[i:i + _CHUNK]) for i in
                               range(0, len(flat), _CHUNK)]).reshape(q.shape)
    return _quantize(flat).reshape(q.shape)


#: rows per block of quantize_rotations
_CHUNK = 2048


def _quantize(q: np.ndarray) -> np.ndarray:
    """quantize_rotations of (N, 4) quaternions. The 16 candidate codes of each are rows of
    (16, N) arrays, so each step is one flat operation."""
    u = _unit(q)
    s = u * SHORT_MAX
    c = np.floor(s)
    n2 = _bit_sums(c)                                                    # |code|^2 / 32767^2
    n2 *= 2.0
    n2 += _dot(c, c)
    n2 += _BIT_COUNT
    n2 /= SHORT_MAX ** 2
    dot = _bit_sums(s)
    dot += _dot(s, c)
    dot /= SHORT_MAX ** 2
    cost = np.square(dot, out=dot)
    np.subtract(n2, cost, out=cost)
    np.maximum(cost, 0.0, out=cost)
    cost /= n2                                                           # sin^2(half angle)
    lever = 1.0 - u[:, 3] ** 2                                           # |R - I|^2 / 4
    n2 -= 1.0
    stretch = np.square(np.abs(n2, out=n2), out=n2)
    stretch *= lever
    cost += stretch
    out = c + np.take(_BITS.T, np.argmin(cost, axis=0), axis=0)
    return np.clip(out, -SHORT_MAX, SHORT_MAX, out=out).astype(np.int16)


#: (16, 1) how many components each of the 16 codes rounds up
_BIT_COUNT = np.sum(_BITS, axis=0)[:, None]


def _bit_sums(a: np.ndarray) -> np.ndarray:
    """(16, N): for each of the 16 codes k, the sum of the components of a (N, 4) whose bit is
    set in k (element by element, so a row's result does not depend on the batch)."""
    out = np.zeros((16, len(a)))
    for i in range(4):              # codes with bit i: the codes below 2^i, plus a[:, i]
        np.add(out[:1 << i], a[:, i], out=out[1 << i:2 << i])
    return out


def dequantize_rotations(codes: np.ndarray) -> np.ndarray:
    """(..., 4) float32 quaternions decoded from normalized SHORT codes, as glTF specifies:
    max(c / 32767, -1)."""
    return np.maximum(np.asarray(codes, dtype=np.float64) / SHORT_MAX, -1.0).astype(np.float32)


def sample(values: np.ndarray, keep: np.ndarray, static: np.ndarray, times: np.ndarray,
           rotation: bool) -> np.ndarray:
    """Reduced curves at every frame, as a player evaluates them.

    values   : (F, C, W) float32, the stored values (key values are values[key frame])
    keep     : (C, F) bool key frames; a channel with none is static
    static   : (C, W) the static channels' values
    times    : (F,) float32 seconds, the key times
    rotation : slerp (xyzw, the short way round) instead of lerp
    returns  : (F, C, W) float64
    """
    return _sample_cf(np.swapaxes(values, 0, 1), keep, static, times, rotation).swapaxes(0, 1)


def _segments(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(prev, nxt), each (C, F) int64, of key frames keep (C, F): the last key at or before
    each frame (-1: none) and the first key after it (F: none). A frame's played value depends
    on these two keys only. Compiled (replay.segments)."""
    return replay.segments(keep)


def _around(prev: np.ndarray, nxt: np.ndarray, frames: np.ndarray, times: np.ndarray,
            f_count: int) -> tuple:
    """The keys around frames `frames` (any shape) given their segments' key frames `prev` and
    `nxt` (`_segments`, read at those frames): (prev, nxt) clipped into the clip, alpha within
    the segment (float32 key times, as written), `fixed` (the channel has no key) and `last`
    (past the last key)."""
    fixed = prev < 0
    last = nxt >= f_count
    prev = np.minimum(np.maximum(prev, 0), f_count - 1)
    nxt = np.where(last, prev, nxt)
    t = np.asarray(times, dtype=np.float32).astype(np.float64)
    t_prev = t.take(prev)
    span = t.take(nxt) - t_prev
    a = np.where(span > 0, (t.take(frames) - t_prev) / np.where(span > 0, span, 1.0), 0.0)
    return prev, nxt, a, fixed, last


def _sample_cf(values: np.ndarray, keep: np.ndarray, static: np.ndarray, times: np.ndarray,
               rotation: bool) -> np.ndarray:
    """`sample` with channels first: values (C, F, W) -> (C, F, W) float64. Like three.js's
    interpolants, a frame on a key is evaluated on the segment that starts there (alpha 0; the
    rotation is normalized there when the next key is nearly equal), and the last key is
    returned as stored."""
    c_count, f_count = keep.shape
    prev, nxt = _segments(keep)
    prev, nxt, a, fixed, last = _around(prev, nxt, np.arange(f_count)[None, :], times, f_count)
    rows = np.arange(c_count)[:, None]
    v0 = values[rows, prev].astype(np.float64)
    v1 = values[rows, nxt].astype(np.float64)
    out = slerp(v0, v1, a) if rotation else v0 + a[..., None] * (v1 - v0)
    out = np.where(last[..., None], v0, out)
    return np.where(fixed[..., None], np.asarray(static, np.float64)[:, None, :], out)


def _inner(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(...) sum over the first axis of a * b (W, ...), component-first, summed left to right
    (into out): np.sum(a * b, axis=0) without its reduction overhead (the same value, up to the
    sign of an all-zero sum)."""
    out = np.multiply(a[0], b[0], out=out)
    tmp = np.empty(out.shape)
    for k in range(1, len(a)):
        out += np.multiply(a[k], b[k], out=tmp)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) np.sum(a * b, axis=-1) of (..., W) a, b (`_inner` over the last axis)."""
    return _inner(_last_first(a), _last_first(b))


def _last_first(a: np.ndarray) -> np.ndarray:
    """np.moveaxis(a, -1, 0), a view, without its overhead."""
    return a.transpose((a.ndim - 1,) + tuple(range(a.ndim - 1)))


def _norm(a: np.ndarray) -> np.ndarray:
    """(...) np.linalg.norm(a, axis=-1) of real (..., W) a, the same arithmetic (squares summed
    left to right) without the reduction overhead."""
    return np.sqrt(_dot(a, a))


def slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Quaternion slerp as three.js plays glTF (Quaternion.slerpFlat): the short way round,
    weights from the stored keys as they are (not renormalized), the result not normalized;
    for nearly equal keys (dot >= 0.9995) a lerp, normalized; equal keys give a as stored.
    a, b (..., 4), t (...)."""
    a, b = np.broadcast_arrays(np.asarray(a), np.asarray(b))
    return np.moveaxis(_slerp(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0), t), 0, -1)


def _slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """slerp of component-first quaternions a, b (4, ...): a new (4, ...) array."""
    if a.ndim != 2:                     # as (4, N) pairs
        t = np.broadcast_to(np.asarray(t, dtype=np.float64), a.shape[1:])
        return _slerp(a.reshape(4, -1), b.reshape(4, -1), t.reshape(-1)).reshape(a.shape)
    d = _inner(a, b)
    flip = d < 0.0
    if flip.any():
        b = np.negative(b, out=b.copy(), where=flip)
    d = np.abs(d, out=d)
    t = np.broadcast_to(np.asarray(t, dtype=np.float64), d.shape)
    near = d >= replay.NEAR_DOT
    wa, wb = 1.0 - t, t.copy()          # near: lerp weights (the result is normalized below)
    far = np.flatnonzero(~near)         # the sines only here (a third of the pairs are near)
    if len(far):
        theta = np.arccos(np.minimum(np.take(d, far), 1.0))
        s = np.sin(theta)
        tf = np.take(wb, far)
        np.put(wa, far, np.sin((1.0 - tf) * theta) / s)
        np.put(wb, far, np.sin(tf * theta) / s)
    out = a * wa
    out += np.multiply(b, wb, out=np.empty(out.shape))
    out /= np.where(near, np.sqrt(_inner(out, out)), 1.0)
    same = a[0] == b[0]                                               # three.js: a, as stored
    for k in range(1, 4):
        same &= a[k] == b[k]
    np.copyto(out, a, where=same)
    return out


def raw_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of xyzw quaternions (..., 4) by the unit-quaternion formula
    applied to q as stored, without normalizing (as three.js and UsdSkel do)."""
    m = _raw_matrix(np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0))
    return np.ascontiguousarray(np.moveaxis(m, (0, 1), (-2, -1)))


def _raw_matrix(q: np.ndarray) -> np.ndarray:
    """raw_matrix, component-first: (3, 3, ...) of (4, ...) float64 quaternions."""
    x, y, z, w = q
    m = np.empty((3, 3) + q.shape[1:])
    xx, yy, zz = x * x, y * y, z * z
    for (r, c), a, b, sign in (((0, 0), yy, zz, 0), ((1, 1), xx, zz, 0), ((2, 2), xx, yy, 0),
                               ((0, 1), x * y, z * w, -1), ((1, 0), x * y, z * w, 1),
                               ((0, 2), x * z, y * w, 1), ((2, 0), x * z, y * w, -1),
                               ((1, 2), y * z, x * w, -1), ((2, 1), y * z, x * w, 1)):
        o = np.subtract(a, b, out=m[r, c]) if sign < 0 else np.add(a, b, out=m[r, c])
        o *= 2
        if not sign:                    # the diagonal: 1 - 2 (yy + zz) ...
            np.subtract(1, o, out=o)
    return m


def _rotation_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) radians between xyzw rotations a and b (..., 4)."""
    return _angle(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0))


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """_rotation_error of component-first rotations a, b (4, ...)."""
    d = np.abs(_inner(a, b))
    d /= np.sqrt(_inner(a, a)) * np.sqrt(_inner(b, b))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0, out=d))


def _errors(values: np.ndarray, reduced: np.ndarray, rotation: bool) -> np.ndarray:
    """(C, F) error of each channel: metres (translations, scales) or radians (rotations).
    values, reduced (F, C, W)."""
    v = np.transpose(values, (2, 1, 0)).astype(np.float64, order="C")           # (W, C, F)
    r = np.transpose(reduced, (2, 1, 0))
    if rotation:
        return _angle(v, r)
    d = r - v
    return np.sqrt(_inner(d, d))


# ------------------------------------------------------------------------------- local pass


def _add_worst(keep: np.ndarray, score: np.ndarray, candidate: np.ndarray) -> int:
    """Add, in every segment between consecutive keys of every channel, a key at the candidate
    frame of the highest score (ties: the earliest). keep (C, F) is updated in place; a static
    channel (no key) that gets a key also gets its first and last frame. Returns the number of
    keys added."""
    f_count = keep.shape[1]
    cand = candidate & ~keep
    if not cand.any():
        return 0
    before = int(keep.sum())
    p = np.flatnonzero(cand)
    ci, fi = np.divmod(p, f_count)
    keys = np.flatnonzero(keep)             # the last key before each candidate, on its channel
    prev = np.full(len(p), -1)
    if len(keys):
        at = np.searchsorted(keys, p)
        prev = np.where(at > 0, keys.take(np.maximum(at - 1, 0)) - ci * f_count, -1)
        prev[prev < 0] = -1                 # on an earlier channel: none
    _key_worst(keep, ci, fi, ci * (f_count + 1) + prev + 1, score.reshape(-1).take(p))
    _close(keep)
    return int(keep.sum()) - before


def _key_worst(keep: np.ndarray, ci: np.ndarray, fi: np.ndarray, group: np.ndarray,
               score: np.ndarray) -> None:
    """Key, in each group (segment) of the candidate pairs (ci, fi), the pair of the highest
    score (ties: the earliest frame). The pairs come in np.nonzero's order, so each group is a
    run of consecutive pairs, frames ascending. In place."""
    if not len(ci):
        return
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    top = np.maximum.reduceat(score, starts)
    best = np.flatnonzero(score == np.repeat(top, np.diff(np.r_[starts, len(score)])))
    first = best[np.r_[True, group[best][1:] != group[best][:-1]]]
    keep[ci[first], fi[first]] = True


def _close(keep: np.ndarray) -> None:
    """Animated channels keep their first and last frame (in place)."""
    animated = keep.any(axis=1)
    keep[animated, 0] = True
    keep[animated, -1] = True


def _local_keys(values: np.ndarray, stored: np.ndarray, times: np.ndarray, rotation: bool,
                tol: np.ndarray, preferred: np.ndarray | None,
                value_bytes: int) -> tuple[np.ndarray, np.ndarray]:
    """Top-down Douglas-Peucker over all channels at once, each within its own tolerance tol (C,)
    (metres or radians) of `values` (F, C, W), interpolating `stored` (the values the file
    holds). A channel within tol of one value is static: `preferred` (C, W) (the rest pose) when
    that is close enough, else its frame-0 value. Returns (keep (C, F), static (C, W)).

    The splitting is compiled (baker.export.keyfit), channel by channel. A channel that ends
    with more keys than `_promote(keep, value_bytes)` keeps as they are is keyed at every
    frame: at once when more frames than that are off even between their two neighbours
    (keyfit.tight_misses, a channel that cannot do without most of its frames), else as soon as its
    keys pass the bound (keys only grow)."""
    f_count, c_count, _ = values.shape
    first = np.asarray(values[0], dtype=np.float32)
    static = first.copy()
    is_static = np.zeros(c_count, dtype=bool)
    for value in ([first] if preferred is None else [np.asarray(preferred, np.float32), first]):
        rows = np.flatnonzero(~is_static)           # the channels not static yet
        if not len(rows):
            break
        sub = np.take(values, rows, axis=1)
        held = np.broadcast_to(np.asarray(value, np.float64)[rows][None], sub.shape)
        ok = rows[_errors(sub, held, rotation).max(axis=1) <= tol[rows]]
        static[ok] = value[ok]
        is_static[ok] = True
    keep = np.zeros((c_count, f_count), dtype=bool)
    vals = np.ascontiguousarray(np.swapaxes(values, 0, 1), dtype=np.float64)   # (C, F, W)
    kept = vals if stored is values else np.ascontiguousarray(np.swapaxes(stored, 0, 1),
                                                              dtype=np.float64)
    bound = value_bytes * f_count / (value_bytes + TIME_BYTES)      # _promote's key count
    active = np.flatnonzero(~is_static)
    dense = keyfit.tight_misses(vals, kept, times, rotation, tol, active) > bound
    keep[active[dense]] = True
    keyfit.fit_channels(vals, kept, times, rotation, tol, active[~dense], bound, keep)
    return keep, static


# ------------------------------------------------------------------------------- hierarchy


def ancestors(parents) -> np.ndarray:
    """(J, D) int64: row k lists joint k, its parent, its grandparent ... up to the root, padded
    with -1 (D: the longest chain). Read-only (kept for the next call with the same parents)."""
    parents = np.asarray(parents)
    key = (parents.dtype.str, parents.tobytes())
    out = _ANCESTORS.get(key)
    if out is None:
        out = _ancestors(parents)
        out.setflags(write=False)
        if len(_ANCESTORS) > 16:
            _ANCESTORS.clear()
        _ANCESTORS[key] = out
    return out


#: `ancestors` by parents array
_ANCESTORS: dict = {}


def _ancestors(parents: np.ndarray) -> np.ndarray:
    chains = []
    for k in range(len(parents)):
        c = [k]
        while parents[c[-1]] >= 0:
            c.append(int(parents[c[-1]]))
        chains.append(c)
    out = np.full((len(parents), max(map(len, chains))), -1, dtype=np.int64)
    for k, c in enumerate(chains):
        out[k, :len(c)] = c
    return out


def levers(parents, world: np.ndarray, local_t: np.ndarray) -> np.ndarray:
    """(J,) metres: how far a rotation of each joint can move a joint below it (the largest
    distance from it to any of its descendants over all frames), at least its own bone length
    (the geometry it carries). world (F, J, 3) positions, local_t (F, J, 3) local translations."""
    parents = np.asarray(parents)
    out = np.linalg.norm(local_t, axis=-1).max(axis=0) * (parents >= 0)
    world = np.ascontiguousarray(np.swapaxes(world, 0, 1))                     # (J, F, 3)
    if world.shape[1]:                              # each joint's reach to its ancestors
        keyfit.reach(ancestors(parents), world, out)
    return out


def _rotvec(q: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (axis x angle, radians) of xyzw quaternions (..., 4)."""
    q = np.where(q[..., 3:4] < 0, -q, q)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:4])
    return q[..., :3] * np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0)


# ------------------------------------------------------------------------------- world pass
# Arrays here are joints first, (J, F, ...), so a level of the skeleton is a block of rows.


@dataclass(frozen=True)
class _Target:
    """The unreduced clip, joints first: local t0 (J, F, 3), q0 (J, F, 4) float64, world pos0
    (J, F, 3), wq0 (J, F, 4); times (F,); parents (J,); levels: the skeleton's depth levels
    (joint index arrays, parents in earlier levels); planted (J, F) bool or None; the tolerance
    [m]; whether rotations are stored as SHORT."""

    t0: np.ndarray
    q0: np.ndarray
    pos0: np.ndarray
    wq0: np.ndarray
    times: np.ndarray
    parents: np.ndarray
    levels: tuple
    planted: np.ndarray | None
    tol: float
    short: bool
    tight: np.ndarray | None = None
    rigid: tuple | None = None


def _target(clip: Clip, parents, planted, tol: float, short: bool, tight=None) -> _Target:
    parents = np.asarray(parents)
    depth = (ancestors(parents) >= 0).sum(axis=1)
    levels = tuple(np.flatnonzero(depth == d) for d in range(1, depth.max() + 1))
    t0, q0, pos0, wq0 = replay.unreduced(np.concatenate(levels), parents, clip.translations,
                                         clip.rotations)       # forward_kinematics' bits
    first = (lambda a: np.ascontiguousarray(np.swapaxes(a, 0, 1)))
    return _Target(t0, q0, pos0, wq0, clip.times, parents, levels,
                   None if planted is None else first(planted), tol, short,
                   None if tight is None else first(tight),
                   rigid_bones(clip.translations.astype(np.float64), parents))


def rigid_bones(t0: np.ndarray, parents: np.ndarray) -> tuple | None:
    """(joints (R,), lengths (R,)) of the non-root joints whose local translation t0 (F, J, 3)
    turns while keeping one length (within RIGID_SPREAD of it), or None."""
    if len(t0) < 2:
        return None
    n = np.linalg.norm(t0, axis=-1)                                  # (F, J)
    length = n.mean(axis=0)
    turns = np.ptp(t0, axis=0).max(axis=-1) > RIGID_SPREAD * length
    j = np.flatnonzero((parents >= 0) & (length > 0) & turns
                       & (np.ptp(n, axis=0) <= RIGID_SPREAD * length))
    return (j, length[j]) if len(j) else None


def _unit(q: np.ndarray) -> np.ndarray:
    return q / _norm(q)[..., None]


class _Player:
    """Compensated playback of a reduction, kept from one round to the next (all arrays joints
    first, (J, F, ...)): level by level down the skeleton, each joint's key values are the local
    transforms that put it exactly on its unreduced world pose relative to its *reduced* parent
    (so a parent's interpolation error is not passed on at the child's keys); its curves are
    sampled between the keys as players do and posed with the players' matrices (raw_matrix:
    stored quaternions are not renormalized), and as the two other players pose them (see
    baker.export.replay).

    `play` recomputes only the (joint, frame) pairs whose result can change since the last play:
    frames whose segment (the keys around them) changed, frames whose segment's stored key
    values changed (bit for bit), and frames whose parent moved. The arrays then hold exactly
    what a first play of the same keys gives.

    Stored key values vt (J, F, 3), vq (J, F, 4) float32 and codes (J, F, 4) int16 (SHORT
    rotations) and their targets tt, tq (float64; codes are requantized only where tq changed),
    at the key frames (the players read no others; `complete` fills in the rest). Joints first
    too, (J, F, W) (a pair's components side by side for the compiled kernels): the played
    local tr (3), rr (4) (float32 values as float64) and Blender's nlerp (4); world positions
    pos (3), rotations wq (4) (the matrices' rotation part) and matrices mat (J, F, 3, 3); the
    other players' poses (unit (3): renormalized slerp; blender (3), wn (4): nlerp); error
    vectors diff (3). And (J, F): the
    error lengths err [m], the worst of the three players; slide (J, F-1) [m]: the change
    of a planted joint's error between planted frames; spread (J, F) [m]: how far the other two
    players are from the first; viol (J, F) bool: over a bound."""

    def __init__(self, x: _Target, static_t: np.ndarray, static_r: np.ndarray):
        j_count, f_count = x.t0.shape[:2]
        self.x, self.static_t, self.static_r = x, static_t, static_r

        def empty(*shape, dtype=np.float64):
            return np.zeros((j_count, f_count) + shape, dtype)

        self.vt, self.vq = empty(3, dtype=np.float32), empty(4, dtype=np.float32)
        self.codes = empty(4, dtype=np.int16)
        self.tt, self.tr, self.rr = empty(3), empty(3), empty(4)
        self.tq = np.full((j_count, f_count, 4), np.nan)     # NaN: none quantized yet
        self.pos, self.wq, self.mat = empty(3), empty(4), empty(3, 3)
        self.nlerp, self.unit, self.blender, self.wn = empty(4), empty(3), empty(3), empty(4)
        self.diff, self.err, self.spread = empty(3), empty(), empty()
        self.pos0 = np.ascontiguousarray(x.pos0)
        self.slide = np.zeros((j_count, max(f_count - 1, 0)))
        self.viol = np.zeros((j_count, f_count), dtype=bool)
        self.segments = None        # ((segments, keys) of translations, of rotations) last played
        self.order = np.concatenate(x.levels)              # the joints, parents first
        if x.planted is not None:   # the joints planted at two frames in a row, and those pairs
            both = x.planted[:, 1:] & x.planted[:, :-1]
            feet = np.flatnonzero(both.any(axis=1))
            self.planted_pairs = feet, both[feet]

    def play(self, keep_t: np.ndarray, keep_r: np.ndarray) -> np.ndarray:
        """Play the keys keep_t, keep_r (J, F) bool; returns viol."""
        x = self.x
        j_count, f_count = x.t0.shape[:2]
        first = self.segments is None
        if first:
            self.segments = ((_segments(keep_t), keep_t.copy()),
                             (_segments(keep_r), keep_r.copy()))
            dirty_t = dirty_r = np.ones((j_count, f_count), dtype=bool)
            new_t, new_r = keep_t, keep_r
        else:
            dirty_t, new_t = replay.resegment(*self.segments[0], keep_t)
            dirty_r, new_r = replay.resegment(*self.segments[1], keep_r)
        moved = np.zeros((j_count, f_count), dtype=bool)       # world position changed
        turned = np.zeros((j_count, f_count), dtype=bool)      # world rotation changed
        # key values where the parent moved or the key is new, then the frames played from a
        # changed segment or a key whose stored value changed (a new key's frames are dirty:
        # their segment changed), then the poses there and below (compiled, in one call)
        replay.play_levels(x, self, keep_t, keep_r, new_t, new_r, dirty_t, dirty_r, first,
                           moved, turned)
        self._slide_at(moved)
        self.viol = replay.violations(
            self.err, self.spread, x.tight, self.slide if x.planted is not None else None,
            (x.tol, PLAYER_SPREAD_M, TIGHT_SHARE * x.tol, PLANTED_SLIDE * x.tol))
        return self.viol

    def stretched(self) -> np.ndarray:
        """(J, F) bool: the rigid bones (x.rigid) whose played length is off by more than
        LENGTH_SHARE of it."""
        out = np.zeros(self.viol.shape, dtype=bool)
        if self.x.rigid is not None:
            j, length = self.x.rigid
            tr = np.take(self.tr, j, axis=0)                                      # (R, F, 3)
            played = np.sqrt(sum(tr[..., k] ** 2 for k in range(3)))              # (R, F)
            out[j] = np.abs(played - length[:, None]) > LENGTH_SHARE * length[:, None]
        return out

    def complete(self, keep_t: np.ndarray, keep_r: np.ndarray) -> None:
        """Fill in the key values (and targets) of the frames that are not keys, keep_t,
        keep_r (J, F) the last played keys: `play` computes them at key frames only (the
        players read no others), the files store every frame's."""
        for level in self.x.levels:
            self._targets(level, ~keep_t[level], ~keep_r[level])

    def _targets(self, level: np.ndarray, target_t: np.ndarray, target_r: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The key values of the joints `level`: translations at the frames target_t, rotations
        at the frames target_r (L, F) bool (new keys, and keys where the parent's pose, or only
        its rotation, moved); SHORT codes requantized only where the target changed. Returns
        ((L, F), (L, F)) bool: the frames whose stored value vt, vq changed (bit for bit)."""
        return replay.targets_level(level, self.x.parents, target_t, target_r, self.x.short,
                                    self.x, self)

    def _slide_at(self, moved: np.ndarray) -> None:
        """slide at the planted frame pairs (f, f + 1) with a moved frame."""
        x = self.x
        f_count = moved.shape[1]
        if x.planted is None or f_count < 2:
            return
        replay.slide_at(*self.planted_pairs, moved, self)        # compiled


def _blame(x: _Target, chains: np.ndarray, p: _Player):
    """Which channels to key where (see the module docstring). Returns (candidates, scores) for
    the translation channels and for the rotation channels, each (J, F); scores in metres.
    The offending pairs are blamed in blocks of about BLAME_PAIRS (pair, ancestor) entries
    (a long skeleton's chains times a clip's worth of pairs were gigabytes at once in numpy;
    compiled, a block's distinct pairs are); each block adds its candidates and raises the
    scores (a maximum), so blocks change nothing."""
    j_count, f_count = p.viol.shape
    ki, fi = np.nonzero(p.viol)
    out = [np.zeros((j_count, f_count), dtype=bool), np.zeros((j_count, f_count)),
           np.zeros((j_count, f_count), dtype=bool), np.zeros((j_count, f_count))]
    step = max(1, BLAME_PAIRS // chains.shape[1])
    for v0 in range(0, len(ki), step):
        _blame_block(x, chains, p, ki[v0:v0 + step], fi[v0:v0 + step], out)
    return out


#: (offending pair, ancestor) entries blamed at once (_blame)
BLAME_PAIRS = 1 << 20


def _blame_block(x: _Target, chains: np.ndarray, p: _Player, ki, fi, out: list) -> None:
    """_blame for the offending pairs (ki, fi): into out = [translation candidates, scores,
    rotation candidates, scores] (in place). The channels' moves (the world offset of each
    translation channel's error, and each rotation channel's error as a world rotation vector)
    are computed once per distinct (ancestor, frame) pair, each entry's share of the error and
    the keys it asks for once per (pair, ancestor) entry: compiled (replay.blame_moves,
    blame_pairs: geometry.transforms' quaternion arithmetic, np.einsum's sums), but for the
    rotation vectors (`_rotvec`: numpy's arctan2 is not the compiled one, bit for bit)."""
    slot, i = replay.blame_slots(ki, fi, chains, p.viol.shape)
    c_t, err_q, wp = replay.blame_moves(i, x, p)
    replay.blame_pairs(ki, fi, chains, slot, p.diff, p.pos, c_t, _rotvec(err_q), wp,
                       BLAME_SHARE, out)


def _refine(x: _Target, keep_t: np.ndarray, keep_r: np.ndarray, player: _Player) -> _Player:
    """World refinement (see the module docstring): adds keys to keep_t, keep_r (J, F) in place
    until no joint is off. Returns the player, holding the final playback."""
    chains = ancestors(x.parents)
    for _ in range(MAX_ROUNDS):
        viol = player.play(keep_t, keep_r)
        if not viol.any():
            stretch = player.stretched()
            if not stretch.any():
                return player
            added = _key_stretched(keep_t, keep_r, x.parents, chains, stretch)
        else:
            cand_t, score_t, cand_r, score_r = _blame(x, chains, player)
            added = _add_worst(keep_t, score_t, cand_t) + _add_worst(keep_r, score_r, cand_r)
            if added == 0:      # only rounding is left: key the offending chains there
                added = _key_chains(keep_t, keep_r, chains, viol)
        if added == 0:
            raise ExportError(f"keyframe reduction cannot reach the --tolerance of {x.tol:g} "
                              f"m: the stored values alone are off by {player.err.max():.3g} "
                              "m; give --tolerance 0 (every key kept) or a larger one",
                              where="--tolerance")
    raise ExportError("keyframe reduction did not converge")


def _key_stretched(keep_t: np.ndarray, keep_r: np.ndarray, parents: np.ndarray,
                   chains: np.ndarray, stretch: np.ndarray) -> int:
    """Every joint within the tolerance, some rigid bones' lengths not (`stretch` (J, F)): key
    each such bone's translation there, or where it is a key already (its compensated value is
    off by its parent's error), its parent's chain. In place; returns how many keys were added."""
    before = int(keep_t.sum())
    own = stretch & ~keep_t
    keep_t |= own
    _close(keep_t)
    added = int(keep_t.sum()) - before
    j, f = np.nonzero(stretch & ~own)
    if len(j):
        up = np.zeros_like(stretch)
        up[parents[j], f] = True
        added += _key_chains(keep_t, keep_r, chains, up)
    return added


def _key_chains(keep_t: np.ndarray, keep_r: np.ndarray, chains: np.ndarray,
                where: np.ndarray) -> int:
    """Key every channel of the chains of the (joint, frame) pairs `where` (J, F) at their
    frames, in place; returns how many keys were added."""
    ki, fi = np.nonzero(where)
    ch = chains[ki]
    v, d = np.nonzero(ch >= 0)
    added = 0
    for keep in (keep_t, keep_r):
        before = int(keep.sum())
        keep[ch[v, d], fi[v]] = True
        _close(keep)
        added += int(keep.sum()) - before
    return added


def _promote(keep: np.ndarray, value_bytes: int) -> None:
    """Key every frame of the channels whose own key set (values + a time accessor of their
    own) would cost more bytes than every frame (values only: the full time accessor is
    shared). In place."""
    n = keep.sum(axis=1)
    f_count = keep.shape[1]
    keep[(n > 0) & ((value_bytes + TIME_BYTES) * n > value_bytes * f_count)] = True


# ------------------------------------------------------------------------------- entry points


def _track_keys(clip: Clip, tol: float, lever: float, short: bool) -> tuple[TrackKeys, ...]:
    """Each node track's channels reduced on their own (see the module docstring)."""
    out = []
    for tr in clip.tracks:
        parts = {}
        for path, values, rot, scale in (("translations", tr.translations, False, 1.0),
                                         ("rotations", tr.rotations, True, lever),
                                         ("scales", tr.scales, False, lever)):
            if values is None:
                continue
            v = np.asarray(values, dtype=np.float32)[:, None, :]
            codes = quantize_rotations(v) if rot and short else None
            stored = v if codes is None else dequantize_rotations(codes)
            value_bytes = VALUE_BYTES["rotation_short" if codes is not None else
                                      "rotation" if rot else "scale"]
            keep, static = _local_keys(v, stored, clip.times, rot,
                                       np.array([tol / max(scale, 1e-9)]), None, value_bytes)
            _promote(keep, value_bytes)
            parts[path] = Keys(keep, stored, static, codes)
        out.append(TrackKeys(**parts))
    return tuple(out)


def reduce_clip(clip: Clip, parents, tolerance_m: float, *, contacts=None,
                rest: tuple[np.ndarray, np.ndarray] | None = None,
                short_rotations: bool = False, tight=None) -> Clip:
    """`clip` with `keys` set (a ClipKeys): keys whose playback keeps every joint within
    `tolerance_m` of its unreduced world position at every frame (the two passes of the module
    docstring). reduce_plan's arguments; its pieces refined here one after the other.
    tolerance_m 0 returns the clip with keys None (every frame is a key)."""
    plan = reduce_plan(clip, parents, tolerance_m, contacts=contacts, rest=rest,
                       short_rotations=short_rotations, tight=tight)
    if plan is None:
        return dataclasses.replace(clip, keys=None)
    return plan.finish([plan.piece(i) for i in range(plan.pieces)])


def reduce_plan(clip: Clip, parents, tolerance_m: float, *, contacts=None,
                rest: tuple[np.ndarray, np.ndarray] | None = None,
                short_rotations: bool = False, tight=None, split: bool = False):
    """The local pass of reduce_clip, and its world refinement to come as a ReducePlan (None
    for tolerance_m 0): plan.finish([plan.piece(i) for i in range(plan.pieces)]) is the
    reduced clip, the pieces refined anywhere (each on a process of its own: baker.parallel).

    parents         : (J,) int, the skeleton's parents array (parents first)
    tolerance_m     : [m] >= 0
    contacts        : (F, J) bool, frames at which a joint is planted (feet in stance), or None
    rest            : ((J, 3) translations, (J, 4) xyzw rotations): the values static channels
                      take when they are within tolerance (so the nodes keep their rest TRS)
    short_rotations : store animated rotations as normalized SHORT (see the module docstring),
                      unless the quantization alone would use more than half the tolerance
    tight           : (F, J) bool or None: frames at which a joint keeps within TIGHT_SHARE of
                      the tolerance (a bone passing that close to the environment, see
                      bones_near, must not be moved into it)
    split           : refine a clip of more than PIECE_FRAMES frames in pieces (piece_bounds)
    """
    tol = float(tolerance_m)
    if not np.isfinite(tol) or tol < 0:
        raise ExportError(f"reduction tolerance must be a finite number >= 0 (got {tolerance_m})")
    if tol == 0:
        return None
    parents = np.asarray(parents)
    f_count, j_count = clip.translations.shape[:2]
    if len(parents) != j_count:
        raise ExportError(f"clip has {j_count} joints, the parents array {len(parents)}")
    planted = None
    if contacts is not None:
        planted = np.asarray(contacts, dtype=bool)
        if planted.shape != (f_count, j_count):
            raise ExportError(f"contacts have shape {planted.shape}, expected "
                              f"({f_count}, {j_count})")
    if tight is not None and np.shape(tight) != (f_count, j_count):
        raise ExportError(f"tight frames have shape {np.shape(tight)}, expected "
                          f"({f_count}, {j_count})")
    x = _target(clip, parents, planted, tol, short_rotations,
                None if tight is None else np.asarray(tight, dtype=bool))
    if short_rotations and not _short_fits(x):
        x = dataclasses.replace(x, short=False)
    lever = np.maximum(levers(parents, np.swapaxes(x.pos0, 0, 1), clip.translations), 1e-9)
    r_t, r_q = (None, None) if rest is None else rest
    share = _local_share(parents, tol)
    rot_bytes = VALUE_BYTES["rotation_short" if x.short else "rotation"]
    keep_t, static_t = _local_keys(clip.translations, clip.translations, clip.times, False,
                                   share, r_t, VALUE_BYTES["translation"])
    keep_r, static_r = _local_keys(clip.rotations, clip.rotations, clip.times, True,
                                   share / lever, r_q, rot_bytes)
    keep_s, static_s = _local_keys(clip.scales, clip.scales, clip.times, False, tol / lever,
                                   np.ones((j_count, 3), np.float32), VALUE_BYTES["scale"])
    _promote_joints(keep_t, keep_r, x.short)
    bounds = piece_bounds(f_count) if split else np.array([0, f_count - 1])
    for keep in (keep_t, keep_r):                   # every piece starts and ends on a key
        keep[np.ix_(keep.any(axis=1), bounds)] = True
    return ReducePlan(clip, x, lever, (keep_t, keep_r, keep_s), (static_t, static_r, static_s),
                      bounds)


def piece_bounds(f_count: int) -> np.ndarray:
    """(n + 1,) the first frame of each of the n pieces a clip of f_count frames is refined in
    (reduce_plan's `split`), then its last frame: pieces of at most PIECE_FRAMES frames after
    their first (consecutive pieces share their seam frame), as even as may be."""
    n = max(1, -(-(f_count - 1) // PIECE_FRAMES))
    return np.round(np.linspace(0, max(f_count - 1, 0), n + 1)).astype(np.int64)


@dataclass
class ReducePlan:
    """A keyframe reduction whose world refinement is to come (reduce_plan): the clip, its
    _Target x, the joints' levers, the local pass's keys (keep_t, keep_r, keep_s), the static
    values (static_t, static_r, static_s) and the pieces' bounds (piece_bounds)."""

    clip: Clip
    x: "_Target"
    lever: np.ndarray
    keeps: tuple
    statics: tuple
    bounds: np.ndarray

    @property
    def pieces(self) -> int:
        return len(self.bounds) - 1

    def piece(self, i: int) -> tuple:
        """(keep_t, keep_r, player) of piece i (its frames bounds[i] to bounds[i + 1]). One
        piece: the whole clip's world refinement, its key counts promoted, refined again
        (_settled), and its player. Several: the piece's world refinement on its own (the promotion
        is the whole clip's, in finish), without the player."""
        a, b = int(self.bounds[i]), int(self.bounds[i + 1]) + 1
        keep_t, keep_r = (k[:, a:b].copy() for k in self.keeps[:2])
        if self.pieces > 1:
            x = _frames_of(self.x, a, b)
            _refine(x, keep_t, keep_r, _Player(x, *self.statics[:2]))
            return keep_t, keep_r, None
        player = _Player(self.x, *self.statics[:2])
        return keep_t, keep_r, _settled(self.x, keep_t, keep_r, player)

    def finish(self, pieces: list) -> Clip:
        """The reduced clip from the pieces' results (piece(i) for every i, in order). Several
        pieces' keys are played over the whole clip, promoted and refined: the pieces hold on
        their own, so the whole clip's refinement adds keys only for the promotion, where a
        seam's key values differ in their last bits (a key frame's played rotation depends on
        the key after it, which the piece before the seam does not have), or where a channel
        static in the local pass got keys in some pieces (keyed at the clip's ends, it is no
        longer the static value in the others)."""
        x, clip = self.x, self.clip
        keep_t, keep_r, p = pieces[0]             # p: the player of the final playback
        if self.pieces > 1:
            keep_t, keep_r = (k.copy() for k in self.keeps[:2])
            for a, b, (kt, kr, _) in zip(self.bounds[:-1], self.bounds[1:] + 1, pieces):
                keep_t[:, a:b] |= kt
                keep_r[:, a:b] |= kr
            # a channel static in the local pass that a piece keyed keeps the clip's ends too
            # (players hold the first key before it: the piece before kept the static value)
            _close(keep_t)
            _close(keep_r)
            p = _settled(x, keep_t, keep_r, _Player(x, *self.statics[:2]))
        keep_s = self.keeps[2]
        _promote(keep_s, VALUE_BYTES["scale"])
        static_t, static_r, static_s = self.statics
        p.complete(keep_t, keep_r)
        keys = ClipKeys(
            translations=Keys(keep_t, _frames_first(p.vt), static_t),
            rotations=Keys(keep_r, _frames_first(p.vq), static_r,
                           _frames_first(p.codes) if x.short else None),
            scales=Keys(keep_s, np.asarray(clip.scales, np.float32), static_s),
            tracks=_track_keys(clip, x.tol, float(self.lever.max()), x.short),
            tolerance_m=x.tol, max_error_m=float(p.err.max(initial=0.0)),
            max_slide_m=float(p.slide.max(initial=0.0)), short_rotations=x.short,
            max_spread_m=float(p.spread.max(initial=0.0)))
        return dataclasses.replace(clip, keys=keys)


def _promote_joints(keep_t: np.ndarray, keep_r: np.ndarray, short: bool) -> None:
    """_promote of the joints' translation and rotation keys (in place)."""
    _promote(keep_t, VALUE_BYTES["translation"])
    _promote(keep_r, VALUE_BYTES["rotation_short" if short else "rotation"])


def _settled(x: "_Target", keep_t: np.ndarray, keep_r: np.ndarray, player: "_Player"
             ) -> "_Player":
    """The world refinement of keep_t, keep_r (in place), their key counts promoted
    (_promote_joints), refined again; returns the player holding the final playback."""
    _refine(x, keep_t, keep_r, player)
    _promote_joints(keep_t, keep_r, x.short)
    return _refine(x, keep_t, keep_r, player)


def _frames_of(x: "_Target", a: int, b: int) -> "_Target":
    """x over its frames a to b - 1 (a piece of the clip), contiguous."""
    def cut(arr):
        return None if arr is None else np.ascontiguousarray(arr[:, a:b])

    return dataclasses.replace(x, t0=cut(x.t0), q0=cut(x.q0), pos0=cut(x.pos0), wq0=cut(x.wq0),
                               times=np.ascontiguousarray(x.times[a:b]), planted=cut(x.planted),
                               tight=cut(x.tight))


def _local_share(parents: np.ndarray, tol: float) -> np.ndarray:
    """(J,) [m] each joint's local-pass tolerance: LOCAL_SHARE * tol, divided by depth /
    DEPTH_SHARED for a joint deeper than DEPTH_SHARED. Between keys the errors of all its
    ancestors add up at a joint; on a 255-segment body the world refinement otherwise found
    about half of all (joint, frame) pairs off and blamed each over its 258 ancestors."""
    depth = (ancestors(parents) >= 0).sum(axis=1)
    return LOCAL_SHARE * tol / np.maximum(1.0, depth / DEPTH_SHARED)


def _frames_first(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.swapaxes(a, 0, 1))


def _short_fits(x: _Target) -> bool:
    """Whether 16-bit rotations, every frame keyed, stay within half the tolerance, and the
    players (which do or do not renormalize the stored quaternions) within half of
    PLAYER_SPREAD_M of each other."""
    j_count, f_count = x.t0.shape[:2]
    some = np.arange(0, f_count, 8)         # every frame a key: frames are independent
    sub = dataclasses.replace(x, t0=np.take(x.t0, some, axis=1), q0=np.take(x.q0, some, axis=1),
                              pos0=np.take(x.pos0, some, axis=1),
                              wq0=np.take(x.wq0, some, axis=1), times=x.times[some],
                              planted=None, tight=None)     # contiguous
    every = np.ones((j_count, len(some)), dtype=bool)
    p = _Player(sub, np.zeros((j_count, 3)), np.zeros((j_count, 4)))
    p.play(every, every)
    return bool(p.err.max(initial=0.0) <= 0.5 * x.tol
                and p.spread.max(initial=0.0) <= 0.5 * PLAYER_SPREAD_M)


# ------------------------------------------------------------------------------- accounting


def clip_key_count(clip: Clip) -> int:
    """Keys the clip's animation holds: every channel's kept keys, or, without keys, every
    frame of the channels an unreduced export writes (joint translations and rotations, joint
    scales when they are not all ones, and each track path)."""
    if clip.keys is not None:
        return clip.keys.count()
    f_count, j_count = clip.translations.shape[:2]
    per_joint = 2 + (0 if np.all(clip.scales == 1.0) else 1)
    paths = sum(v is not None for t in clip.tracks for v in (t.translations, t.rotations,
                                                             t.scales))
    return f_count * (j_count * per_joint + paths)


def glb_animation_bytes(clip: Clip) -> int:
    """Bytes of the clip's glTF animation data as build_glb writes it alone in a file: every
    sampler output, plus one time accessor per distinct key set (static channels write nothing:
    their value is the node's TRS). Without keys, every frame of every channel."""
    f_count = clip.n_frames
    k = clip.keys
    if k is None:
        per_frame = clip.n_joints * (12 + 16 + (0 if np.all(clip.scales == 1.0) else 12))
        per_frame += sum(b for t in clip.tracks for v, b in ((t.translations, 12),
                                                              (t.rotations, 16),
                                                              (t.scales, 12)) if v is not None)
        return f_count * (TIME_BYTES + per_frame)
    rot = "rotation_short" if k.short_rotations else "rotation"
    total, sets = 0, set()
    groups = [(k.translations, "translation"), (k.rotations, rot), (k.scales, "scale")]
    groups += [(keys, rot if path == "rotation" else path) for t in k.tracks
               for path, keys in t.parts()]
    for keys, kind in groups:
        n = keys.keep.sum(axis=1)
        total += VALUE_BYTES[kind] * int(n.sum())
        sets.update(row.tobytes() for row in keys.keep[n > 0])
    return total + TIME_BYTES * sum(int(np.frombuffer(s, dtype=bool).sum()) for s in sets)


def reduction_stats(before: Clip, after: Clip) -> dict:
    """The report's `animation` numbers for one clip: keys and GLB animation bytes before and
    after reduction, the tolerance and the measured errors (metres)."""
    k = after.keys
    b0, b1 = glb_animation_bytes(before), glb_animation_bytes(after)
    return {
        "tolerance_m": 0.0 if k is None else k.tolerance_m,
        "keys_before": clip_key_count(before),
        "keys_after": clip_key_count(after),
        "bytes_before": b0,
        "bytes_after": b1,
        "ratio": round(b0 / b1, 3) if b1 else None,
        "max_error_m": 0.0 if k is None else k.max_error_m,
        "planted_slide_max_m": 0.0 if k is None else k.max_slide_m,
        "players_max_spread_m": 0.0 if k is None else k.max_spread_m,
        "rotations": "short" if k is not None and k.short_rotations else "float",
    }


def played_joints(clip: Clip) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The clip's joint channels as a player evaluates them from its keys at every frame:
    (F, J, 3) translations, (F, J, 4) xyzw rotations, (F, J, 3) scales, float32. Without keys,
    the clip's own arrays."""
    k = clip.keys
    if k is None:
        return clip.translations, clip.rotations, clip.scales
    return (k.translations.play(clip.times, False), k.rotations.play(clip.times, True),
            k.scales.play(clip.times, False))


def bones_near(starts: np.ndarray, ends: np.ndarray, rays, margin: float, end_gap: float
               ) -> np.ndarray:
    """(F, B) bool: the frames at which each bone passes within about `margin` of the
    environment. A reduced pose moves each joint by up to the tolerance, so such a bone could be
    moved into what the unreduced one just clears.

    starts, ends : (F, B, 3) unreduced bone ends in the frame of `rays` (a RayCaster)
    margin : [m] the rays along each bone are offset by this much, 4 ways, and cast with it
    end_gap: [m] the rays stop this short of the bone's end (a foot's tip bone ends on the
             ground)
    """
    v = ends - starts
    length = np.linalg.norm(v, axis=-1)
    d = v / np.maximum(length, 1e-12)[..., None]
    side = np.cross(d, np.array([0.0, 1.0, 0.0]))
    weak = np.linalg.norm(side, axis=-1) < 1e-6
    side[weak] = np.cross(d[weak], np.array([1.0, 0.0, 0.0]))
    side /= np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-12)
    other = np.cross(d, side)
    reach = np.maximum(length - end_gap, 0.0).reshape(-1)
    hit = np.zeros(length.shape, dtype=bool)
    if hit.size == 0:
        return hit
    for off in (np.zeros_like(side), side, -side, other, -other):
        # first_hit's hits, without the points and normals it would build
        hit |= rays.occluded((starts + margin * off).reshape(-1, 3), d.reshape(-1, 3),
                             reach).reshape(length.shape)
    return hit
