"""Generate the default scene `environments/showcase.glb`: a rainforest floor patch laid out so
that a 60 s bake meets every behaviour.

A 6 m square of forest floor for a 0.25 m centipede (body length BL = 0.25 m) that walks about
12 m a minute, so that it meets the features within a minute:

- leaf litter relief: the ground undulates by a centimetre or two, in patches of bare soil and
  of litter (one surface, two materials);
- a bank along the east edge, rising 0.3 m with slopes up to about 50 deg;
- fallen branches around the middle, 2.8 cm high (taller than a step: the centipede rears up
  to climb them) and two solid logs to climb over (buried so that their sides meet the ground at 52-55 deg), and a
  hollow half log to walk through (open at both ends, 0.11 m of headroom inside, walkable
  outer walls);
- a big log whose top (0.28 m up, its sides overhanging) is an upper level reached by a bark
  plank ramp at about 30 deg;
- roots 2-3 cm high (a climb worth rearing up for; two arch high enough to walk under) and
  stones (low flat ones to step onto, taller
  rocks to walk around);
- broad-leaved seedlings and a fallen bark sheet leaning on a stone that cast real shade: about
  18% of the walkable ground is in shade at the file's sun;
- a directional sun 40 deg from the zenith (glTF KHR_lights_punctual) that turns about the
  vertical at 0.5 deg/s during a bake (the light's extras `azimuth_deg_per_s`, read by
  baker.environment.load), so the shade moves by a few centimetres a minute.

The parts and the GLB writer are those of make_rainforest_floor.py. The output is
deterministic: `python environments/make_showcase.py` rewrites the GLB byte for byte.

Usage: python environments/make_showcase.py [--seed N] [--out PATH]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import make_rainforest_floor as rf  # noqa: E402  (the sibling generator: helpers and writer)

DEFAULT_SEED = 20260614
DEFAULT_OUT = Path(__file__).resolve().parent / "showcase.glb"

SIZE = 6.0                 # [m] the patch is SIZE x SIZE, centred on the origin
GROUND_CELL = 0.06         # [m] ground grid spacing
SUN_ZENITH_DEG = 40.0      # angle of the sun from vertical
SUN_AZIMUTH_DEG = 60.0     # measured from +X toward +Z
SUN_DRIFT_DEG_PER_S = 0.5  # the sun turns about +Y this fast during a bake (30 deg a minute)
BANK_X = 2.05              # [m] the bank's slope is centred on this x
BANK_HEIGHT = 0.3          # [m]
BANK_SLOPE_DEG = 50.0      # steepest slope of the bank

MATERIALS = {
    "soil": rf.srgb_to_linear((72, 63, 57)),
    "litter": rf.srgb_to_linear((112, 74, 40)),
    "moss": rf.srgb_to_linear((14, 64, 31)),
    "rock": rf.srgb_to_linear((92, 88, 80)),
    "bark": rf.srgb_to_linear((58, 42, 30)),
    "wood": rf.srgb_to_linear((96, 70, 46)),
    "leaf": rf.srgb_to_linear((38, 96, 34)),
    "root": rf.srgb_to_linear((80, 58, 40)),
}
DOUBLE_SIDED = ("leaf", "bark")


# --------------------------------------------------------------------------- ground
class Ground:
    """Height field y = h(x, z): litter relief (short sinusoids, 1-2 cm) plus the east bank."""

    def __init__(self, rng: np.random.Generator):
        n = 8
        wl = rng.uniform(0.35, 1.2, n)
        ang = rng.uniform(0.0, 2.0 * np.pi, n)
        self.k = np.stack([np.cos(ang), np.sin(ang)], 1) * (2 * np.pi / wl)[:, None]
        self.amp = wl * rng.uniform(0.006, 0.011, n)     # slope per wave <= 0.07
        self.phase = rng.uniform(0.0, 2.0 * np.pi, n)
        # logistic bank: steepest slope = height * s / 4
        self.bank_s = 4.0 * math.tan(math.radians(BANK_SLOPE_DEG)) / BANK_HEIGHT

    def height(self, x, z) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        z = np.asarray(z, dtype=np.float64)
        h = rf.sum_of_waves(x, z, self.k, self.amp, self.phase)
        # the bank's foot wavers a little along z
        xb = BANK_X + 0.12 * np.sin(1.3 * z + 0.4)
        return h + BANK_HEIGHT / (1.0 + np.exp(-self.bank_s * (x - xb)))

    def parts(self, rng: np.random.Generator) -> list[rf.Part]:
        """The ground grid as two meshes on the same vertices: bare soil and leaf litter
        (patches picked by a noise pattern). One surface: no thin sheets over the ground for
        feet to plant under."""
        n = int(round(SIZE / GROUND_CELL)) + 1
        c = np.linspace(-SIZE / 2, SIZE / 2, n)
        X, Z = np.meshgrid(c, c, indexing="xy")
        v = np.stack([X, self.height(X, Z), Z], axis=-1).reshape(-1, 3)
        i = np.arange(n * n).reshape(n, n)
        a, b, cc, d = i[:-1, :-1], i[:-1, 1:], i[1:, :-1], i[1:, 1:]
        f = np.concatenate([np.stack([a, cc, b], -1).reshape(-1, 3),
                            np.stack([b, cc, d], -1).reshape(-1, 3)])
        centre = v[f].mean(axis=1)
        ang = rng.uniform(0.0, 2.0 * np.pi, 6)
        k = np.stack([np.cos(ang), np.sin(ang)], 1) * (2 * np.pi / rng.uniform(0.3, 0.9, 6))[:, None]
        noise = np.sin(centre[:, [0, 2]] @ k.T + rng.uniform(0.0, 2.0 * np.pi, 6)).sum(axis=1)
        litter = noise > 0.0
        out = []
        for name, mat, sel in (("ground", "soil", ~litter), ("ground_litter", "litter", litter)):
            used, ff = np.unique(f[sel], return_inverse=True)   # only the vertices it uses
            out.append(rf.make_part(name, mat, v[used], ff.reshape(-1, 3),
                                    up_hint=np.array([0.0, 1.0, 0.0])))
        return out


# --------------------------------------------------------------------------- shapes
def _frames(path: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit tangents (n, 3) along a polyline and two normals across it (n, 3) each."""
    t = np.gradient(path, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    ref = np.where(np.abs(t[:, 1:2]) > 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    n1 = np.cross(ref, t)
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    return t, n1, np.cross(t, n1)


def tube(path: np.ndarray, radius, n_around: int = 14, caps: bool = True) -> list:
    """Pieces of a tube of `radius` ((n,) or scalar) swept along `path` (n, 3), with flat end
    caps."""
    path = np.asarray(path, dtype=np.float64)
    r = np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(path),))
    t, n1, n2 = _frames(path)
    a = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    ring = np.cos(a)[None, :, None] * n1[:, None] + np.sin(a)[None, :, None] * n2[:, None]
    v = (path[:, None] + r[:, None, None] * ring).reshape(-1, 3)
    i = np.arange(len(path) * n_around).reshape(len(path), n_around)
    j = np.roll(i, -1, axis=1)
    f = np.concatenate([np.stack([i[:-1], j[:-1], i[1:]], -1).reshape(-1, 3),
                        np.stack([j[:-1], j[1:], i[1:]], -1).reshape(-1, 3)])
    pieces = [rf.piece(v, f, ring.reshape(-1, 3)[f[:, 0]])]
    if caps:
        for k, sign in ((0, -1.0), (len(path) - 1, 1.0)):
            cv = np.vstack([path[k], path[k] + r[k] * ring[k]])
            cf = np.stack([np.zeros(n_around, int), 1 + np.arange(n_around),
                           1 + (np.arange(n_around) + 1) % n_around], 1)
            pieces.append(rf.piece(cv, cf, sign * t[k]))
    return pieces


