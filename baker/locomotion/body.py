"""Follow-the-leader body: every segment sits on the head's trail at its fixed arc length
behind the head, is projected onto the surface below and oriented by the surface normal,
facing the segment ahead. Vectorized over frames and segments: one ray batch for the bake."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.environment.rays import RayCaster
from baker.geometry import polyline
from baker.geometry.conventions import UP
from baker.geometry.transforms import frames_to_quat, normalize


@dataclass(frozen=True)
class BodyFrames:
    """positions : (F, S, 3) float64 metres, world; rotations : (F, S, 4) xyzw world;
    normals : (F, S, 3) unit surface normals under each joint; ground : (F, S) surface heights."""

    positions: np.ndarray
    rotations: np.ndarray
    normals: np.ndarray
    ground: np.ndarray


def project_to_surface(rays: RayCaster, points: np.ndarray, probe: float):
    """Drop points onto the surface below them.

    points : (n, 3) float, near the surface (within `probe` metres above or below it)
    returns (surface points (n, 3), up-facing unit normals (n, 3), hit (n,) bool); points that
    miss keep their position and get UP as the normal.
    """
    hits = rays.cast_down(points, probe, max_distance=3.0 * probe)
    out = points.copy()
    nrm = np.tile(UP, (len(points), 1))
    out[hits.hit] = hits.points[hits.hit]
    n = hits.normals[hits.hit]
    n[n[:, 1] < 0] *= -1.0
    nrm[hits.hit] = n
    return out, nrm, hits.hit


def body_frames(trail: np.ndarray, head_arc: np.ndarray, spacing: float, segments: int,
                clearance: float, rays: RayCaster, probe: float) -> BodyFrames:
    """Place the spine on the trail.

    trail    : (T, 3) float, head trail on the surface, oldest first (includes the initial body)
    head_arc : (F,) float, arc length of the head along `trail` at each frame
    spacing  : metres between neighbouring joints along the trail
    probe    : metres above a trail point from which the surface is searched (less than the
               free height of the walkable layer, so an overhang is never hit)
    """
    cum = polyline.arc_lengths(trail)
    s = head_arc[:, None] - spacing * np.arange(segments)[None, :]            # (F, S)
    virt = polyline.sample(trail, cum, s)                                        # (F, S, 3)
    F = len(head_arc)
    ground, normals, _ = project_to_surface(rays, virt.reshape(-1, 3), probe)
    ground = ground.reshape(F, segments, 3)
    normals = normals.reshape(F, segments, 3)
    # Smooth normals along the body (1-2-1) so triangle edges do not make the spine jitter.
    pad = np.concatenate([normals[:, :1], normals, normals[:, -1:]], axis=1)
    normals = normalize(pad[:, :-2] + 2.0 * pad[:, 1:-1] + pad[:, 2:])
    pos = ground + clearance * UP
    forward = np.empty_like(pos)
    forward[:, 1:] = pos[:, :-1] - pos[:, 1:]
    head_dir = polyline.tangents(trail, cum, head_arc)
    ahead = pos[:, 0] - pos[:, 1]
    # The head faces along the trail; fall back to the neck direction where the trail is flat.
    forward[:, 0] = np.where(np.linalg.norm(head_dir, axis=1, keepdims=True) > 0.5, head_dir, ahead)
    rot = frames_to_quat(forward, normals)
    return BodyFrames(positions=pos, rotations=rot, normals=normals, ground=ground[..., 1])
