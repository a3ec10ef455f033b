"""The solve stage: one run's record -> trail -> body -> legs (and the prey) for every exported
frame, in vectorized passes over frames, joints and rays.

1. trail — the head path (after the straight start line) dropped onto the surface by batched
           rays, searched from below the agent's free height so overhangs are never hit
           (locomotion.body.build_trail);
2. body  — every spine joint on the trail at the head's arc length minus its spacing, with the
           cobra lift (locomotion.body.body_frames, locomotion.cobra.lift_profile);
3. legs  — legs, antennae and ultimate legs from the placed spine (locomotion.legs.leg_frames);
           in a crowd, after every body is placed, the ultimate legs and antennae raised clear
           of the other bodies they reach (locomotion.near.crowd_near);
4. prey  — on the surface, held at the head while fed on, hidden once eaten.
"""

from __future__ import annotations

import numpy as np

from scipy.spatial.transform import Rotation

from baker.behaviour.prey import HELD, HIDDEN
from baker.config import RigConfig
from baker.geometry import polyline
from baker.geometry.conventions import UP
from baker.geometry.transforms import frames_to_quat, quat_mul, quat_rotate
from baker.locomotion.body import (BodyFrames, body_frames, build_trail, project_to_surface,
                                   raised_for_hips, step_over_lips)
from baker.locomotion.cobra import lift_profile
from baker.locomotion.legs import hip_extent, hip_layout, leg_frames
from baker.locomotion.near import CrowdSpines, crowd_near
from baker.run.record import RunRecord
from baker.solve.trajectory import Trajectory

#: the head is never drawn over a face steeper than this (the quality limit on the head's
#: slope is 60 degrees) [rad]
LIP_SLOPE = np.radians(58.0)
#: how far along its trail a head sampled over a steep strip may move off it [spacings]
LIP_REACH = 0.5
#: at most this many raises of the trail where placed hips come too close to the surface
HIP_ROUNDS = 2


def solve(rec: RunRecord, rays, rig: RigConfig) -> Trajectory:
    """The creature's world frames at the export fps from its run."""
    return solve_limbs(rec, *solve_body(rec, rays, rig), rays, rig)


def solve_body(rec: RunRecord, rays, rig: RigConfig) -> tuple[BodyFrames, np.ndarray]:
    """(the spine's BodyFrames, the head's arc (F,) along its trail) of the creature's run at
    the export fps: steps 1 and 2."""
    body, navc = rig.body, rig.navigation
    probe = 0.5 * navc.height
    path = np.vstack([rec.start_line, rec.heads])
    trail = build_trail(path, rays, probe=probe, spacing=body.spacing, clearance=body.clearance,
                        hips=hip_extent(rig))
    flat = path.copy()
    flat[:, 1] = 0.0
    cum_h = polyline.arc_lengths(flat)
    lift = lift_profile(rec.cobra, rig.cobra.curve, rig.cobra.height, body.segments)
    hips, hip_joints = hip_layout(rig)
    for rounds in range(HIP_ROUNDS, -1, -1):
        head_arc = trail.arc_at(cum_h[len(rec.start_line) + rec.frame_steps])
        head_arc = step_over_lips(trail, head_arc, rays, body.clearance, LIP_SLOPE,
                                  reach=LIP_REACH * body.spacing,
                                  depth=0.5 * body.spacing * body.segments)
        bf = body_frames(trail, head_arc, body.spacing, body.segments, body.clearance,
                         lift=lift, rays=rays, ceiling_margin=rig.cobra.ceiling_margin,
                         fps=rec.fps, ramp_time=rig.cobra.ramp_time)
        # a hip placed over ground its trail's sides never sampled raises the trail there
        raised = (raised_for_hips(trail, bf, rays, hips, hip_joints, body.clearance,
                                  body.spacing) if rounds and len(hips) else None)
        if raised is None:
            break
        trail = raised
    return bf, head_arc


