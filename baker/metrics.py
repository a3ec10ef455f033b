"""Motion-quality metrics, computed independently of the simulation from its output and the
environment, so tests and users can check a bake by its numbers."""

from __future__ import annotations

import numpy as np

from baker.geometry.conventions import UP
from baker.geometry.transforms import quat_conj, quat_mul
from baker.sim.trajectory import Trajectory


def spine_metrics(traj: Trajectory, rays, *, spacing: float, clearance: float,
                  max_slope: float, body_length: float) -> dict:
    """Spine metrics over every frame.

    - clearance: height of each trunk joint above the first surface straight below it,
      as a multiple of the rig clearance (the issue bound is [0, 2]);
    - spacing: relative error of the distance between neighbouring spine joints;
    - head slope: angle of the surface under the head (max slope is the walkable limit);
    - rotation: largest change of any joint's world orientation between frames;
    - NaN count over positions and rotations.
    """
    pos = traj.spine_positions
    F, S, _ = pos.shape
    nan = int(np.count_nonzero(~np.isfinite(pos)) + np.count_nonzero(~np.isfinite(traj.spine_rotations)))

    trunk = pos[:, 1:].reshape(-1, 3)
    down = np.tile(-UP, (len(trunk), 1))
    h = rays.first_hit(trunk, down, max_distance=10.0 * max(clearance, 1e-3))
    ratio = np.where(h.hit, h.distance / max(clearance, 1e-12), np.inf)

    gaps = np.linalg.norm(np.diff(pos, axis=1), axis=2) / spacing - 1.0

    hh = rays.first_hit(pos[:, 0], np.tile(-UP, (F, 1)), max_distance=10.0 * max(clearance, 1e-3))
    cosang = np.abs(hh.normals[hh.hit, 1])
    slope = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))) if len(cosang) else np.zeros(1)

    q = traj.spine_rotations
    dq = quat_mul(quat_conj(q[:-1]), q[1:]) if F > 1 else np.zeros((0, S, 4)) + [0, 0, 0, 1]
    rot = np.degrees(2.0 * np.arccos(np.clip(np.abs(dq[..., 3]), 0.0, 1.0)))

    step = np.linalg.norm(np.diff(pos[:, 0], axis=0), axis=1)
    return {
        "frames": int(F),
        "distance_walked_m": float(step.sum()),
        "distance_walked_body_lengths": float(step.sum() / body_length),
        "clearance_ratio_min": float(ratio.min()),
        "clearance_ratio_max": float(ratio.max()),
        "clearance_violations": int(np.count_nonzero((ratio < 0) | (ratio > 2.0))),
        "spacing_error_max": float(np.abs(gaps).max()),
        "head_slope_max_deg": float(slope.max()),
        "head_unsupported_frames": int(np.count_nonzero(~hh.hit)),
        "frames_on_unwalkable_slope": int(np.count_nonzero(slope > np.degrees(max_slope) + 1e-6)),
        "max_joint_rotation_per_frame_deg": float(rot.max()) if rot.size else 0.0,
        "nan_count": nan,
    }
