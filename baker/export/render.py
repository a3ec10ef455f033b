"""CPU ray-cast pictures of a bake: Embree (embreex) rays, Lambert shading with the sun and its
shadows, a camera that follows the creature from a three-quarter view. No GPU, no OpenGL.

Each frame casts one batch of primary rays (one per pixel) and one batch of shadow rays toward
the sun (from every lit-facing hit point), against the environment (one Embree scene, built
once) and the frame's moving meshes (the skinned creature and the prey, a small scene built per
frame). Same scene and camera, same pixels.

    caster = environment_caster(scene)
    cams = follow_cameras(scene, frames, caster)
    frame = render_frame(scene, f, cams[k], 640, 360, caster)   # Frame: rgb, ids, points, ...
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from baker.environment.rays import RayCaster
from baker.export.preview_scene import PreviewScene
from baker.geometry.transforms import normalize

#: pixel ids (Frame.ids)
SKY, ENVIRONMENT, CREATURE, PREY = 0, 1, 2, 3
#: vertical field of view, degrees
VFOV_DEG = 40.0
#: camera distance from the creature's centre, body lengths
DISTANCE_BL = 1.45
#: camera candidates, best first: (azimuth from the creature's heading, elevation), degrees.
#: The first is the three-quarter front view; the others are used when the environment hides
#: the creature from it (under a leaf, behind a log).
CANDIDATES = ((40.0, 32.0), (-40.0, 32.0), (140.0, 32.0), (-140.0, 32.0), (40.0, 60.0),
              (-40.0, 60.0), (90.0, 18.0), (-90.0, 18.0), (0.0, 80.0), (180.0, 18.0),
              (0.0, 18.0))
#: score lost per candidate rank (prefers the three-quarter view) and per camera switch
RANK_COST, SWITCH_COST = 0.02, 0.25
#: light: sun and sky (hemisphere) radiance on a linear base colour, before the sRGB encoding
SUN_LIGHT, SKY_LIGHT = 2.6, 0.55
#: shadow rays start this many body lengths off the surface (against self-shadowing)
SHADOW_BIAS_BL = 2e-3
SKY_ZENITH = np.array([0.42, 0.60, 0.85])
SKY_HORIZON = np.array([0.80, 0.85, 0.90])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera: position and target (3,) float64 metres world, vertical fov degrees."""

    position: np.ndarray
    target: np.ndarray
    vfov_deg: float = VFOV_DEG

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(forward, right, up) unit vectors; up is as close to +Y as the view allows."""
        fwd = normalize(self.target - self.position)
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        if np.linalg.norm(right) < 1e-9:
            right = np.array([1.0, 0.0, 0.0])
        right = normalize(right)
        return fwd, right, np.cross(right, fwd)

    def rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(origins (h*w, 3), unit directions (h*w, 3)) through the pixel centres, row-major
        from the top-left pixel."""
        fwd, right, up = self.basis()
        th = np.tan(np.radians(self.vfov_deg) / 2.0)
        x = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * th * width / height
        y = (1.0 - 2.0 * (np.arange(height) + 0.5) / height) * th
        d = fwd + x[None, :, None] * right + y[:, None, None] * up
        d = d.reshape(-1, 3)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.position, d.shape), d

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """(n, 2) pixel coordinates (column, row) of world points (n, 3) in front of the camera."""
        fwd, right, up = self.basis()
        rel = np.asarray(points, dtype=np.float64) - self.position
        z = rel @ fwd
        th = np.tan(np.radians(self.vfov_deg) / 2.0)
        x = (rel @ right) / z / (th * width / height)
        y = (rel @ up) / z / th
        return np.stack([(x + 1.0) * width / 2.0, (1.0 - y) * height / 2.0], axis=1)


@dataclass(frozen=True)
class Frame:
    """One rendered picture.

    rgb    : (h, w, 3) uint8 sRGB
    ids    : (h, w) int8, what each pixel's primary ray hit: SKY, ENVIRONMENT, CREATURE, PREY
    points : (h, w, 3) float64 metres world hit points (NaN on SKY)
    lit    : (h, w) bool, the sun reaches the hit point (it faces the sun and no shadow ray
             toward the sun is blocked)
    """

    rgb: np.ndarray
    ids: np.ndarray
    points: np.ndarray
    lit: np.ndarray