def solve_limbs(rec: RunRecord, bf: BodyFrames, head_arc: np.ndarray, rays, rig: RigConfig,
                crowd: CrowdSpines | None = None, index: int = 0) -> Trajectory:
    """The creature's Trajectory from its placed spine (solve_body): steps 3 and 4. In a crowd
    whose placed spines are `crowd`'s, this one's `index`: its ultimate legs and antennae
    raise clear of the other bodies they reach (locomotion.near.crowd_near)."""
    times = rec.times
    limbs = {}
    if rig.legs.enabled:
        near = None if crowd is None else crowd_near(rays, crowd, index, rig)
        lf = leg_frames(bf, head_arc, times, rays, rig, warning=rec.warning,
                        chain_period=rec.chain_period, near=near)
        limbs = dict(joint_names=lf.names, joint_positions=lf.positions,
                     joint_rotations=lf.rotations, foot_contacts=lf.contacts)
    prey_t = (prey_frames(rec.prey_names, rec.prey_positions, rec.prey_modes, bf.positions[:, 0],
                          bf.rotations[:, 0], rays, rig) if rec.prey_names else {})
    return Trajectory(
        times=times,
        spine_positions=bf.positions,
        spine_rotations=bf.rotations,
        head_surface_normal=bf.normals[:, 0],
        ground_heights=bf.ground,
        events=rec.events,
        cobra_lift=bf.lift,
        warning=rec.warning,
        sun_directions=rec.sun_directions,
        head_arc=head_arc,
        slither_phase=rec.slither,
        **limbs,
        **prey_t,
    )


def prey_frames(names, positions: np.ndarray, modes: np.ndarray, head_p: np.ndarray,
                head_q: np.ndarray, rays, rig: RigConfig) -> dict:
    """World frames of every prey capsule: on the surface while free or captured, held at the
    head while a centipede feeds, hidden (scale 0) once eaten.

    names : P names; positions (F, P, 3) on the prey agents' paths; modes (F, P) int8
    head_p, head_q : the holding head's positions and rotations (xyzw): (F, 3) and (F, 4) for a
                     lone creature, (F, P, 3) and (F, P, 4) per prey in a crowd
    """
    probe = 0.5 * rig.navigation.height
    pos = positions.copy()
    F, P, _ = pos.shape
    flat = pos.reshape(-1, 3)
    ground, _, hit = project_to_surface(rays, flat, probe)
    flat[hit] = ground[hit]
    pos = flat.reshape(F, P, 3) + rig.prey.radius * UP
    # heading from motion, held when still
    fwd = np.zeros_like(pos)
    fwd[1:] = pos[1:] - pos[:-1]
    fwd[..., 1] = 0.0
    moving = np.linalg.norm(fwd, axis=-1) > 1e-6
    fwd[0] = np.array([0.0, 0.0, 1.0])
    moving[0] = True
    # carry the last heading through stops: forward-fill the index of the last moving frame
    last = np.maximum.accumulate(np.where(moving, np.arange(F)[:, None], 0), axis=0)
    fwd = fwd[last, np.arange(P)[None, :]]
    rot = frames_to_quat(fwd, np.broadcast_to(UP, fwd.shape))
    held = modes == HELD
    if held.any():
        ahead = quat_rotate(head_q, np.array([0.0, 0.0, 1.0]))
        below = quat_rotate(head_q, np.array([0.0, -1.0, 0.0]))
        grip = (head_p + ahead * (0.5 * rig.prey.length + 0.25 * rig.body.spacing)
                + below * 0.25 * rig.prey.radius)
        f_idx, j_idx = np.nonzero(held)
        at = f_idx if head_p.ndim == 2 else (f_idx, j_idx)
        pos[f_idx, j_idx] = grip[at]
        side = quat_mul(head_q, Rotation.from_euler("y", np.pi / 2).as_quat())
        rot[f_idx, j_idx] = side[at]
    return dict(prey_names=tuple(names), prey_positions=pos, prey_rotations=rot,
                prey_visible=modes != HIDDEN, prey_modes=modes)
