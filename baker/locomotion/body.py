"""Follow-the-leader body: every segment sits on the head's trail at its fixed arc length behind
the head, a clearance above the surface, oriented by the surface normal and facing the segment
ahead. Vectorized over frames and segments, with one batch of ray casts for the whole bake.

The trail is the head's path projected onto the surface below (Embree rays). Its height profile is
smoothed along the trail and kept inside a band around the surface, so the spine rides over
creases and small steps without kinks: neighbouring joints keep their spacing, and every joint
stays between 0 and 2x the clearance above the surface below it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from baker.environment.rays import RayCaster
from baker.geometry import polyline
from baker.geometry.conventions import UP
from baker.geometry.transforms import frames_to_quat, normalize
from baker.locomotion.cobra import raise_front


@dataclass(frozen=True)
class BodyFrames:
    """positions : (F, S, 3) float64 metres, world; rotations : (F, S, 4) xyzw world;
    normals : (F, S, 3) unit surface normals under each joint; ground : (F, S) surface heights;
    lift : (F, S) cobra lift applied to each joint, metres (None: no lift requested)."""

    positions: np.ndarray
    rotations: np.ndarray
    normals: np.ndarray
    ground: np.ndarray
    lift: np.ndarray | None = None


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


@dataclass(frozen=True)
class Trail:
    """The head's trail on the surface, resampled uniformly in horizontal arc length.

    points  : (T, 3) float64, metres, world; y is the smoothed surface height
    normals : (T, 3) float64, smoothed unit surface normals
    ground  : (T,) float64, raw surface height under each point
    cum     : (T,) float64, 3D arc length along `points`
    cum_h   : (T,) float64, horizontal arc length of each point
    """

    points: np.ndarray
    normals: np.ndarray
    ground: np.ndarray
    cum: np.ndarray
    cum_h: np.ndarray

    def arc_at(self, horizontal_arc: np.ndarray) -> np.ndarray:
        """3D arc length at given horizontal arc lengths (exact, piecewise linear)."""
        return np.interp(horizontal_arc, self.cum_h, self.cum)


def build_trail(path: np.ndarray, rays: RayCaster, *, probe: float, spacing: float,
                clearance: float, resolution: float | None = None) -> Trail:
    """Project the head's path onto the surface and smooth its height profile.

    path       : (n, 3) float, head positions oldest first (heights approximate, within `probe`)
    spacing    : metres between spine joints; the smoothing scale
    clearance  : metres; the smoothed height stays within 0.9 clearance of the surface
    resolution : horizontal sample spacing (default spacing / 8)
    """
    res = resolution or spacing / 8.0
    flat = path.copy()
    flat[:, 1] = 0.0
    cum_h0 = polyline.arc_lengths(flat)
    n = max(int(np.ceil(cum_h0[-1] / res)), 1) + 1
    s = np.linspace(0.0, cum_h0[-1], n)
    pts = polyline.sample(path, cum_h0, s)
    ground_pts, normals, _ = project_to_surface(rays, pts, probe)
    ground = ground_pts[:, 1]
    sigma = 2.0 * spacing / res
    smooth = gaussian_filter1d(ground, sigma, mode="nearest")
    band = 0.95 * clearance
    y = np.clip(smooth, ground - band, ground + band)
    pts = ground_pts.copy()
    pts[:, 1] = y
    normals = normalize(gaussian_filter1d(normals, 0.5 * sigma, axis=0, mode="nearest"))
    return Trail(points=pts, normals=normals, ground=ground, cum=polyline.arc_lengths(pts), cum_h=s)


def body_frames(trail: Trail, head_arc: np.ndarray, spacing: float, segments: int,
                clearance: float, *, lift: np.ndarray | None = None, rays=None,
                ceiling_margin: float = 0.0) -> BodyFrames:
    """Place the spine on the trail.

    head_arc : (F,) float, 3D arc length of the head along the trail at each frame
    lift     : (F, S) optional cobra lift per joint (metres), limited by upward rays on `rays`
    """
    s = head_arc[:, None] - spacing * np.arange(segments)[None, :]            # (F, S)
    virt = polyline.sample(trail.points, trail.cum, s)                         # (F, S, 3)
    normals = normalize(polyline.sample(trail.normals, trail.cum, s))
    ground = np.interp(s, trail.cum, trail.ground)
    pos = virt + clearance * UP
    if lift is not None and lift.max(initial=0.0) > 0.0:
        pos, lift = raise_front(trail.points, trail.cum, head_arc, pos, lift, spacing, clearance,
                                rays, ceiling_margin)
        ground = ground.copy()
        raised = lift.max(axis=1) > 0
        if raised.any():  # re-read the surface under the re-placed joints
            g = project_to_surface(rays, pos[raised].reshape(-1, 3) - (clearance + lift[raised]).reshape(-1, 1) * UP,
                                   spacing)[0][:, 1]
            ground[raised] = g.reshape(-1, segments)
    forward = np.empty_like(pos)
    forward[:, 1:] = pos[:, :-1] - pos[:, 1:]
    head_dir = polyline.tangents(trail.points, trail.cum, head_arc)
    ahead = pos[:, 0] - pos[:, 1]
    forward[:, 0] = np.where(np.linalg.norm(head_dir, axis=1, keepdims=True) > 0.5, head_dir, ahead)
    rot = frames_to_quat(forward, normals)
    return BodyFrames(positions=pos, rotations=rot, normals=normals, ground=ground, lift=lift)
