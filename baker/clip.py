"""Trajectory + Skeleton -> Clip: per-frame joint-local TRS arrays, ready for the exporters.

Far from the origin, float32 world positions step in millimetres, so a clip is written relative
to a *placement*: a world point near the creature's path (`export_origin`: the centre of the
head path's bounding box rounded to whole metres). The root joint's translations and the prey
tracks are relative to it (float32, small numbers); the exporters put the placement itself on a
node or Xform translation, which glTF JSON and USD store in double precision.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from baker.errors import ExportError
from baker.geometry.conventions import is_valid_name
from baker.geometry.transforms import light_rotation, quat_conj, quat_mul, quat_rotate
from baker.rig.build import Rig
from baker.rig.skeleton import forward_kinematics
from baker.solve.trajectory import Trajectory


@dataclass(frozen=True)
class NodeTrack:
    """Animation of one scene node that is not a joint (a prey capsule, the sun).

    node         : node name in the exported scene
    translations : (F, 3) float32 metres, relative to the clip's placement (the node's parent
                   carries the placement translation), or None
    rotations    : (F, 4) float32 xyzw unit, sign-continuous, or None
    scales       : (F, 3) float32, or None (0 hides the node)
    """

    node: str
    translations: np.ndarray | None = None
    rotations: np.ndarray | None = None
    scales: np.ndarray | None = None

    def slice(self, f0: int, f1: int) -> "NodeTrack":
        cut = (lambda a: None if a is None else a[f0:f1])
        return NodeTrack(self.node, cut(self.translations), cut(self.rotations), cut(self.scales))


@dataclass(frozen=True)
class Clip:
    """One animation over the whole skeleton, sampled at the export fps.

    name         : animation name, [A-Za-z0-9_]
    fps          : export frame rate [Hz]; times[f] == float32(f / fps)
    times        : (F,) float32, seconds, times[0] == 0, strictly increasing
    translations : (F, J, 3) float32, metres, joint-local (relative to the parent joint;
                   the root joint relative to the creature's placement node)
    rotations    : (F, J, 4) float32, xyzw, joint-local, unit in float32, sign-continuous over F
    scales       : (F, J, 3) float32, joint-local (ones for now)
    tracks       : animated scene nodes that are not joints (prey, sun)
    placement    : (3,) float64, metres, world translation of the placement node ("Centipede"
                   in glTF, the SkelRoot in USD) and of the prey's parent; whole metres
    loop         : the clip repeats seamlessly (locomotion cycles); importers see it by name
    events       : JSON-safe animation events (foot contacts, behaviour changes, loop markers),
                   written to the glTF animation's extras and the USD SkelAnimation's customData
    keys         : the frames each channel keeps after keyframe reduction and the values
                   stored there (a baker.export.reduce.ClipKeys, set by reduce_clip), or None:
                   every frame is a key
    """

    name: str
    times: np.ndarray
    translations: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    fps: int = 30
    tracks: tuple[NodeTrack, ...] = ()
    placement: np.ndarray = field(default_factory=lambda: np.zeros(3))
    loop: bool = False
    events: dict = field(default_factory=dict)
    keys: object | None = None

    def __post_init__(self) -> None:
        p = np.array(self.placement, dtype=np.float64).reshape(3)
        p.setflags(write=False)
        object.__setattr__(self, "placement", p)

    def segment(self, f0: int, f1: int, name: str) -> "Clip":
        """Frames [f0, f1) as a clip of its own, with times starting at 0."""
        f1 = min(f1, self.n_frames)
        if not 0 <= f0 < f1:
            raise ExportError(f"empty clip segment [{f0}, {f1})")
        return Clip(name=name, times=times_for(f1 - f0, self.fps),
                    translations=self.translations[f0:f1], rotations=self.rotations[f0:f1],
                    scales=self.scales[f0:f1], fps=self.fps,
                    tracks=tuple(t.slice(f0, f1) for t in self.tracks), placement=self.placement)

    @property
    def n_frames(self) -> int:
        return len(self.times)

    @property
    def n_joints(self) -> int:
        return self.translations.shape[1]

    def world(self, parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics: (F, J, 3) world translations (placement + the joint chain, in
        float64), (F, J, 4) xyzw world rotations (scales are ignored; they are ones)."""
        t, q = forward_kinematics(parents, self.translations, self.rotations)
        return t + self.placement, q


def times_for(n_frames: int, fps: int) -> np.ndarray:
    """(F,) float32 frame times f / fps, computed in float64 and rounded once."""
    return (np.arange(n_frames, dtype=np.float64) / float(fps)).astype(np.float32)


def _infer_fps(times: np.ndarray) -> int:
    if len(times) < 2:
        return 30
    return int(round((len(times) - 1) / (float(times[-1]) - float(times[0]))))


def normalize_quats_f32(q: np.ndarray) -> np.ndarray:
    """Unit quaternions in float32 (norm computed in float64, result rounded once)."""
    q = np.asarray(q, dtype=np.float64)
    return (q / np.linalg.norm(q, axis=-1, keepdims=True)).astype(np.float32)


def sign_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 so consecutive keys have a non-negative dot product (vectorized).

    q : (F, ..., 4); the first key keeps w >= 0.
    """
    q = np.asarray(q)
    if len(q) == 0:
        return q.copy()
    dots = np.sum(q[1:].astype(np.float64) * q[:-1].astype(np.float64), axis=-1)
    step = np.where(dots < 0, -1.0, 1.0)
    first = np.where(q[:1, ..., 3] < 0, -1.0, 1.0)
    sign = np.cumprod(np.concatenate([first, step], axis=0), axis=0)
    return (q * sign[..., None]).astype(q.dtype)


def export_origin(head: np.ndarray) -> np.ndarray:
    """(3,) float64 placement for a clip: the centre of the bounding box of the head's world
    positions head (F, 3) float64, rounded to whole metres (exact, deterministic)."""
    head = np.asarray(head, dtype=np.float64).reshape(-1, 3)
    return np.floor(0.5 * (head.min(axis=0) + head.max(axis=0)) + 0.5)


def build_clip(traj: Trajectory, rig: Rig, name: str = "bake", fps: int | None = None,
               origin=None, placement=None) -> Clip:
    """Convert the trajectory's spine and limb frames into joint-local TRS.

    traj      : spine_positions (F, S, 3) / spine_rotations (F, S, 4) are the transforms of the
                S spine joints rig.spine in the trajectory's frame (the environment's local
                frame: world = origin + position)
    fps       : export frame rate; None infers it from traj.times (which must be f / fps).
    origin    : (3,) float64 metres, world position of the trajectory frame's origin
                (Environment.origin); None: zeros
    placement : (3,) float64 metres, world translation of the placement node; None: the
                export_origin of the head's world path. Root joint and prey translations are
                stored relative to it (computed in float64, rounded to float32 once).
    Limb joints named in traj.joint_names take their world frames from traj.joint_positions /
    joint_rotations. Other joints keep their rest pose relative to their parent.
    """
    if not is_valid_name(name):
        raise ExportError(f"clip name {name!r} must use [A-Za-z0-9_] only")
    skel = rig.skeleton
    spine = np.asarray(rig.spine, dtype=np.int64)
    pos = np.asarray(traj.spine_positions, dtype=np.float64)
    rot = np.asarray(traj.spine_rotations, dtype=np.float64)
    f_count = len(traj.times)
    if f_count == 0:
        raise ExportError("the trajectory has no frames")
    if pos.shape != (f_count, len(spine), 3) or rot.shape != (f_count, len(spine), 4):
        raise ExportError(f"trajectory shapes {pos.shape}/{rot.shape} do not match "
                          f"{f_count} frames x {len(spine)} spine joints")
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(rot))):
        raise ExportError("the trajectory has non-finite positions or rotations")
    origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
    if placement is None:
        placement = export_origin(pos[:, 0] + origin)
    placement = np.asarray(placement, dtype=np.float64).reshape(3)
    shift = placement - origin          # trajectory frame -> placement frame
    pos = pos - shift
    fps = _infer_fps(np.asarray(traj.times)) if fps is None else int(fps)
    if fps <= 0:
        raise ExportError(f"fps must be > 0 (got {fps})")
    frame_err = np.abs(np.asarray(traj.times, dtype=np.float64) * fps - np.arange(f_count)).max()
    if frame_err > 0.01:
        raise ExportError(f"trajectory times are not frame / {fps} s (off by up to "
                          f"{frame_err:.3g} frames): resample the trajectory first")

    j_count = skel.n_joints
    # world transforms of every joint, joint-major (J, F, .): the spine from the trajectory,
    # the rest by rest-pose FK (_local_transforms)
    rot = rot / np.linalg.norm(rot, axis=-1, keepdims=True)
    world_t = np.zeros((j_count, f_count, 3))
    world_q = np.zeros((j_count, f_count, 4))
    driven = np.zeros(j_count, dtype=bool)
    driven[spine] = True
    world_t[spine] = pos.transpose(1, 0, 2)
    world_q[spine] = rot.transpose(1, 0, 2)
    if traj.joint_names:       # limbs: world frames of named joints
        limb = np.array([skel.index(n) for n in traj.joint_names], dtype=np.int64)
        lp = np.asarray(traj.joint_positions, dtype=np.float64)
        lq = np.asarray(traj.joint_rotations, dtype=np.float64)
        if lp.shape != (f_count, len(limb), 3) or lq.shape != (f_count, len(limb), 4):
            raise ExportError(f"trajectory limb shapes {lp.shape}/{lq.shape} do not match "
                              f"{f_count} frames x {len(limb)} joints")
        if not (np.all(np.isfinite(lp)) and np.all(np.isfinite(lq))):
            raise ExportError("the trajectory has non-finite limb positions or rotations")
        driven[limb] = True
        world_t[limb] = (lp - shift).transpose(1, 0, 2)
        world_q[limb] = (lq / np.linalg.norm(lq, axis=-1, keepdims=True)).transpose(1, 0, 2)
    local_t, local_q = _local_transforms(skel, driven, world_t, world_q)

    rotations = sign_continuous(normalize_quats_f32(local_q))
    clip = Clip(name=name, times=times_for(f_count, fps),
                translations=local_t.astype(np.float32), rotations=rotations,
                scales=np.ones((f_count, j_count, 3), dtype=np.float32), fps=fps,
                tracks=node_tracks(traj, shift), placement=placement)
    for arr in (clip.times, clip.translations, clip.rotations, clip.scales):
        arr.setflags(write=False)
    return clip


def _local_transforms(skel, driven: np.ndarray, world_t: np.ndarray, world_q: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(F, J, 3) float64 local translations and (F, J, 4) local rotations of every joint.

    driven  : (J,) bool, the joints whose world frames are given
    world_t : (J, F, 3) / world_q (J, F, 4) world frames, joint-major; the undriven joints'
              are filled in here: each follows its parent in the rest pose
    A driven joint's local transform is its world frame relative to its parent's (a root's is
    its world frame); an undriven joint keeps its rest transform. The joints are taken a depth
    of the skeleton at a time (parents before children), with the arithmetic of one joint at
    a time."""
    parents = np.asarray(skel.parents, dtype=np.int64)
    f_count = world_t.shape[1]
    local_t = np.repeat(np.asarray(skel.rest_translations, np.float64)[:, None], f_count, axis=1)
    local_q = np.repeat(np.asarray(skel.rest_rotations, np.float64)[:, None], f_count, axis=1)
    depth = np.zeros(len(parents), dtype=np.int64)
    for j, p in enumerate(parents):
        depth[j] = depth[p] + 1 if p >= 0 else 0
    roots = np.nonzero((parents < 0) & ~driven)[0]
    world_t[roots], world_q[roots] = local_t[roots], local_q[roots]
    for level in range(1, int(depth.max(initial=0)) + 1):    # undriven: rest pose FK
        js = np.nonzero((depth == level) & ~driven)[0]
        ps = parents[js]
        world_t[js] = world_t[ps] + quat_rotate(world_q[ps], local_t[js])
        world_q[js] = quat_mul(world_q[ps], local_q[js])
    js = np.nonzero(driven & (parents >= 0))[0]
    ps = parents[js]
    inv = quat_conj(world_q[ps])
    local_t[js] = quat_rotate(inv, world_t[js] - world_t[ps])
    local_q[js] = quat_mul(inv, world_q[js])
    top = np.nonzero(driven & (parents < 0))[0]
    local_t[top], local_q[top] = world_t[top], world_q[top]
    return local_t.transpose(1, 0, 2), local_q.transpose(1, 0, 2)


def node_tracks(traj: Trajectory, shift=None) -> tuple[NodeTrack, ...]:
    """Tracks for the prey capsules (hidden by a zero scale once eaten; translations relative
    to the placement: trajectory position - shift, shift (3,) float64 metres = placement -
    origin) and, when the sun moves, the sun's rotation (its local -Z along the light)."""
    shift = np.zeros(3) if shift is None else np.asarray(shift, dtype=np.float64)
    tracks = []
    for j, name in enumerate(traj.prey_names):
        scale = np.where(np.asarray(traj.prey_visible[:, j])[:, None], 1.0, 0.0)
        tracks.append(NodeTrack(
            node=name,
            translations=(np.asarray(traj.prey_positions[:, j], dtype=np.float64)
                          - shift).astype(np.float32),
            rotations=sign_continuous(normalize_quats_f32(traj.prey_rotations[:, j])),
            scales=np.repeat(scale, 3, axis=1).astype(np.float32)))
    sun = traj.sun_directions
    if sun is not None and len(sun) > 1 and np.ptp(sun, axis=0).max() > 1e-9:
        tracks.append(NodeTrack(node="Sun", rotations=sign_continuous(
            normalize_quats_f32(light_rotation(sun)))))
    return tuple(tracks)
