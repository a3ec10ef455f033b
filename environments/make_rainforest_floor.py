"""Generate the bundled environment `environments/rainforest_floor.glb`.

A rainforest floor for a 0.25 m centipede (body length BL = 0.25 m):

- ground: a 22.5 m (90 BL) square of dull soil, gently undulating (slopes well under 30 deg);
- hollow half logs: squashed half-cylinder shells lying open side down, sunk into the ground so
  that the outer wall meets the ground at a walkable slope (<= ~52 deg) and leaves a tunnel
  with more than 0.05 m of headroom inside;
- rocks and stones (squashed spheres) and twigs, bark slabs, stumps and blocks (boxes), randomly
  rotated and partly embedded: the low ones are climbable, the tall ones are not;
- a directional sun about 28 deg from the zenith (glTF KHR_lights_punctual).

The output is deterministic: `python environments/make_rainforest_floor.py` rewrites the GLB
byte for byte (positions are quantized to 2**-16 m, the JSON has no timestamps).

Usage: python environments/make_rainforest_floor.py [--seed N] [--out PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DEFAULT_SEED = 20180501
DEFAULT_OUT = Path(__file__).resolve().parent / "rainforest_floor.glb"

BODY_LENGTH = 0.25          # [m] the centipede this floor is sized for
GROUND_SIZE = 90 * BODY_LENGTH  # [m] 22.5 m square
GROUND_CELL = 0.25          # [m] ground grid spacing
SUN_ZENITH_DEG = 28.0       # angle of the sun from vertical
SUN_AZIMUTH_DEG = 35.0      # measured from +X toward +Z
SUN_INTENSITY = 3.0         # [lux] dark forest floor
SUN_COLOR = (1.0, 0.95, 0.85)
QUANTUM = 2.0 ** -16        # [m] position quantization (exact in float32 below 256 m)


def srgb_to_linear(rgb) -> tuple[float, float, float, float]:
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return (round(float(lin[0]), 6), round(float(lin[1]), 6), round(float(lin[2]), 6), 1.0)


# name -> linear RGBA base colour (sRGB bytes converted)
MATERIALS = {
    "soil": srgb_to_linear((72, 63, 57)),
    "moss": srgb_to_linear((14, 64, 31)),
    "rock": srgb_to_linear((92, 88, 80)),
    "bark": srgb_to_linear((58, 42, 30)),
}


def sum_of_waves(x, z, k, amp, phase, h=None) -> np.ndarray:
    """`h` (default 0) plus the plane waves amp * sin(k . (x, z) + phase), added in order."""
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    h = np.zeros(np.broadcast(x, z).shape) if h is None else h
    for kk, a, p in zip(k, amp, phase):
        h = h + a * np.sin(kk[0] * x + kk[1] * z + p)
    return h


@dataclass(frozen=True)
class Part:
    """One mesh of the floor. vertices (n, 3) float64 world metres; faces (m, 3) int64;
    normals (n, 3) float64 unit."""

    name: str
    material: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray


@dataclass(frozen=True)
class SunSpec:
    direction: np.ndarray  # (3,) unit, toward the sun
    intensity: float
    color: tuple[float, float, float]


# --------------------------------------------------------------------------- ground
class Ground:
    """Height field y = h(x, z): a sum of long-wavelength sinusoids plus a faint ripple."""

    def __init__(self, rng: np.random.Generator):
        n = 7
        self.wavelength = rng.uniform(3.0, 9.0, n)
        ang = rng.uniform(0.0, 2.0 * np.pi, n)
        wavenumber = 2 * np.pi / self.wavelength
        self.k = np.stack([np.cos(ang), np.sin(ang)], axis=1) * wavenumber[:, None]
        self.amp = self.wavelength * rng.uniform(0.004, 0.008, n)  # slope per wave <= 0.05
        self.phase = rng.uniform(0.0, 2.0 * np.pi, n)
        r_ang = rng.uniform(0.0, 2.0 * np.pi, 3)
        self.rk = np.stack([np.cos(r_ang), np.sin(r_ang)], axis=1) * (2 * np.pi / 1.3)
        self.ramp = np.full(3, 0.006)
        self.rphase = rng.uniform(0.0, 2.0 * np.pi, 3)

    def height(self, x, z) -> np.ndarray:
        h = sum_of_waves(x, z, self.k, self.amp, self.phase)
        return sum_of_waves(x, z, self.rk, self.ramp, self.rphase, h)

    def part(self) -> Part:
        n = int(round(GROUND_SIZE / GROUND_CELL)) + 1
        c = np.linspace(-GROUND_SIZE / 2, GROUND_SIZE / 2, n)
        X, Z = np.meshgrid(c, c, indexing="xy")  # X varies along columns
        Y = self.height(X, Z)
        v = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
        i = np.arange(n * n).reshape(n, n)
        a, b, cc, d = i[:-1, :-1], i[:-1, 1:], i[1:, :-1], i[1:, 1:]
        # counter-clockwise seen from above (+Y): (x, z) -> (x+1, z) -> (x, z+1) is clockwise
        # in the x-z plane seen from +Y, so use a, cc, b.
        f = np.concatenate([np.stack([a, cc, b], -1).reshape(-1, 3),
                            np.stack([b, cc, d], -1).reshape(-1, 3)])
        return make_part("ground", "soil", v, f, up_hint=np.array([0.0, 1.0, 0.0]))


# --------------------------------------------------------------------------- mesh helpers
def quantize(v: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(v, dtype=np.float64) / QUANTUM) * QUANTUM


def face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Unnormalized (area-weighted) face normals."""
    return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])


def vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    fn = face_normals(v, f)
    vn = np.zeros_like(v)
    for j in range(3):
        np.add.at(vn, f[:, j], fn)  # unbuffered, sequential: deterministic
    length = np.sqrt((vn * vn).sum(axis=1, keepdims=True))
    return vn / np.maximum(length, 1e-20)


def orient(v: np.ndarray, f: np.ndarray, outward: np.ndarray) -> np.ndarray:
    """Flip faces whose normal points against `outward` ((m, 3) per face or (3,))."""
    fn = face_normals(v, f)
    bad = (fn * outward).sum(axis=1) < 0
    f = f.copy()
    f[bad] = f[bad][:, ::-1]
    return f


def make_part(name, material, v, f, up_hint=None, outward=None) -> Part:
    v = quantize(v)
    f = np.asarray(f, dtype=np.int64)
    if outward is not None:
        f = orient(v, f, outward)
    elif up_hint is not None:
        f = orient(v, f, up_hint)
    return Part(name, material, v, f, vertex_normals(v, f))


def merge(name, material, pieces) -> Part:
    """Concatenate (v, f, n) pieces (each already oriented, sharp edges between pieces)."""
    vs, fs, ns, off = [], [], [], 0
    for v, f, n in pieces:
        vs.append(v)
        fs.append(f + off)
        ns.append(n)
        off += len(v)
    return Part(name, material, np.concatenate(vs), np.concatenate(fs), np.concatenate(ns))


def grid_faces(rows: int, cols: int) -> np.ndarray:
    i = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = i[:-1, :-1], i[:-1, 1:], i[1:, :-1], i[1:, 1:]
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                           np.stack([b, d, c], -1).reshape(-1, 3)])


def piece(v, f, outward) -> tuple:
    v = quantize(v)
    f = orient(v, np.asarray(f, dtype=np.int64), outward)
    return v, f, vertex_normals(v, f)


