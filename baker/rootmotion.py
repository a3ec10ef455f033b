"""Root motion: re-express a clip on a skeleton with a top `root` joint on the ground.

    clip, rig, motion = apply_root_motion(clip, rig, "root", ground)

Modes (`--root-motion`):
- `world`    : the clip as baked; the skeleton's top joint is `head` (no root joint).
- `root`     : a joint `root` is added above `head`. Each frame it sits on the ground under the
               body's centre and turns with the body's heading (yaw only), and every other joint
               is animated relative to it. This is the layout engines extract root motion from
               (Unreal's root bone, Unity's Animator root motion, Godot's `root_motion_track`).
- `in-place` : the same skeleton with the root held at the placement (identity) in the clip; the
               removed motion is returned as a NodeTrack on the `root` joint, which the writers
               store as a separate `root_motion` animation.

The body's centre is the mean of the spine joints; its heading is the horizontal direction from
the mean of the rear half of the spine to the mean of the front half (defined when the creature
stands still), averaged over time as an angle by a centred Gaussian (sigma 0.5 s, each frame
weighted by the length of that direction) so the root does not sway with the slither. The
ground height comes from `ground` and is smoothed over half a second, so a staircase gives the
root a ramp, not steps. World joint positions are unchanged by construction (to float32
rounding).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from baker.clip import Clip, NodeTrack, normalize_quats_f32, sign_continuous
from baker.errors import ExportError
from baker.geometry.transforms import quat_conj, quat_mul, quat_rotate
from baker.rig.build import Rig
from baker.rig.mesh import SkinnedMesh
from baker.rig.skeleton import Skeleton, forward_kinematics

MODES = ("world", "root", "in-place")
ROOT = "root"
#: [s] window of the centred moving average over the ground height under the body
GROUND_SMOOTHING = 0.5
#: [s] sigma of the centred Gaussian over the body's heading: it takes the slither's sway
#: (periods of 0.5-2 s) out of the root's yaw and keeps a steady turn's rate
HEADING_SMOOTHING = 0.5


def with_root(rig: Rig) -> Rig:
    """`rig` with a joint `root` (at the skeleton origin, identity rest) above its top joint:
    joint indices shift by one in the skeleton, the skin and the spine."""
    skel = rig.skeleton
    if ROOT in {n.lower() for n in skel.names}:
        raise ExportError(f"the rig already has a joint named {ROOT!r}")
    rooted = Skeleton(
        names=(ROOT,) + skel.names,
        parents=np.concatenate([[-1], skel.parents + 1]),
        rest_translations=np.concatenate([np.zeros((1, 3)), skel.rest_translations]),
        rest_rotations=np.concatenate([[[0.0, 0.0, 0.0, 1.0]], skel.rest_rotations]))
    m = rig.mesh
    mesh = SkinnedMesh(vertices=m.vertices, normals=m.normals, faces=m.faces,
                       joints=np.where(m.weights > 0, m.joints.astype(np.int64) + 1, 0),
                       weights=m.weights, face_material=m.face_material, materials=m.materials)
    spine = np.asarray(rig.spine, dtype=np.int64) + 1
    spine.setflags(write=False)
    return Rig(config=rig.config, skeleton=rooted, mesh=mesh, spine=spine)


def yaw_quaternions(forward: np.ndarray, sigma: float = 0.0) -> np.ndarray:
    """(F, 4) xyzw rotations about +Y turning +Z to the horizontal part of forward (F, 3).
    Frames whose forward is (nearly) vertical hold the last defined heading (the first one
    before any is defined). sigma > 0: the headings (unwrapped angles) averaged over the
    frames by a centred Gaussian of that many frames, each weighted by its forward's
    horizontal length (a body coiled head to tail says little about its heading). Averaged as
    angles, a turn of more than half a circle within the window keeps its way round; averaged
    as vectors, their mean came near zero there and swung 60 degrees in a frame."""
    fx, fz = forward[:, 0], forward[:, 2]
    w = np.hypot(fx, fz)
    ok = w > 1e-9
    if not ok.any():
        fx, fz, ok = np.zeros(len(forward)), np.ones(len(forward)), np.ones(len(forward), bool)
        w = ok.astype(float)
    idx = np.arange(len(forward))
    near = np.maximum.accumulate(np.where(ok, idx, -1))
    near[near < 0] = idx[ok][0]
    yaw = np.unwrap(np.arctan2(fx[near], fz[near]))
    if sigma > 0.0:
        w = np.where(ok, w, 0.0)
        total = gaussian_filter1d(w, sigma, mode="nearest")
        mean = gaussian_filter1d(w * yaw, sigma, mode="nearest")
        yaw = np.divide(mean, total, out=yaw.copy(), where=total > 1e-12 * max(w.max(), 1e-300))
    q = np.zeros((len(forward), 4))
    q[:, 1] = np.sin(0.5 * yaw)
    q[:, 3] = np.cos(0.5 * yaw)
    return q


def root_frames(spine_world: np.ndarray, fps: int, ground=None) -> tuple[np.ndarray, np.ndarray]:
    """The root joint's translation (F, 3) float64 and yaw rotation (F, 4) xyzw for spine joint
    positions spine_world (F, S, 3) float64 (head first) in the placement frame.

    ground : callable (N, 3) points -> (N,) ground heights below them (NaN for none), in the
             same frame; None: the plane y = 0."""
    s = spine_world.shape[1]
    centre = spine_world.mean(axis=1)
    half = max(s // 2, 1)
    forward = spine_world[:, :half].mean(axis=1) - spine_world[:, s - half:].mean(axis=1)
    rot = yaw_quaternions(forward, HEADING_SMOOTHING * fps)
    height = np.zeros(len(centre)) if ground is None else np.asarray(ground(centre), float)
    miss = ~np.isfinite(height)
    if miss.all():
        height = centre[:, 1].copy()
    elif miss.any():
        idx = np.arange(len(height))
        height = np.interp(idx, idx[~miss], height[~miss])
    if ground is not None:
        size = max(int(round(GROUND_SMOOTHING * fps)), 1)
        height = uniform_filter1d(height, size=size, mode="nearest")
    pos = np.stack([centre[:, 0], height, centre[:, 2]], axis=1)
    return pos, rot


def apply_root_motion(clip: Clip, rig: Rig, mode: str, ground=None
                      ) -> tuple[Clip, Rig, NodeTrack | None]:
    """(the clip on the rooted skeleton, the rooted rig, the removed root motion or None).

    clip   : a clip over rig.skeleton (no root joint), e.g. from build_clip
    mode   : "world" returns the inputs unchanged
    ground : see root_frames; the placement frame of the clip
    """
    if mode not in MODES:
        raise ExportError(f"unknown root-motion mode {mode!r}: use one of {', '.join(MODES)}")
    if mode == "world":
        return clip, rig, None
    rooted = with_root(rig)
    root_t, root_q = root_frames(_spine_world(clip, rig), clip.fps, ground)
    return _rooted_clip(clip, rooted, root_t, root_q, mode)


def _spine_world(clip: Clip, rig: Rig) -> np.ndarray:
    """(F, S, 3) float64 world positions of the spine joints less the placement: clip.world's,
    posing only the spine joints and their ancestors (the same bits)."""
    parents = np.asarray(rig.skeleton.parents, dtype=np.int64)
    need = np.zeros(len(parents), dtype=bool)
    for j in np.asarray(rig.spine, dtype=np.int64).tolist():
        while j >= 0 and not need[j]:
            need[j], j = True, int(parents[j])
    sub = np.flatnonzero(need)                       # parents before children, as there
    at = np.full(len(parents), -1, dtype=np.int64)
    at[sub] = np.arange(len(sub))
    wt, _ = forward_kinematics(at[parents[sub]], clip.translations[:, sub],
                               clip.rotations[:, sub])
    return (wt + clip.placement)[:, at[np.asarray(rig.spine)]] - clip.placement


def _rooted_clip(clip: Clip, rooted: Rig, root_t, root_q, mode: str):
    """Insert the root's track as joint 0 and make the old top joints relative to it."""
    tops = np.nonzero(rooted.skeleton.parents == 0)[0] - 1      # old indices of the top joints
    lt = clip.translations.astype(np.float64)
    lq = clip.rotations.astype(np.float64)
    inv = quat_conj(root_q)
    new_t = np.concatenate([root_t[:, None], lt], axis=1)
    new_q = np.concatenate([root_q[:, None], lq], axis=1)
    for j in tops:
        new_t[:, j + 1] = quat_rotate(inv, lt[:, j] - root_t)
        new_q[:, j + 1] = quat_mul(inv, lq[:, j])
    motion = None
    if mode == "in-place":
        motion = NodeTrack(node=ROOT, translations=root_t.astype(np.float32),
                           rotations=sign_continuous(normalize_quats_f32(root_q)))
        new_t[:, 0] = 0.0
        new_q[:, 0] = [0.0, 0.0, 0.0, 1.0]
    f = clip.n_frames
    out = replace(clip, translations=new_t.astype(np.float32),
                  rotations=sign_continuous(normalize_quats_f32(new_q)),
                  scales=np.concatenate([np.ones((f, 1, 3), np.float32), clip.scales], axis=1),
                  keys=None)
    for arr in (out.translations, out.rotations, out.scales):
        arr.setflags(write=False)
    return out, rooted, motion
