"""Exact loops and one-shots on a rooted skeleton: window planning, the seam measure, residual
distribution and blending in joint space (pure numpy; used by baker/cycles and its tests).

Definitions (a loop clip has keys 0..N; key N is the frame one cycle after key 0, so the loop
closes when key N repeats key 0's pose and an engine wraps from N to 0):
- root-relative positions: p[f, j] = R_root[f]^T (x[f, j] - x_root[f]), the position of joint j
  seen from the root joint (its translation and yaw);
- seam error = max_j |p[N, j] - p[0, j]| [m];
- velocity mismatch: the loop as played moves through its seam with the simulation's own
  velocities. Arriving at the seam it moves from key N-1 to key N, and the simulation arrived
  at the window's first frame from its frame -1; leaving the seam it moves from key 0 to key 1,
  and the simulation left the window's last frame N for N+1 (the uncut simulation). A
  velocity is a joint's step over the ground seen from the root at the step's start (so the
  root's own translation and yaw count too). The mismatch is the largest difference over
  joints and both sides, divided by the fastest joint step there: 0.02 means the velocities
  at the first and the last frame agree within 2%. (Comparing key 1 - key 0 with key N -
  key N-1 directly would compare two different frames of the gait: a foot touching down
  between them changes its speed completely in one frame, mid-clip too.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from baker.clip import Clip, normalize_quats_f32, sign_continuous
from baker.geometry.transforms import quat_angle, quat_conj, quat_mul, quat_rotate, quat_slerp
from baker.rig.skeleton import forward_kinematics

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Window:
    """A loop window: `frames` frames holding whole numbers of each periodic motion.

    frames  : N, the loop's length in frames (its clip has N + 1 keys)
    counts  : whole cycles of each rate in the window (same order as the rates planned)
    scales  : factor each rate is nudged by to fit them (count / (rate * N / fps))
    """

    frames: int
    counts: tuple[int, ...]
    scales: tuple[float, ...]

    def worst(self, k: int | None = None) -> float:
        """Largest relative nudge |scale - 1| (of the first k rates)."""
        s = self.scales[:k] if k is not None else self.scales
        return max((abs(x - 1.0) for x in s), default=0.0)


def plan_window(rates, fps: int, min_s: float, max_s: float, tol: float = 0.01,
                extra=(), extra_tol: float = 0.05) -> Window:
    """The shortest window of min_s..max_s seconds in which each of `rates` [cycles/s] (> 0)
    fits a whole number (>= 1) of cycles after a nudge of at most `tol` (relative), preferring
    windows where the `extra` rates (decorative: antennae) also fit within `extra_tol`; without
    one, the window with the smallest nudge."""
    rates = [float(r) for r in rates]
    extra = [float(r) for r in extra]
    best, best_cost = None, math.inf
    fallback = None
    for n in range(max(int(math.ceil(min_s * fps)), 1), int(math.floor(max_s * fps)) + 1):
        t = n / fps
        counts = [max(int(round(r * t)), 1) for r in rates]
        scales = [c / (r * t) for c, r in zip(counts, rates)]
        w = Window(n, tuple(counts), tuple(scales))
        cost = w.worst()
        if cost <= tol:
            ex = max((abs(round(r * t) / (r * t) - 1.0) for r in extra if r * t >= 0.5),
                     default=0.0)
            if ex <= extra_tol:
                return w
            fallback = fallback or w
        if cost < best_cost:
            best, best_cost = w, cost
    return fallback or best


def root_relative(parents: np.ndarray, translations, rotations, placement=None,
                  root: int = 0) -> np.ndarray:
    """(F, J, 3) float64 joint positions seen from the root joint (see the module docstring)."""
    t, q = forward_kinematics(parents, translations, rotations)
    rel = t - t[:, root:root + 1]
    return quat_rotate(np.broadcast_to(quat_conj(q[:, root:root + 1]), q.shape), rel)


def _relative_step(a: np.ndarray, b: np.ndarray) -> float:
    """max |b - a| / max(|a|, |b|) over the rows of (..., 3) arrays (0 when all are still)."""
    scale = max(float(np.linalg.norm(a, axis=-1).max()), float(np.linalg.norm(b, axis=-1).max()))
    return float(np.linalg.norm(b - a, axis=-1).max()) / scale if scale > 1e-9 else 0.0


def seam_error(parents: np.ndarray, translations, rotations, root: int = 0) -> float:
    """max_j |p[N, j] - p[0, j]| [m] of a clip with keys 0..N (see the module docstring)."""
    p = root_relative(parents, translations, rotations, root=root)
    return float(np.linalg.norm(p[-1] - p[0], axis=-1).max())


def ground_steps(parents: np.ndarray, translations, rotations, frames, root: int = 0):
    """(k, J, 3) every joint's displacement over the ground from frame f to f + 1, seen in the
    root's frame at f, for f in `frames` (root motion, yaw included, moves every joint)."""
    t, q = forward_kinematics(parents, translations, rotations)
    f = np.asarray(frames)
    inv = np.broadcast_to(quat_conj(q[f, root])[:, None], (len(f),) + q.shape[1:])
    return quat_rotate(inv, t[f + 1] - t[f])