def environment_caster(scene: PreviewScene) -> RayCaster:
    """The Embree scene of the environment (built once per preview)."""
    e = scene.env
    return RayCaster(trimesh.Trimesh(e.vertices, e.faces, process=False))


def moving_meshes(scene: PreviewScene, f: int):
    """(vertices (n, 3), faces (m, 3), normals (n, 3), colors (n, 3), ids (m,) int8) of the
    creature posed at frame f and the prey visible at f, as one mesh."""
    v, n = scene.skin.pose(scene.joint_matrices(f))
    parts = [(v, scene.skin.faces, n, scene.skin.colors, CREATURE)]
    for p in scene.prey:
        if p.visible(f):
            pv, pn = p.at(f)
            parts.append((pv, p.faces, pn, np.broadcast_to(p.color, pv.shape), PREY))
    offsets = np.cumsum([0] + [len(q[0]) for q in parts[:-1]])
    return (np.concatenate([q[0] for q in parts]),
            np.concatenate([q[1] + o for q, o in zip(parts, offsets)]),
            np.concatenate([q[2] for q in parts]), np.concatenate([q[3] for q in parts]),
            np.concatenate([np.full(len(q[1]), q[4], np.int8) for q in parts]))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (n, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.maximum(np.sqrt(_dot(a, a)), 1e-12)[:, None]


def _surface(caster: RayCaster, normals, colors, prim, uv, d):
    """(geometric normal, shading normal, colour) at hits on faces prim (k,) with barycentric
    coordinates uv (k, 2), both normals facing the ray (directions d (k, 3))."""
    f = caster.faces[prim]
    bary = np.column_stack([1.0 - uv[:, 0] - uv[:, 1], uv])
    ng = caster.face_normals[prim]
    ng = np.where((_dot(ng, d) > 0)[:, None], -ng, ng)
    ns = _unit(np.einsum("kj,kjc->kc", bary, normals[f]))
    ns = np.where((_dot(ns, ng) < 0)[:, None], -ns, ns)
    col = np.einsum("kj,kjc->kc", bary, colors[f])
    return ng, ns, np.clip(col, 0.0, 1.0)


def srgb(linear: np.ndarray) -> np.ndarray:
    """uint8 sRGB of linear values (clipped to [0, 1])."""
    c = np.clip(linear, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)


def render_frame(scene: PreviewScene, f: int, camera: Camera, width: int, height: int,
                 env: RayCaster) -> Frame:
    """Frame f seen by `camera`, width x height pixels (see the module docstring)."""
    mv, mf, mn, mc, mid = moving_meshes(scene, f)
    dyn = RayCaster(trimesh.Trimesh(mv, mf, process=False))
    o, d = camera.rays(width, height)
    n = len(d)
    t_env, p_env, uv_env = env.cast_uv(o, d)
    t_dyn, p_dyn, uv_dyn = dyn.cast_uv(o, d)
    use_dyn = t_dyn < t_env
    t = np.where(use_dyn, t_dyn, t_env)
    hit = np.flatnonzero(np.isfinite(t))                       # pixels that see something
    on_dyn = use_dyn[hit]
    ids = np.full(n, SKY, np.int8)
    ids[hit] = np.where(on_dyn, mid[np.maximum(p_dyn[hit], 0)], ENVIRONMENT)
    dh = d[hit]
    pts = camera.position + t[hit, None] * dh
    ng, ns, col = (np.empty((len(hit), 3)) for _ in range(3))
    for mask, caster, prim, uv, nrm, clr in (
            (~on_dyn, env, p_env, uv_env, scene.env.normals, scene.env.colors),
            (on_dyn, dyn, p_dyn, uv_dyn, mn, mc)):
        if mask.any():
            k = hit[mask]
            ng[mask], ns[mask], col[mask] = _surface(caster, nrm, clr, prim[k], uv[k], dh[mask])
    sun = scene.sun[f]
    cos = np.clip(ns @ sun, 0.0, None)
    facing = np.flatnonzero((ng @ sun > 0) & (cos > 0))
    lit = np.zeros(len(hit), bool)
    if len(facing):
        so = pts[facing] + ng[facing] * (SHADOW_BIAS_BL * scene.body_length)
        sd = np.broadcast_to(sun, so.shape)
        lit[facing] = (env.cast(so, sd)[1] < 0) & (dyn.cast(so, sd)[1] < 0)
    light = SUN_LIGHT * cos * lit + SKY_LIGHT * (0.7 + 0.3 * ns[:, 1])
    sky = SKY_HORIZON + (SKY_ZENITH - SKY_HORIZON) * np.sqrt(np.clip(d[:, 1], 0.0, 1.0))[:, None]
    rgb = np.round(sky * 255.0).astype(np.uint8)
    rgb[hit] = srgb(col * light[:, None])
    points = np.full((n, 3), np.nan)
    points[hit] = pts
    lit_all = np.zeros(n, bool)
    lit_all[hit] = lit
    return Frame(rgb=rgb.reshape(height, width, 3), ids=ids.reshape(height, width),
                 points=points.reshape(height, width, 3), lit=lit_all.reshape(height, width))


# ---------------------------------------------------------------- the camera


def _smooth(values: np.ndarray, frames: np.ndarray, half: int) -> np.ndarray:
    """values (F, ...) averaged over frames f-half..f+half (clamped), at `frames`."""
    c = np.cumsum(np.concatenate([np.zeros((1,) + values.shape[1:]), values]), axis=0)
    lo = np.clip(frames - half, 0, len(values) - 1)
    hi = np.clip(frames + half, 0, len(values) - 1) + 1
    return (c[hi] - c[lo]) / (hi - lo).reshape((-1,) + (1,) * (values.ndim - 1))


def _viterbi(score: np.ndarray, switch: float) -> np.ndarray:
    """(T,) candidate per step maximizing the summed score (T, K) less `switch` per change."""
    T, K = score.shape
    best = score[0].copy()
    back = np.zeros((T, K), np.int64)
    for k in range(1, T):
        stay = best
        move = best.max() - switch
        back[k] = np.where(stay >= move, np.arange(K), int(np.argmax(best)))
        best = np.maximum(stay, move) + score[k]
    path = np.zeros(T, np.int64)
    path[-1] = int(np.argmax(best))
    for k in range(T - 1, 0, -1):
        path[k - 1] = back[k, path[k]]
    return path


def follow_cameras(scene: PreviewScene, frames, env: RayCaster,
                   smooth_s: float = 0.5) -> list[Camera]:
    """A camera per frame in `frames`, following the creature: looking at its centre from
    DISTANCE_BL body lengths, from the best CANDIDATES view (the three-quarter front view
    unless the environment hides the spine from it), switching views rarely. The centre and
    heading are averaged over +-smooth_s seconds, so the slither does not shake the camera."""
    frames = np.asarray(frames, dtype=np.int64)
    spine = scene.baked.positions[:, scene.spine]                       # (F, S, 3)
    half = max(int(round(smooth_s * scene.fps)), 0)
    centre = _smooth(spine.mean(axis=1), frames, half)
    s = spine.shape[1]
    axis = spine[:, : s // 2].mean(axis=1) - spine[:, s // 2:].mean(axis=1)
    axis[:, 1] = 0.0
    axis = _smooth(axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12),
                   frames, half)
    yaw = np.arctan2(axis[:, 0], axis[:, 2])                            # from +Z toward +X
    cand = np.radians(np.asarray(CANDIDATES))
    az = yaw[:, None] + cand[None, :, 0]
    el = np.broadcast_to(cand[None, :, 1], az.shape)
    offset = np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)
    pos = centre[:, None, :] + DISTANCE_BL * scene.body_length * offset   # (T, K, 3)
    # visibility of every other spine joint from each candidate, environment only
    pts = spine[frames][:, ::2]                                          # (T, P, 3)
    vec = pts[:, None, :, :] - pos[:, :, None, :]                        # (T, K, P, 3)
    dist = np.linalg.norm(vec, axis=-1)
    o = np.broadcast_to(pos[:, :, None, :], vec.shape).reshape(-1, 3)
    blocked = env.occluded(o, vec.reshape(-1, 3),
                           np.maximum(dist.reshape(-1) - 0.02 * scene.body_length, 0.0))
    seen = 1.0 - blocked.reshape(dist.shape).mean(axis=-1)               # (T, K)
    score = seen - RANK_COST * np.arange(len(CANDIDATES))[None, :]
    pick = _viterbi(score, SWITCH_COST)
    return [Camera(position=pos[k, c], target=centre[k]) for k, c in enumerate(pick)]