def buried_log(name: str, ground: Ground, p0, p1, radius: float, side_deg: float,
               material: str = "bark", dive: float = 0.0) -> rf.Part:
    """A solid log from p0 to p1 (x, z) sunk into the ground so that its sides meet the ground
    at `side_deg` (the top shows radius * (1 - cos side) above the ground). With `dive` > 0 its
    ends dive under the ground over that fraction of its length at each end (no upright end
    faces to walk into)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    n = max(8, int(math.ceil(np.linalg.norm(p1 - p0) / 0.06)) + 1)
    xz = p0 + np.linspace(0.0, 1.0, n)[:, None] * (p1 - p0)
    g = ground.height(xz[:, 0], xz[:, 1])
    g = np.convolve(np.pad(g, 2, mode="edge"), np.ones(5) / 5, mode="valid")  # a straight-ish log
    y = g - radius * math.cos(math.radians(side_deg))
    if dive > 0:
        u = np.linspace(0.0, 1.0, n)
        e = np.clip(np.minimum(u, 1.0 - u) / dive, 0.0, 1.0)     # 0 at the ends, 1 inside
        y = y - 1.2 * radius * (1.0 - e * e * (3.0 - 2.0 * e))
    return rf.merge(name, material, tube(np.stack([xz[:, 0], y, xz[:, 1]], 1), radius, 24))


def leaf(base: np.ndarray, yaw: float, pitch: float, length: float, width: float,
         droop: float) -> tuple:
    """A broad leaf blade (one double-sided sheet): from `base`, along the horizontal direction
    `yaw`, rising at `pitch`, drooping by `droop` at its tip, cupped across."""
    nu, nv = 9, 7
    u = np.linspace(0.0, 1.0, nu)[:, None]
    v = np.linspace(-1.0, 1.0, nv)[None, :]
    half = width / 2 * np.sin(np.pi * np.clip(u, 0.02, 1.0)) ** 0.7
    along = u * length * np.ones_like(v)
    up = (math.tan(pitch) * u * length - droop * u ** 2 + 0.12 * width * v ** 2) * np.ones_like(v)
    across = v * half
    d = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
    w = np.array([-math.sin(yaw), 0.0, math.cos(yaw)])
    p = (base + along[..., None] * d + up[..., None] * np.array([0.0, 1.0, 0.0])
         + across[..., None] * w).reshape(-1, 3)
    return rf.piece(p, rf.grid_faces(nu, nv), np.array([0.0, 1.0, 0.0]))


def seedling(name: str, ground: Ground, xz, height: float, n_leaves: int, leaf_len: float,
             rng: np.random.Generator) -> list[rf.Part]:
    """A broad-leaved seedling: a thin stem and `n_leaves` leaves spreading from its top."""
    g = float(ground.height(xz[0], xz[1]))
    top = np.array([xz[0], g + height, xz[1]])
    stem = tube(np.array([[xz[0], g - 0.02, xz[1]], top]), 0.006, 8)
    yaw0 = rng.uniform(0, 2 * np.pi)
    blades = []
    for k in range(n_leaves):
        yaw = yaw0 + 2 * np.pi * k / n_leaves + rng.uniform(-0.3, 0.3)
        ln = leaf_len * rng.uniform(0.8, 1.1)
        base = top - np.array([0.0, 0.02 * k, 0.0])
        blades.append(leaf(base, yaw, math.radians(rng.uniform(8, 22)), ln, 0.5 * ln,
                           droop=0.35 * ln))
    return [rf.merge(f"{name}_stem", "wood", stem), rf.merge(f"{name}_leaves", "leaf", blades)]


def bark_sheet(name: str, ground: Ground, centre, yaw: float, length: float, width: float,
               lift: float) -> rf.Part:
    """A fallen sheet of bark, curled across, one long edge on the ground and the other
    propped `lift` up (on a stone): a low shelter. The low edge sinks a little into the
    ground, as lying bark does: a zero-thickness edge hovering above the ground left a slot a
    foot could step into under it, and a leg then crossed the sheet to land on its top."""
    nu, nv = 12, 8
    u = np.linspace(-0.5, 0.5, nu)[:, None] * length
    s = np.linspace(0.0, 1.0, nv)[None, :]
    d = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
    w = np.array([-math.sin(yaw), 0.0, math.cos(yaw)])
    xz = (np.asarray(centre, float)[None, None, :] + u[..., None] * d[[0, 2]]
          + ((s - 0.5) * width)[..., None] * w[[0, 2]])
    g = ground.height(xz[..., 0], xz[..., 1])
    y = g - 0.004 + lift * s + 0.05 * np.sin(np.pi * s)   # curled up across
    p = np.stack([xz[..., 0], y, xz[..., 1]], -1).reshape(-1, 3)
    top = rf.piece(p, rf.grid_faces(nu, nv), np.array([0.0, 1.0, 0.0]))
    return rf.Part(name, "bark", *top)


def root(name: str, ground: Ground, pts_xz, radius: float, arch: tuple | None) -> rf.Part:
    """A root along the (x, z) points, sunk to 60% of its radius; `arch` = (u0, u1, height):
    between fractions u0 and u1 of its length it arches up, its axis `height` above the
    ground at the middle (a gap to crawl under)."""
    pts_xz = np.asarray(pts_xz, float)
    seg = np.linalg.norm(np.diff(pts_xz, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(10, int(math.ceil(s[-1] / 0.04)) + 1)
    su = np.linspace(0.0, s[-1], n)
    x, z = np.interp(su, s, pts_xz[:, 0]), np.interp(su, s, pts_xz[:, 1])
    off = np.full(n, -0.6 * radius)
    if arch is not None:
        u = su / s[-1]
        u0, u1, h = arch
        a = np.clip((u - u0) / (u1 - u0), 0.0, 1.0)
        off = off + (h + 0.6 * radius) * np.sin(np.pi * a) ** 1.5
    r = radius * (1.0 - 0.3 * su / s[-1])         # tapering
    return rf.merge(name, "root", tube(np.stack([x, ground.height(x, z) + off, z], 1), r, 12))


def ellipsoid(name: str, material: str, radii, R, centre) -> rf.Part:
    v, f = rf.icosphere(3)
    p = (v * radii) @ R.T + centre
    return rf.Part(name, material, *rf.piece(p, f, ((v / radii) @ R.T)[f[:, 0]]))


def plank(name: str, ground: Ground, foot_xz, top: np.ndarray, width: float,
          thick: float) -> rf.Part:
    """A straight board from the ground at foot_xz (its lower end sunk in) up to `top` (3,),
    where its upper face ends."""
    foot = np.array([foot_xz[0], float(ground.height(foot_xz[0], foot_xz[1])), foot_xz[1]])
    d = top - foot
    length = float(np.linalg.norm(d))
    d /= length
    side = np.cross(d, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, d)
    R = np.stack([d, up, side], 1)                   # box x along the board, y its normal
    centre = foot + d * (length / 2 - 0.03) - up * (thick / 2)
    return rf.merge(name, "wood", rf.box_pieces(np.array([length / 2 + 0.03, thick / 2,
                                                           width / 2]), R, centre))


# --------------------------------------------------------------------------- the scene
def make_showcase(seed: int = DEFAULT_SEED) -> tuple[list[rf.Part], rf.SunSpec]:
    """Build the patch. Returns (parts, sun); parts are in world space (metres, +Y up)."""
    rng = np.random.default_rng(seed)
    ground = Ground(rng)
    parts = ground.parts(rng)

    # the upper level: a big log with overhanging sides; a bark plank ramp up to its top
    big_r, big_y = 0.2, 0.08
    big = np.array([[-2.5, -1.75], [-0.5, -1.55]])
    bx = np.linspace(0, 1, 34)[:, None] * (big[1] - big[0]) + big[0]
    path = np.stack([bx[:, 0], np.full(len(bx), big_y), bx[:, 1]], 1)
    parts.append(rf.merge("log_upper", "bark", tube(path, big_r, 28)))
    crest = np.array([-1.35, big_y + big_r + 0.004, -1.635])
    parts.append(plank("ramp", ground, (-1.22, -0.95), crest, width=0.17, thick=0.02))

    # logs to climb over
    parts.append(buried_log("log_climb_1", ground, (-1.9, 0.3), (-0.7, 1.35), 0.16, 54.0))
    parts.append(buried_log("log_climb_2", ground, (0.2, -2.0), (1.4, -1.1), 0.2, 52.0))
    # fallen branches, 2.8 cm high with 53 deg sides: climbed with the front reared up
    for i, (a, b) in enumerate([((-0.3, 0.95), (0.25, 0.85)), ((0.05, -0.15), (0.55, -0.45)),
                                ((-0.35, 0.1), (-0.05, 0.5)), ((1.35, 1.3), (1.8, 1.0)),
                                ((0.6, 2.5), (1.3, 2.6)), ((-0.5, -0.9), (0.0, -0.75))]):
        parts.append(buried_log(f"branch_{i + 1:02d}", ground, a, b, 0.07, 53.0, "wood",
                                dive=0.25))
    # the hollow log to walk through (open side down, walkable 50 deg walls)
    shape = rf.LogShape(a=0.25, b=0.2, t=0.018, foot_slope=math.radians(50.0), bury=0.03)
    parts.append(rf.log_part("log_hollow", ground, (0.95, 0.75),
                             math.radians(80.0), 1.5, shape))

    # roots from a tree just off the patch's north-west corner; one arches over the floor
    parts.append(root("root_1", ground, [(-3.1, -2.6), (-2.2, -2.3), (-1.4, -2.5), (-0.4, -2.35)],
                      0.075, (0.35, 0.75, 0.16)))
    parts.append(root("root_2", ground, [(-3.1, -2.2), (-2.6, -1.0), (-2.7, 0.2), (-2.3, 1.0)],
                      0.07, None))
    parts.append(root("root_3", ground, [(-2.9, 0.6), (-1.9, 1.9), (-0.6, 2.3), (0.4, 2.0)],
                      0.07, (0.45, 0.8, 0.16)))

    # stones: low flat ones to step onto, taller rocks to walk around
    for i, (x, z, a, c) in enumerate([(0.35, 0.2, 0.14, 0.04), (-0.35, -0.55, 0.12, 0.035),
                                      (1.9, 1.6, 0.16, 0.04), (0.2, 2.15, 0.13, 0.03),
                                      (-1.5, 1.3, 0.12, 0.035), (1.0, 1.9, 0.13, 0.038),
                                      (-2.3, -1.0, 0.14, 0.036), (1.75, -0.75, 0.12, 0.034),
                                      (-1.1, 1.75, 0.11, 0.037), (1.5, 0.2, 0.13, 0.039)]):
        R = rf.random_rotation(rng, max_tilt=math.radians(4.0))
        g = float(ground.height(x, z))
        parts.append(ellipsoid(f"stone_{i + 1:02d}", "rock", np.array([a, c * 2.2, 0.8 * a]), R,
                               np.array([x, g + c - 2.2 * c, z])))
    for i, (x, z, a) in enumerate([(-0.4, 1.9, 0.2), (2.55, -1.2, 0.24), (-1.3, -0.35, 0.15)]):
        R = rf.random_rotation(rng)
        g = float(ground.height(x, z))
        parts.append(ellipsoid(f"rock_{i + 1:02d}", "rock", a * np.array([1.0, 0.75, 0.85]), R,
                               np.array([x, g + 0.3 * a, z])))

    # the fallen bark sheet, propped on a rock: a low shelter
    parts.append(bark_sheet("bark_sheet", ground, (-1.0, -0.25), math.radians(15.0), 0.95, 0.6,
                            0.14))

    # broad-leaved seedlings: the canopy the shade comes from
    plants = [(0.9, -0.5, 0.34, 5, 0.5), (-0.6, 0.6, 0.3, 5, 0.46), (2.4, 0.3, 0.36, 6, 0.5),
              (-2.0, -0.6, 0.28, 4, 0.42), (0.4, 1.3, 0.32, 5, 0.46), (-1.8, 2.3, 0.3, 5, 0.48),
              (1.8, -2.3, 0.33, 5, 0.48), (2.5, 2.4, 0.34, 5, 0.5), (-0.1, -1.2, 0.3, 4, 0.44),
              (0.05, 0.25, 0.3, 5, 0.42), (1.6, -1.6, 0.32, 5, 0.44)]
    for i, (x, z, h, n, ln) in enumerate(plants):
        parts += seedling(f"plant_{i + 1:02d}", ground, (x, z), h, n, 1.25 * ln, rng)

    zen, az = math.radians(SUN_ZENITH_DEG), math.radians(SUN_AZIMUTH_DEG)
    sun_dir = np.array([math.sin(zen) * math.cos(az), math.cos(zen), math.sin(zen) * math.sin(az)])
    return parts, rf.SunSpec(direction=sun_dir, intensity=rf.SUN_INTENSITY, color=rf.SUN_COLOR)


def build(seed: int = DEFAULT_SEED) -> bytes:
    parts, sun = make_showcase(seed)
    return rf.build_glb(parts, sun, seed, materials=MATERIALS, scene_name="showcase",
                        generator="baker environments/make_showcase.py",
                        extras={"size_m": SIZE}, double_sided=DOUBLE_SIDED,
                        sun_extras={"azimuth_deg_per_s": SUN_DRIFT_DEG_PER_S})


def write(path: Path, seed: int = DEFAULT_SEED) -> Path:
    return rf.save(path, build(seed))


def main(argv=None) -> int:
    return rf.run_cli(argv, __doc__, write, DEFAULT_SEED, DEFAULT_OUT)


if __name__ == "__main__":
    raise SystemExit(main())