def seam_velocity(parents: np.ndarray, loop, ref, root: int = 0) -> dict:
    """Velocity mismatch (fraction) of a loop with keys 0..N, loop = (translations,
    rotations), against ref = the simulation's frames -1..N+1 around it (see the module
    docstring). velocity_mismatch compares every joint's step over the ground seen from the
    root (root motion included); joint_velocity_mismatch its step seen from the root (root
    motion excluded)."""
    lt, lq = (np.asarray(a, dtype=np.float64) for a in loop)
    rt, rq = (np.asarray(a, dtype=np.float64) for a in ref)
    n = len(lt) - 1
    played = ground_steps(parents, lt, lq, [n - 1, 0], root)     # arriving, leaving the seam
    sim = ground_steps(parents, rt, rq, [0, n + 1], root)        # at the first, the last frame
    p = root_relative(parents, lt, lq, root=root)
    r = root_relative(parents, rt, rq, root=root)
    rel = _relative_step(np.stack([p[-1] - p[-2], p[1] - p[0]]),
                         np.stack([r[1] - r[0], r[-1] - r[-2]]))
    return {"velocity_mismatch": _relative_step(played, sim), "joint_velocity_mismatch": rel}


def root_yaw(clip: Clip, root: int = 0) -> np.ndarray:
    """(F,) unwrapped yaw [rad] of the root joint (which turns about +Y only)."""
    q = clip.rotations[:, root].astype(np.float64)
    return np.unwrap(2.0 * np.arctan2(q[:, 1], q[:, 3]))


def loop_heading(clip: Clip, root: int = 0) -> float:
    """[rad] the root's heading at the first key with the slither's sway averaged out: its mean
    yaw over the loop less half the loop's turn (whole slither periods average out)."""
    yaw = root_yaw(clip, root)
    return float(yaw[:-1].mean() - 0.5 * (yaw[-1] - yaw[0]) * (1.0 - 1.0 / (len(yaw) - 1)))


def start_at_origin(clip: Clip, root: int = 0, heading: float | None = None) -> Clip:
    """The clip moved and turned (about +Y) so that its root joint starts at the origin and
    `heading` (default: the root's yaw at the first frame) faces +Z, with a zero placement (only
    the root's track changes; yaw-only roots stay yaw-only)."""
    t = clip.translations.astype(np.float64)
    q = clip.rotations.astype(np.float64)
    t[:, root] += clip.placement
    start = t[0, root].copy()
    start[1] = 0.0                       # stays on the ground: only x and z move to the origin
    yaw = root_yaw(clip, root)[0] if heading is None else heading
    turn = np.broadcast_to([0.0, -math.sin(0.5 * yaw), 0.0, math.cos(0.5 * yaw)],
                           (clip.n_frames, 4))
    t[:, root] = quat_rotate(turn, t[:, root] - start)
    q[:, root] = quat_mul(turn, q[:, root])
    return _with_pose(clip, t, q, placement=np.zeros(3))