def rotation_matrix(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def random_rotation(rng, max_tilt=None) -> np.ndarray:
    """A rotation: a yaw about +Y, then (if max_tilt is given) a tilt of at most max_tilt about
    a random horizontal axis; with max_tilt None, uniformly random."""
    if max_tilt is None:
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        x, y, z, w = q
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    yaw = rotation_matrix([0, 1, 0], rng.uniform(0, 2 * np.pi))
    a = rng.uniform(0, 2 * np.pi)
    tilt = rotation_matrix([math.cos(a), 0, math.sin(a)], rng.uniform(0, max_tilt))
    return tilt @ yaw


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    t = (1.0 + 5 ** 0.5) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = np.array(v, dtype=np.float64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    f = np.array(f, dtype=np.int64)
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        mid = v[uniq].mean(axis=1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(f)
        e01, e12, e20 = inv[:m] + len(v), inv[m:2 * m] + len(v), inv[2 * m:] + len(v)
        v = np.concatenate([v, mid])
        f = np.concatenate([np.stack([f[:, 0], e01, e20], 1), np.stack([f[:, 1], e12, e01], 1),
                            np.stack([f[:, 2], e20, e12], 1), np.stack([e01, e12, e20], 1)])
    return v, f


def box_pieces(half: np.ndarray, R: np.ndarray, centre: np.ndarray) -> list:
    """A box as 6 flat quads (sharp edges), rotated by R and moved to centre."""
    out = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, w = [a for a in range(3) if a != axis]
            corners = []
            for su, sw in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis] = sign * half[axis]
                p[u] = su * half[u]
                p[w] = sw * half[w]
                corners.append(p)
            v = np.array(corners) @ R.T + centre
            normal = np.zeros(3)
            normal[axis] = sign
            out.append(piece(v, [[0, 1, 2], [0, 2, 3]], R @ normal))
    return out


# --------------------------------------------------------------------------- logs
@dataclass(frozen=True)
class LogShape:
    a: float          # [m] horizontal semi-axis of the outer ellipse
    b: float          # [m] vertical semi-axis of the outer ellipse
    t: float          # [m] shell thickness
    foot_slope: float  # [rad] outer slope where the shell meets the ground
    bury: float       # [m] how far the shell continues below the ground line

    @property
    def theta0(self) -> float:
        """Outer-ellipse angle where the ground line cuts it (slope = foot_slope)."""
        return math.atan2(1.0, math.tan(self.foot_slope) * self.a / self.b)

    @property
    def ground_y(self) -> float:
        """Ground line height above the ellipse centre."""
        return self.b * math.sin(self.theta0)

    @property
    def half_width(self) -> float:
        return self.a * math.cos(self.theta0)

    @property
    def headroom(self) -> float:
        """Free height inside at the centre line."""
        return self.b - self.t - self.ground_y


def log_part(name: str, ground: Ground, centre_xz, yaw: float, length: float, shape: LogShape,
             n_arc: int = 28) -> Part:
    """A hollow half log lying open side down along direction `yaw`, following the ground."""
    u = np.array([math.cos(yaw), 0.0, math.sin(yaw)])   # axis
    w = np.array([-math.sin(yaw), 0.0, math.cos(yaw)])  # across
    n_slices = max(8, int(math.ceil(length / 0.04)) + 1)
    s = np.linspace(-length / 2, length / 2, n_slices)
    axis_pts = np.array([centre_xz[0], 0.0, centre_xz[1]]) + s[:, None] * u
    hw = shape.half_width
    hp = ground.height(axis_pts[:, 0] + hw * w[0], axis_pts[:, 2] + hw * w[2])
    hm = ground.height(axis_pts[:, 0] - hw * w[0], axis_pts[:, 2] - hw * w[2])
    roll = np.arctan2(hp - hm, 2 * hw)                    # (S,) follow the cross slope
    centre_y = (hp + hm) / 2 - shape.ground_y             # (S,)

    cut = shape.ground_y - shape.bury                     # profile cut height (below ground)
    th_o = math.asin(cut / shape.b)
    th_i = math.asin(cut / (shape.b - shape.t))
    to = np.linspace(th_o, np.pi - th_o, n_arc)
    ti = np.linspace(th_i, np.pi - th_i, n_arc)
    outer2 = np.stack([shape.a * np.cos(to), shape.b * np.sin(to)], 1)             # (A, 2)
    inner2 = np.stack([(shape.a - shape.t) * np.cos(ti), (shape.b - shape.t) * np.sin(ti)], 1)

    def place(profile2):
        """(A, 2) profile (across, up) -> (S, A, 3) world points."""
        c, sn = np.cos(roll)[:, None], np.sin(roll)[:, None]
        x2 = c * profile2[None, :, 0] - sn * profile2[None, :, 1]   # rotate in the slice plane
        y2 = sn * profile2[None, :, 0] + c * profile2[None, :, 1]
        return (axis_pts[:, None, :] + x2[..., None] * w + (centre_y[:, None] + y2)[..., None]
                * np.array([0.0, 1.0, 0.0]))

    P_out, P_in = place(outer2), place(inner2)
    axis_centre = axis_pts + centre_y[:, None] * np.array([0.0, 1.0, 0.0])
    pieces = []
    # outer and inner surfaces: (S, A) grids
    f = grid_faces(n_slices, n_arc)
    v = P_out.reshape(-1, 3)
    out_dir = v - np.repeat(axis_centre, n_arc, axis=0)
    pieces.append(piece(v, f, out_dir[f[:, 0]]))
    v = P_in.reshape(-1, 3)
    in_dir = np.repeat(axis_centre, n_arc, axis=0) - v
    pieces.append(piece(v, f, in_dir[f[:, 0]]))
    # end caps: strips between outer and inner profile at each end
    for k, sign in ((0, -1.0), (n_slices - 1, 1.0)):
        v = np.concatenate([P_out[k], P_in[k]])
        cf = grid_faces(2, n_arc)
        pieces.append(piece(v, cf, sign * u))
    # feet: strips along the log between outer and inner edge at both sides
    for j in (0, n_arc - 1):
        v = np.concatenate([P_out[:, j], P_in[:, j]])
        pieces.append(piece(v, grid_faces(2, n_slices), np.array([0.0, -1.0, 0.0])))
    return merge(name, "moss", pieces)


# --------------------------------------------------------------------------- placement
class Footprints:
    """2D capsules (segment p0-p1 in x-z, radius) used to keep objects apart."""

    def __init__(self):
        self.items: list[tuple[np.ndarray, np.ndarray, float]] = []

    @staticmethod
    def seg_dist(p0, p1, q0, q1) -> float:
        def pt_seg(p, a, b):
            ab = b - a
            d = float(ab @ ab)
            t = 0.0 if d == 0 else min(1.0, max(0.0, float((p - a) @ ab) / d))
            return float(np.linalg.norm(p - (a + t * ab)))
        # segments in 2D: if they cross the distance is 0
        def cross(o, a, b):
            return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        d1, d2 = cross(q0, q1, p0), cross(q0, q1, p1)
        d3, d4 = cross(p0, p1, q0), cross(p0, p1, q1)
        if d1 * d2 < 0 and d3 * d4 < 0:
            return 0.0
        return min(pt_seg(p0, q0, q1), pt_seg(p1, q0, q1), pt_seg(q0, p0, p1), pt_seg(q1, p0, p1))

    def free(self, p0, p1, r, gap) -> bool:
        lim = GROUND_SIZE / 2 - 0.75
        for p in (p0, p1):
            if abs(p[0]) + r > lim or abs(p[1]) + r > lim:
                return False
        if self.seg_dist(p0, p1, np.zeros(2), np.zeros(2)) < r + 0.75:  # clear spawn area
            return False
        return all(self.seg_dist(p0, p1, a, b) >= r + rb + gap for a, b, rb in self.items)

    def add(self, p0, p1, r):
        self.items.append((np.asarray(p0, float), np.asarray(p1, float), float(r)))


def place(rng, fp: Footprints, half_len: float, r: float, gap: float, tries: int = 2000):
    """Random (centre_xz, yaw) whose capsule is free; registers it. None when it fails."""
    lim = GROUND_SIZE / 2 - 0.75
    for _ in range(tries):
        c = rng.uniform(-lim, lim, 2)
        yaw = rng.uniform(0.0, 2.0 * np.pi)
        d = np.array([math.cos(yaw), math.sin(yaw)]) * half_len
        if fp.free(c - d, c + d, r, gap):
            fp.add(c - d, c + d, r)
            return c, yaw
    return None


# --------------------------------------------------------------------------- the scene
def make_rainforest_floor(seed: int = DEFAULT_SEED) -> tuple[list[Part], SunSpec]:
    """Build the floor. Returns (parts, sun); parts are in world space (metres, +Y up)."""
    rng = np.random.default_rng(seed)
    ground = Ground(rng)
    parts = [ground.part()]
    fp = Footprints()

    # hollow half logs
    for i in range(4):
        a = rng.uniform(0.23, 0.28)
        shape = LogShape(a=a, b=a * rng.uniform(0.76, 0.82), t=0.018,
                         foot_slope=math.radians(50.0), bury=0.03)
        length = rng.uniform(1.2, 2.0)
        c, yaw = place(rng, fp, length / 2, shape.half_width + 0.1, gap=0.45)
        parts.append(log_part(f"log_{i + 1:02d}", ground, c, yaw, length, shape))

    sphere_lo = icosphere(2)
    sphere_hi = icosphere(3)

    def ellipsoid(name, material, radii, R, centre, hi=False):
        v, f = sphere_hi if hi else sphere_lo
        p = (v * radii) @ R.T + centre
        outward = ((v / radii) @ R.T)[f[:, 0]]  # gradient direction of the ellipsoid
        vv, ff, nn = piece(p, f, outward)
        return Part(name, material, vv, ff, nn)

    # large rocks: steep, not climbable
    for i in range(6):
        A = rng.uniform(0.2, 0.55)
        radii = A * np.array([1.0, rng.uniform(0.6, 0.95), rng.uniform(0.75, 1.0)])
        c, _ = place(rng, fp, 0.0, A, gap=0.3)
        R = random_rotation(rng)
        h = ground.height(c[0], c[1])
        centre = np.array([c[0], h + radii.min() * rng.uniform(0.2, 0.5), c[1]])
        parts.append(ellipsoid(f"rock_{i + 1:02d}", "rock", radii, R, centre, hi=True))

    # low flat stones: climbable (top slope <= 45 deg, at most 4.5 cm above the ground)
    for i in range(10):
        A = rng.uniform(0.08, 0.3)
        cz = A * rng.uniform(0.25, 0.4)                   # vertical semi-axis
        ratio = rng.uniform(0.7, 1.0)                     # second horizontal semi-axis / A
        # the ground cuts the ellipsoid where its slope (across the narrow axis) is 45 deg
        th_min = math.atan2(1.0, math.tan(math.radians(45.0)) * ratio * A / cz)
        h_max = cz * (1.0 - math.sin(th_min))
        h = min(rng.uniform(0.02, 0.045), h_max)
        c, _ = place(rng, fp, 0.0, A, gap=0.25)
        R = random_rotation(rng, max_tilt=math.radians(4.0))
        g = ground.height(c[0], c[1])
        centre = np.array([c[0], g + h - cz, c[1]])
        parts.append(ellipsoid(f"stone_{i + 1:02d}", "rock", np.array([A, cz, ratio * A]), R,
                               centre, hi=True))

    # twigs: thin boxes lying on the ground, easy to step over
    for i in range(10):
        length = rng.uniform(0.4, 0.9)
        thick = rng.uniform(0.015, 0.035)
        c, yaw = place(rng, fp, length / 2, 0.05, gap=0.15)
        d = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
        e0, e1 = (np.array([c[0], 0, c[1]]) + s * d * length / 2 for s in (-1, 1))
        y0, y1 = ground.height(e0[0], e0[2]), ground.height(e1[0], e1[2])
        pitch = math.atan2(y1 - y0, length)
        R = rotation_matrix([0, 1, 0], -yaw) @ rotation_matrix([0, 0, 1], pitch)
        R = R @ rotation_matrix([1, 0, 0], rng.uniform(0, np.pi / 2))  # roll about its length
        centre = np.array([c[0], (y0 + y1) / 2 + thick * 0.15, c[1]])
        parts.append(merge(f"twig_{i + 1:02d}", "bark",
                           box_pieces(np.array([length / 2, thick / 2, thick / 2]), R, centre)))

    # bark slabs: flat boxes, top at most ~4 cm above the ground, nearly level: climbable
    for i in range(6):
        half = np.array([rng.uniform(0.08, 0.2), rng.uniform(0.015, 0.025),
                         rng.uniform(0.06, 0.15)])
        c, _ = place(rng, fp, 0.0, float(np.hypot(half[0], half[2])), gap=0.2)
        R = random_rotation(rng, max_tilt=math.radians(6.0))
        g = ground.height(c[0], c[1])
        centre = np.array([c[0], g + half[1] * 0.4, c[1]])
        parts.append(merge(f"slab_{i + 1:02d}", "bark", box_pieces(half, R, centre)))

    # stumps: tall upright boxes, not climbable
    for i in range(4):
        half = np.array([rng.uniform(0.1, 0.17), rng.uniform(0.2, 0.35), rng.uniform(0.1, 0.17)])
        c, _ = place(rng, fp, 0.0, float(np.hypot(half[0], half[2])), gap=0.3)
        R = random_rotation(rng, max_tilt=math.radians(8.0))
        g = ground.height(c[0], c[1])
        centre = np.array([c[0], g + half[1] - 0.08, c[1]])
        parts.append(merge(f"stump_{i + 1:02d}", "bark", box_pieces(half, R, centre)))

    # blocks: randomly rotated boxes half sunk into the ground, steep
    for i in range(5):
        half = rng.uniform(0.07, 0.2, 3)
        c, _ = place(rng, fp, 0.0, float(np.linalg.norm(half)), gap=0.25)
        R = random_rotation(rng)
        g = ground.height(c[0], c[1])
        centre = np.array([c[0], g + half.min() * 0.5, c[1]])
        parts.append(merge(f"block_{i + 1:02d}", "rock", box_pieces(half, R, centre)))

    zen, az = math.radians(SUN_ZENITH_DEG), math.radians(SUN_AZIMUTH_DEG)
    sun_dir = np.array([math.sin(zen) * math.cos(az), math.cos(zen), math.sin(zen) * math.sin(az)])
    return parts, SunSpec(direction=sun_dir, intensity=SUN_INTENSITY, color=SUN_COLOR)


# --------------------------------------------------------------------------- GLB writer
def _quat_z_to(d: np.ndarray) -> list[float]:
    """xyzw unit quaternion rotating +Z onto unit vector d."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ d)
    if c < -1 + 1e-12:
        return [0.0, 1.0, 0.0, 0.0]
    axis = np.cross(z, d)
    q = np.array([axis[0], axis[1], axis[2], 1.0 + c])
    q /= np.linalg.norm(q)
    return [round(float(x), 9) for x in q]  # rounded: the JSON text must not vary by platform


def build_glb(parts: list[Part], sun: SunSpec, seed: int, *, materials: dict | None = None,
              scene_name: str = "rainforest_floor",
              generator: str = "baker environments/make_rainforest_floor.py",
              extras: dict | None = None, double_sided: tuple[str, ...] = (),
              sun_extras: dict | None = None) -> bytes:
    """Serialize the floor as GLB 2.0 bytes (deterministic). `materials` (name -> linear RGBA,
    default MATERIALS), the scene's name, the generator string and extra scene extras let other
    generators (make_showcase.py) share this writer; `double_sided` names materials of thin
    sheets (leaves) seen from both sides; `sun_extras` go to the light's extras."""
    materials_rgba = MATERIALS if materials is None else materials
    blob = bytearray()
    buffer_views, accessors = [], []

    def add_view(data: bytes, target: int) -> int:
        while len(blob) % 4:
            blob.append(0)
        buffer_views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                             "target": target})
        blob.extend(data)
        return len(buffer_views) - 1

    mat_names = list(materials_rgba)
    materials = [{"name": n,
                  "pbrMetallicRoughness": {"baseColorFactor": list(materials_rgba[n]),
                                           "metallicFactor": 0.0, "roughnessFactor": 1.0},
                  **({"doubleSided": True} if n in double_sided else {})}
                 for n in mat_names]
    meshes, nodes = [], []
    for p in parts:
        v = p.vertices.astype(np.float32)
        n = p.normals.astype(np.float32)
        idx_dtype, idx_ct = (np.uint16, 5123) if len(v) < 65535 else (np.uint32, 5125)
        pos = len(accessors)
        accessors.append({"bufferView": add_view(v.astype("<f4").tobytes(), 34962),
                          "componentType": 5126, "count": len(v), "type": "VEC3",
                          "min": [float(x) for x in v.min(axis=0)],
                          "max": [float(x) for x in v.max(axis=0)]})
        accessors.append({"bufferView": add_view(n.astype("<f4").tobytes(), 34962),
                          "componentType": 5126, "count": len(n), "type": "VEC3"})
        f = p.faces.astype(idx_dtype).reshape(-1)
        accessors.append({"bufferView": add_view(f.astype(np.dtype(idx_dtype).newbyteorder("<"))
                                                 .tobytes(), 34963),
                          "componentType": idx_ct, "count": len(f), "type": "SCALAR"})
        meshes.append({"name": p.name, "primitives": [{
            "attributes": {"POSITION": pos, "NORMAL": pos + 1}, "indices": pos + 2,
            "material": mat_names.index(p.material), "mode": 4}]})
        nodes.append({"name": p.name, "mesh": len(meshes) - 1})
    nodes.append({"name": "sun", "rotation": _quat_z_to(sun.direction),
                  "extensions": {"KHR_lights_punctual": {"light": 0}}})
    while len(blob) % 4:
        blob.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "sun", "type": "directional", "intensity": float(sun.intensity),
             "color": [float(c) for c in sun.color],
             **({"extras": sun_extras} if sun_extras else {})}]}},
        "scene": 0,
        "scenes": [{"name": scene_name, "nodes": list(range(len(nodes))),
                    "extras": {"seed": int(seed), "body_length_m": BODY_LENGTH,
                               "fog": {"color": [0.05, 0.06, 0.05], "density": 0.08},
                               **(extras or {})}}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": buffer_views,
        "buffers": [{"byteLength": len(blob)}],
    }
    js = json.dumps(doc, separators=(",", ":"), sort_keys=False).encode("utf-8")
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return (struct.pack("<III", 0x46546C67, 2, total)
            + struct.pack("<II", len(js), 0x4E4F534A) + js
            + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


def save(path: Path, data: bytes) -> Path:
    """Write `data` to `path` through a temporary file and a rename (all or nothing)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    return path


def write(path: Path, seed: int = DEFAULT_SEED) -> Path:
    parts, sun = make_rainforest_floor(seed)
    return save(path, build_glb(parts, sun, seed))


def run_cli(argv, doc: str, write_fn, default_seed: int, default_out: Path) -> int:
    """A generator's command line: --seed and --out, then `write_fn(out, seed)`."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--seed", type=int, default=default_seed)
    ap.add_argument("--out", type=Path, default=default_out)
    args = ap.parse_args(argv)
    out = write_fn(args.out, args.seed)
    print(f"wrote {out} ({out.stat().st_size} bytes)")
    return 0


def main(argv=None) -> int:
    return run_cli(argv, __doc__, write, DEFAULT_SEED, DEFAULT_OUT)


if __name__ == "__main__":
    raise SystemExit(main())
