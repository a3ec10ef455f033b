"""Limb layout: walking legs, ultimate legs, antennae and forcipules, from the rig config.

One place defines where every limb joint sits, so the skeleton's rest pose (rig/build.py), the
mesh (rig/mesh.py) and the simulation (locomotion/legs.py) agree. Every limb bone is a joint
whose local +Y points along the bone (Blender's bone convention) and whose local +X is the
bend (hinge) axis; a bone ends at its child joint. The last bone of every limb ends at an *end
joint* (`leg_L_07_foot`, `ultimate_L_foot`, `antenna_L_tip`, `forcipule_L_end`): a leaf joint at
(0, length, 0) in its parent with the identity local rotation and no skin weights, so every bone
has a length and engines have a joint at the contact point (feet) or the sensing end (antennae).

Segment frame: +X left, +Y up (surface normal), +Z forward; the spine joint at the origin,
the surface at y = -clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.config import RigConfig
from baker.geometry.ik import bone_frames, two_bone_ik
from baker.geometry.transforms import normalize, quat_rotate

HIP_DROP = 0.35     # hip below the centre line, as a fraction of the segment's half-height


@dataclass(frozen=True)
class LegLayout:
    """The walking legs, two per trunk segment, ordered L_01, R_01, L_02, R_02, ...

    upper_names, tip_names : (L,) joint names, leg_L_07_upper / leg_L_07_tip
    foot_names : (L,) end joint names at the contact point, leg_L_07_foot (child of the tip)
    segment : (L,) int64, spine index the leg hangs from (1..S-1)
    side    : (L,) float64, +1 left (+X), -1 right
    hip     : (L, 3) float64, metres, hip (upper joint origin) in the segment frame
    anchor  : (L, 3) float64, metres, neutral foot position on the surface, segment frame
    lag     : (L,) float64, cycles; gait phase offset (phase = travel / stride + lag):
              retrograde wave (rear legs lag), right side half a cycle from the left
    l1, l2  : bone lengths [m]
    """

    upper_names: tuple[str, ...]
    tip_names: tuple[str, ...]
    foot_names: tuple[str, ...]
    segment: np.ndarray
    side: np.ndarray
    hip: np.ndarray
    anchor: np.ndarray
    lag: np.ndarray
    l1: float
    l2: float

    @property
    def n_legs(self) -> int:
        return len(self.segment)


@dataclass(frozen=True)
class Chain:
    """A two-joint limb that is posed by angles, not by a foothold (ultimate legs, antennae,
    forcipules).

    names    : (2,) joint names, base first
    end      : the end joint's name (child of names[1], at its bone's end): ultimate_L_foot,
               antenna_L_tip, forcipule_L_end
    parent   : spine index of the parent spine joint
    base     : (3,) base joint position in the parent segment frame
    dirs     : (2, 3) rest bone directions (unit) in the parent segment frame
    hinge    : (3,) rest hinge (local +X) direction, segment frame
    lengths  : (2,) bone lengths [m]
    radius   : tube radius at the base [m]
    kind     : "ultimate", "antenna" or "forcipule"
    side     : +1 left, -1 right
    """

    names: tuple[str, str]
    parent: int
    base: np.ndarray
    dirs: np.ndarray
    hinge: np.ndarray
    lengths: np.ndarray
    radius: float
    kind: str
    side: float
    end: str = ""


def half_widths(cfg: RigConfig) -> np.ndarray:
    """(S,) segment half-widths [m] (the rig default when the profile is empty)."""
    w = np.asarray(cfg.body.width_profile, float)
    return w if w.size else np.full(cfg.body.segments, 0.045 * cfg.body.length)


def half_height(cfg: RigConfig) -> np.ndarray:
    return half_widths(cfg) * cfg.body.height_ratio


def leg_layout(cfg: RigConfig) -> LegLayout:
    b, lg = cfg.body, cfg.legs
    widths = half_widths(cfg)
    segs = np.repeat(np.arange(1, b.segments), 2)
    side = np.tile([1.0, -1.0], b.segments - 1)
    n_pairs = b.segments - 1
    hip = np.stack([side * lg.hip_width * widths[segs],
                    -HIP_DROP * half_height(cfg)[segs], np.zeros(len(segs))], -1)
    anchor = np.stack([side * lg.reach, np.full(len(segs), -b.clearance), np.zeros(len(segs))], -1)
    lag = -(segs - 1) * (lg.waves / n_pairs) + np.where(side > 0, 0.0, 0.5)
    lag = lag - np.floor(lag)
    names_u = tuple(f"leg_{'L' if s > 0 else 'R'}_{k:02d}_upper" for k, s in zip(segs, side))
    names_t = tuple(f"leg_{'L' if s > 0 else 'R'}_{k:02d}_tip" for k, s in zip(segs, side))
    names_f = tuple(f"leg_{'L' if s > 0 else 'R'}_{k:02d}_foot" for k, s in zip(segs, side))
    return LegLayout(upper_names=names_u, tip_names=names_t, foot_names=names_f, segment=segs,
                     side=side, hip=hip, anchor=anchor, lag=lag, l1=float(lg.upper_length),
                     l2=float(lg.tip_length))


def leg_pole(layout: LegLayout, hip: np.ndarray, target: np.ndarray, fwd: np.ndarray,
             left: np.ndarray, knee_out: float) -> np.ndarray:
    """World knee pole directions (..., L, 3): perpendicular to hip->target in the plane
    across the body (side * fwd x u, i.e. up for a leg reaching sideways), tilted outward by
    knee_out. It never lines up with the leg, so the knee cannot flip, even when a swinging
    foot rises above its hip."""
    u = normalize(target - hip)
    s = layout.side[:, None]
    return s * np.cross(fwd, u) + knee_out * s * left


def _dir(side: float, yaw: float, pitch: float, forward: float = 1.0) -> np.ndarray:
    """Unit direction in a segment frame: `yaw` outward from +Z (or -Z when forward=-1),
    `pitch` up from the horizontal plane."""
    return np.array([side * np.sin(yaw) * np.cos(pitch), np.sin(pitch),
                     forward * np.cos(yaw) * np.cos(pitch)])


def chains(cfg: RigConfig) -> tuple[Chain, ...]:
    """Ultimate legs (on the last segment), antennae and forcipules (on the head)."""
    b, lg = cfg.body, cfg.legs
    w = half_widths(cfg)
    hh = half_height(cfg)
    sp = b.spacing
    last = b.segments - 1
    out: list[Chain] = []
    for s, tag in ((1.0, "L"), (-1.0, "R")):
        # ultimate legs: backward, spread outward, raised by ultimate_raise
        d1 = _dir(s, lg.ultimate_spread, lg.ultimate_raise, forward=-1.0)
        d2 = _dir(s, lg.ultimate_spread + np.radians(8), lg.ultimate_raise - np.radians(6), -1.0)
        out.append(Chain((f"ultimate_{tag}_upper", f"ultimate_{tag}_tip"), last,
                         np.array([s * 0.6 * w[last], -HIP_DROP * hh[last], -0.3 * sp]),
                         np.stack([d1, d2]), _hinge(d1, s), np.array([lg.ultimate_upper, lg.ultimate_tip]),
                         lg.radius * 0.9, "ultimate", s, end=f"ultimate_{tag}_foot"))
        # antennae: forward, outward and a little up from the front of the head
        a1 = _dir(s, np.radians(28), np.radians(12))
        a2 = _dir(s, np.radians(40), np.radians(2))
        out.append(Chain((f"antenna_{tag}_1", f"antenna_{tag}_2"), 0,
                         np.array([s * 0.45 * w[0], 0.35 * hh[0], 0.55 * sp]),
                         np.stack([a1, a2]), _hinge(a1, s),
                         np.array([lg.antenna_length, lg.antenna_length]), lg.radius * 0.45,
                         "antenna", s, end=f"antenna_{tag}_tip"))
        # forcipules: under the head, forward then curving inward (rest posture)
        f1 = _dir(s, np.radians(35), np.radians(-10))
        f2 = _dir(s, np.radians(-55), np.radians(-5))
        out.append(Chain((f"forcipule_{tag}", f"forcipule_{tag}_tip"), 0,
                         np.array([s * 0.45 * w[0], -0.55 * hh[0], 0.25 * sp]),
                         np.stack([f1, f2]), _hinge(f1, s),
                         np.array([lg.forcipule_length, 0.9 * lg.forcipule_length]),
                         lg.radius * 0.8, "forcipule", s, end=f"forcipule_{tag}_end"))
    return tuple(out)


def _hinge(d: np.ndarray, side: float) -> np.ndarray:
    """A hinge axis perpendicular to d, roughly horizontal (bends the chain up/down)."""
    h = np.cross(np.array([0.0, 1.0, 0.0]), d)
    if np.linalg.norm(h) < 1e-6:
        h = np.array([1.0, 0.0, 0.0])
    return normalize(h)


@dataclass(frozen=True)
class LimbRest:
    """Rest (bind) pose of every limb joint in the skeleton (= segment frame at rest).

    The two bone joints of every limb come first (limb by limb, as before end joints existed, so
    their skeleton indices do not move), then every limb's end joint, in the same limb order.

    names     : (K,) limb joint names, parents first within each limb
    parents   : (K,) parent *names* (spine or limb joint)
    positions : (K, 3) world (skeleton-space) rest positions
    rotations : (K, 4) xyzw world rest rotations (an end joint's is its parent's)
    lengths   : (K,) bone lengths [m] (0 for end joints)
    radii     : (K,) tube radius at each bone's start [m] (0 for end joints)
    end       : (K,) bool, True for the end joints (leaves, no skin weights)
    """

    names: tuple[str, ...]
    parents: tuple[str, ...]
    positions: np.ndarray
    rotations: np.ndarray
    lengths: np.ndarray
    radii: np.ndarray
    end: np.ndarray

    @property
    def n_limbs(self) -> int:
        return len(self.names) // 3


def limb_rest(cfg: RigConfig, spine_names: tuple[str, ...]) -> LimbRest:
    """Rest pose: walking legs standing on their anchors (two-bone IK), chains at rest angles;
    every limb ends in an end joint at (0, length, 0) of its last bone."""
    lay = leg_layout(cfg)
    sp = cfg.body.spacing
    seg_origin = np.stack([np.zeros(lay.n_legs), np.zeros(lay.n_legs), -lay.segment * sp], -1)
    hip = seg_origin + lay.hip
    foot = seg_origin + lay.anchor
    fwd = np.tile([0.0, 0.0, 1.0], (lay.n_legs, 1))
    left = np.tile([1.0, 0.0, 0.0], (lay.n_legs, 1))
    sol = two_bone_ik(hip, foot, leg_pole(lay, hip, foot, fwd, left, cfg.legs.knee_out),
                      lay.l1, lay.l2)
    q_u = bone_frames(hip, sol.mid, sol.hinge)
    q_t = bone_frames(sol.mid, sol.end, sol.hinge)
    # (limb names, parent of the first joint, bone starts (2, 3), rotations (2, 4), lengths,
    # base radius)
    limbs = [((lay.upper_names[i], lay.tip_names[i], lay.foot_names[i]),
              spine_names[lay.segment[i]], np.stack([hip[i], sol.mid[i]]),
              np.stack([q_u[i], q_t[i]]), np.array([lay.l1, lay.l2]), cfg.legs.radius)
             for i in range(lay.n_legs)]
    for ch in chains(cfg):
        p1 = np.array([0.0, 0.0, -ch.parent * sp]) + ch.base
        p2 = p1 + ch.dirs[0] * ch.lengths[0]
        q = bone_frames(np.stack([p1, p2]), np.stack([p2, p2 + ch.dirs[1]]),
                        np.stack([ch.hinge, ch.hinge]))
        limbs.append((ch.names + (ch.end,), spine_names[ch.parent], np.stack([p1, p2]), q,
                      np.asarray(ch.lengths, float), ch.radius))
    names, parents, pos, rot, lens, radii = [], [], [], [], [], []
    for (n1, n2, _), parent, start, q, length, r in limbs:
        names += [n1, n2]
        parents += [parent, n1]
        pos += [start[0], start[1]]
        rot += [q[0], q[1]]
        lens += [length[0], length[1]]
        radii += [r, 0.7 * r]
    for (_, n2, n3), _, start, q, length, _ in limbs:   # end joints after every bone joint
        names.append(n3)
        parents.append(n2)
        pos.append(start[1] + quat_rotate(q[1], np.array([0.0, length[1], 0.0])))
        rot.append(q[1])
        lens.append(0.0)
        radii.append(0.0)
    return LimbRest(names=tuple(names), parents=tuple(parents), positions=np.array(pos),
                    rotations=np.array(rot), lengths=np.array(lens), radii=np.array(radii),
                    end=np.repeat([False, True], [2 * len(limbs), len(limbs)]))