def close_loop(clip: Clip, root: int = 0) -> Clip:
    """Keys 0..N with the seam's residual distributed: every joint but the root loses the
    linearly ramped difference (f / N) of its local transform between key N and key 0
    (translations subtracted, rotations turned back by the slerped difference), so key N
    repeats key 0 exactly and the velocities at both ends change alike."""
    t = clip.translations.astype(np.float64)
    q = clip.rotations.astype(np.float64)
    n = clip.n_frames - 1
    u = np.arange(n + 1) / n
    keep = np.arange(clip.n_joints) == root
    dt = np.where(keep[:, None], 0.0, t[-1] - t[0])
    t = t - u[:, None, None] * dt[None]
    delta = quat_mul(quat_conj(q[0]), q[-1])                     # (J, 4): q0^-1 qN
    delta[keep] = IDENTITY
    ramp = quat_slerp(np.broadcast_to(IDENTITY, (n + 1,) + delta.shape),
                      np.broadcast_to(delta, (n + 1,) + delta.shape), u[:, None])
    q = quat_mul(q, quat_conj(ramp))
    q[-1, ~keep] = q[0, ~keep]
    t[-1, ~keep] = t[0, ~keep]
    return _with_pose(clip, t, q)


def blend(base: Clip, action: Clip, weight: np.ndarray, root: int = 0) -> Clip:
    """`action` with every joint but the root slerped (rotations) and lerped (translations)
    toward `base` by 1 - weight (F,) in joint space; the root keeps the action's track."""
    w = np.asarray(weight, dtype=np.float64)
    keep = np.arange(action.n_joints) == root
    wj = np.where(keep[None, :], 1.0, w[:, None])                 # (F, J)
    tb, ta = base.translations.astype(np.float64), action.translations.astype(np.float64)
    qb, qa = base.rotations.astype(np.float64), action.rotations.astype(np.float64)
    t = tb + wj[..., None] * (ta - tb)
    q = quat_slerp(qb, qa, wj)
    return _with_pose(action, t, q)


def blend_weights(n_frames: int, ramp: int) -> np.ndarray:
    """(F,) 0 at the first and last frame, 1 in between, with smoothstep ramps of `ramp` frames
    (shortened to fit); the largest change per frame is 1.5 / ramp."""
    f = np.arange(n_frames, dtype=np.float64)
    r = max(min(int(ramp), (n_frames - 1) // 2), 1)
    x = np.clip(np.minimum(f, n_frames - 1 - f) / r, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def largest_turn(a: Clip, b: Clip, root: int = 0) -> float:
    """Largest angle [rad] between the local rotations of a and b at the same frame and joint
    (the root excluded)."""
    keep = np.arange(a.n_joints) != root
    return float(quat_angle(a.rotations[:, keep].astype(np.float64),
                            b.rotations[:, keep].astype(np.float64)).max(initial=0.0))


def frame_turns(clip: Clip) -> np.ndarray:
    """(F-1, J) float64 degrees each joint's local rotation turns from one frame to the next."""
    q = clip.rotations.astype(np.float64)
    return np.degrees(quat_angle(q[:-1], q[1:]))


def _with_pose(clip: Clip, t: np.ndarray, q: np.ndarray, placement=None) -> Clip:
    out = replace(clip, translations=t.astype(np.float32),
                  rotations=sign_continuous(normalize_quats_f32(q)), keys=None,
                  placement=clip.placement if placement is None else placement)
    for arr in (out.translations, out.rotations):
        arr.setflags(write=False)
    return out
