"""Generate the multi-storey test level `environments/multistorey.glb`.

A small human-scale building for a 2 m giant centipede (the default rig at `--scale 8`: agent
radius 0.16 m, height 0.4 m, riser 0.2 m, cell 0.12 m). Y up, metres; the level spans
x -1..33 m, z -1..25 m and 6.9 m in height. What it holds, and what the navigation surface
must make of it:

- ground floor (top at y = 0): a slab under everything;
- two ground-floor rooms, A (x 0..10) and B (x 10..20), z 0..12, walled, 3.3 m high, under the
  upper floor's slab (the walls carry the slab: their tops touch its underside). Doorways, the
  floor running straight through each: A-B under a round arch, A-hall under a lintel, B-hall
  under a round arch, B-yard under a lintel. The walls over the doorways touch the slab too,
  so every doorway has a lintel with a slab resting on it (coincident faces);
- the upper floor (top at y = 3.6 m, x -0.25..20.25, z -0.25..12.25): an open terrace C over
  room A and a walled room D over room B (roof at 6.6..6.9 m, unreachable), D's doorways: to C
  under a round arch, to the ramp and to the bridge under lintels;
- a staircase from the hall up to the terrace's south edge: 20 risers of 0.18 m, treads of
  0.35 m, 2.5 m wide (x 1..3.5, z 12.25..18.9);
- a ramp at 22 deg from the yard up to D's east doorway (x 20.25..29.16, z 1.25..3.75);
- a bridge (deck 3.3..3.6 m) from D's south doorway across the hall to a tower (top 3.6 m); the
  hall floor under the bridge is a passage with 3.3 m of headroom;
- a hollow log lying in the hall (x 22..29, axis along x): an elliptical half shell cut by the
  floor where its outer slope is 50 deg, so the top is walkable from the floor and the floor
  inside it (0.7 m of headroom at the middle) through its open ends;
- a directional sun (glTF KHR_lights_punctual).

Every part is a closed solid wound outward (checked here), and no two parts share a vertex.
The output is deterministic: `python environments/make_multistorey.py` rewrites the GLB byte
for byte (positions are quantized to 2**-16 m, the JSON has no timestamps).

Usage: python environments/make_multistorey.py [--out PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DEFAULT_OUT = Path(__file__).resolve().parent / "multistorey.glb"

BODY_LENGTH = 2.0      # [m] the creature this level is sized for (default rig, --scale 8)
RISER = 0.18           # [m] stair riser
TREAD = 0.35           # [m] stair tread
N_RISERS = 20
UPPER_Y = RISER * N_RISERS   # [m] 3.6, top of the upper floor
SLAB = 0.3             # [m] upper floor slab thickness (underside at 3.3 m)
WALL_T = 0.3           # [m] wall thickness
STOREY = 3.0           # [m] upper-floor wall height (roof underside at 6.6 m)
RAMP_DEG = 22.0
QUANTUM = 2.0 ** -16   # [m] position quantization (exact in float32 below 256 m)
SUN_DIR = (0.35, 0.85, 0.4)
SUN_INTENSITY = 3.0    # [lux]

# name -> linear RGBA base colour
MATERIALS = {
    "stone": (0.12, 0.115, 0.11, 1.0),
    "plaster": (0.32, 0.3, 0.27, 1.0),
    "wood": (0.16, 0.09, 0.045, 1.0),
    "moss": (0.0047, 0.0513, 0.0137, 1.0),
}


@dataclass(frozen=True)
class Part:
    """One closed solid. vertices (n, 3) float64 world metres, faces (m, 3) int64 wound
    outward."""

    name: str
    material: str
    vertices: np.ndarray
    faces: np.ndarray


# --------------------------------------------------------------------------- solids
def _ear_clip(poly: np.ndarray) -> np.ndarray:
    """Triangles (k, 3) of a simple counter-clockwise polygon (n, 2) by ear clipping."""
    idx = list(range(len(poly)))
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    while len(idx) > 3:
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= 1e-12:
                continue  # reflex or flat corner
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                tris.append((i0, i1, i2))
                idx.pop(k)
                break
        else:
            raise RuntimeError("polygon is not simple")
    tris.append(tuple(idx))
    return np.array(tris, dtype=np.int64)


def prism(poly, axis: int, a0: float, a1: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed solid: the simple polygon `poly` (n, 2) extruded along world axis `axis`
    (0 x, 1 y, 2 z) from a0 to a1. The polygon's coordinates are the other two axes in
    increasing order (for axis 0: (y, z); 1: (x, z); 2: (x, y)). Returns (vertices (2n, 3),
    faces wound outward)."""
    poly = np.asarray(poly, dtype=np.float64)
    area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    if area < 0:
        poly = poly[::-1]
    n = len(poly)
    other = [a for a in range(3) if a != axis]
    v = np.zeros((2 * n, 3))
    for k, a in enumerate((a0, a1)):
        v[k * n:(k + 1) * n, other[0]] = poly[:, 0]
        v[k * n:(k + 1) * n, other[1]] = poly[:, 1]
        v[k * n:(k + 1) * n, axis] = a
    t = _ear_clip(poly)
    i = np.arange(n)
    j = (i + 1) % n
    sides = np.concatenate([np.stack([i, j, j + n], 1), np.stack([i, j + n, i + n], 1)])
    f = np.concatenate([t[:, ::-1], t + n, sides])
    return outward(v, f)


def outward(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flip all faces of a closed, consistently wound solid when its signed volume is
    negative. Raises RuntimeError when it is not closed and consistently wound."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {(int(a), int(b)) for a, b in e}
    if len(fwd) != len(e) or any((b, a) not in fwd for a, b in fwd):
        raise RuntimeError("solid is not closed and consistently wound")
    c = v - v.mean(axis=0)
    vol = np.einsum("ij,ij->i", c[f[:, 0]], np.cross(c[f[:, 1]], c[f[:, 2]])).sum()
    return v, (f if vol > 0 else f[:, ::-1])


def box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return prism([(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])], 2, lo[2], hi[2])


def arch_outline(u0: float, u1: float, spring: float, n: int = 16) -> list[tuple[float, float]]:
    """The top of an opening from u0 to u1 (left to right), seen from the front: a round arch
    springing at height `spring` (n segments), or a flat lintel when n == 0. Points from the
    right jamb over the top to the left jamb."""
    if n == 0:
        return [(u1, spring), (u0, spring)]
    r, uc = 0.5 * (u1 - u0), 0.5 * (u0 + u1)
    th = np.linspace(0.0, math.pi, n + 1)
    return [(uc + r * math.cos(t), spring + r * math.sin(t)) for t in th]


def wall(name: str, along: int, u0: float, u1: float, across: float, y0: float, y1: float,
         doors=()) -> Part:
    """A straight wall of thickness WALL_T centred on `across`, running along world axis
    `along` (0 x, 2 z) from u0 to u1, from y0 to y1, with door openings from the floor:
    doors = [(d0, d1, spring, arch_segments)] in increasing order (arch_segments 0: lintel)."""
    poly = [(u0, y0)]
    for d0, d1, spring, n in doors:
        top = arch_outline(d0, d1, y0 + spring, n)
        poly += [(d0, y0)] + top[::-1] + [(d1, y0)]
    poly += [(u1, y0), (u1, y1), (u0, y1)]
    pts = np.array(poly)
    if along == 0:   # polygon in (x, y), extruded along z
        v, f = prism(pts, 2, across - WALL_T / 2, across + WALL_T / 2)
    else:            # polygon in (z, y) -> axis 0 takes (y, z)
        v, f = prism(pts[:, ::-1], 0, across - WALL_T / 2, across + WALL_T / 2)
    return Part(name, "plaster", v, f)


def stairs(x0: float, x1: float, z_top: float) -> Part:
    """A solid flight rising toward -z: N_RISERS - 1 steps of RISER and TREAD from the floor
    at z_top + (N_RISERS - 1) * TREAD up to z_top, where the last riser meets the upper
    floor's edge. Profile in (y, z), extruded along x."""
    n = N_RISERS - 1
    z_foot = z_top + n * TREAD
    pts = [(0.0, z_top), (0.0, z_foot)]
    for k in range(1, n + 1):
        z = z_foot - (k - 1) * TREAD
        pts += [(k * RISER, z), (k * RISER, z - TREAD)]
    v, f = prism(pts, 0, x0, x1)
    return Part("stairs", "wood", v, f)


def ramp(x_top: float, z0: float, z1: float) -> Part:
    """A solid wedge from the upper floor's edge at x_top down to the ground toward +x."""
    run = UPPER_Y / math.tan(math.radians(RAMP_DEG))
    v, f = prism([(x_top, 0.0), (x_top + run, 0.0), (x_top, UPPER_Y)], 2, z0, z1)
    return Part("ramp", "stone", v, f)


def hollow_log(x0: float, x1: float, zc: float, a: float = 2.4, b: float = 2.0,
               t: float = 0.15, foot_deg: float = 50.0, n_arc: int = 32) -> Part:
    """A hollow half log along x: an elliptical shell (outer semi-axes a across, b up;
    thickness t) cut by the floor y = 0 where its outer slope is foot_deg. Closed: outer and
    inner surfaces, two end rings and two feet on the floor."""
    th0 = math.atan2(1.0, math.tan(math.radians(foot_deg)) * a / b)
    gy = b * math.sin(th0)                        # floor height above the ellipse centre
    ti0 = math.asin(gy / (b - t))
    to = np.linspace(th0, math.pi - th0, n_arc + 1)
    ti = np.linspace(ti0, math.pi - ti0, n_arc + 1)
    outer = np.stack([zc + a * np.cos(to), b * np.sin(to) - gy], 1)            # (z, y)
    inner = np.stack([zc + (a - t) * np.cos(ti), (b - t) * np.sin(ti) - gy], 1)
    poly = np.concatenate([outer, inner[::-1]])   # a closed ring-shaped profile
    v, f = prism(poly[:, ::-1], 0, x0, x1)
    return Part("hollow_log", "moss", v, f)


# --------------------------------------------------------------------------- the level
def make_multistorey() -> list[Part]:
    """All parts of the level (world space, metres, +Y up)."""
    h = WALL_T / 2
    g0 = UPPER_Y - SLAB           # 3.3: ground-floor walls end under the slab
    parts = [Part("ground", "stone", *box((-1.0, -0.3, -1.0), (33.0, 0.0, 25.0)))]
    # ground-floor rooms A (x 0..10) and B (x 10..20); ends tucked into the crossing walls
    parts += [
        wall("wall_A_B_north", 0, -h, 20.0 + h, 0.0, 0.0, g0),
        wall("wall_A_B_south", 0, -h, 20.0 + h, 12.0, 0.0, g0,
             doors=[(6.0, 8.0, 2.4, 0), (16.5, 18.5, 2.0, 16)]),
        wall("wall_A_west", 2, 0.1, 11.9, 0.0, 0.0, g0),
        wall("wall_A_B", 2, 0.1, 11.9, 10.0, 0.0, g0, doors=[(5.0, 7.0, 2.0, 16)]),
        wall("wall_B_east", 2, 0.1, 11.9, 20.0, 0.0, g0, doors=[(8.0, 10.0, 2.6, 0)]),
        Part("upper_floor", "stone", *box((-0.25, g0, -0.25), (20.25, UPPER_Y, 12.25))),
    ]
    # upper floor: terrace C (open) and room D with a roof
    y0, y1 = UPPER_Y, UPPER_Y + STOREY
    parts += [
        wall("wall_D_north", 0, 10.0 - h, 20.0 + h, 0.0, y0, y1),
        wall("wall_D_south", 0, 10.0 - h, 20.0 + h, 12.0, y0, y1, doors=[(12.0, 14.5, 2.4, 0)]),
        wall("wall_C_D", 2, 0.1, 11.9, 10.0, y0, y1, doors=[(3.0, 5.0, 1.9, 16)]),
        wall("wall_D_east", 2, 0.1, 11.9, 20.0, y0, y1, doors=[(1.25, 3.75, 2.4, 0)]),
        Part("roof_D", "stone", *box((9.75, y1, -0.25), (20.25, y1 + SLAB, 12.25))),
    ]
    # ways up and across
    parts += [
        stairs(1.0, 3.5, 12.25),
        ramp(20.25, 1.25, 3.75),
        Part("bridge", "wood", *box((12.0, g0, 12.25), (14.5, UPPER_Y, 18.0))),
        Part("tower", "stone", *box((10.5, 0.0, 18.0), (16.0, UPPER_Y, 23.0))),
        hollow_log(22.0, 29.0, 19.5),
    ]
    return [Part(p.name, p.material, quantize(p.vertices), p.faces) for p in parts]


def quantize(v: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(v, dtype=np.float64) / QUANTUM) * QUANTUM


# --------------------------------------------------------------------------- GLB writer
def flat_shaded(p: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (k, 3) float32, normals (k, 3) float32, faces (m, 3)): vertices split where
    faces of different normal meet (sharp edges), shared within each flat face."""
    v, f = p.vertices, p.faces
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    q = np.round(fn * 1e4).astype(np.int64)
    key = np.stack([f.reshape(-1), np.repeat(q, 3, axis=0)[:, 0], np.repeat(q, 3, axis=0)[:, 1],
                    np.repeat(q, 3, axis=0)[:, 2]], 1)
    uk, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    vid = uk[:, 0]
    normals = np.repeat(fn, 3, axis=0)[first]
    return (v[vid].astype(np.float32), normals.astype(np.float32),
            inv.reshape(-1).reshape(-1, 3))


def _quat_z_to(d: np.ndarray) -> list[float]:
    """xyzw unit quaternion rotating +Z onto unit vector d."""
    c = float(d[2])
    q = np.array([-d[1], d[0], 0.0, 1.0 + c])
    q /= np.linalg.norm(q)
    return [round(float(x), 9) for x in q]


def build_glb(parts: list[Part]) -> bytes:
    """Serialize the level as GLB 2.0 bytes (deterministic)."""
    blob = bytearray()
    views, accessors, meshes, nodes = [], [], [], []

    def add_view(data: bytes, target: int) -> int:
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                      "target": target})
        blob.extend(data)
        return len(views) - 1

    names = list(MATERIALS)
    for p in parts:
        v, n, f = flat_shaded(p)
        a = len(accessors)
        accessors.append({"bufferView": add_view(v.astype("<f4").tobytes(), 34962),
                          "componentType": 5126, "count": len(v), "type": "VEC3",
                          "min": [float(x) for x in v.min(axis=0)],
                          "max": [float(x) for x in v.max(axis=0)]})
        accessors.append({"bufferView": add_view(n.astype("<f4").tobytes(), 34962),
                          "componentType": 5126, "count": len(n), "type": "VEC3"})
        idx = f.reshape(-1).astype("<u2" if len(v) < 65535 else "<u4")
        accessors.append({"bufferView": add_view(idx.tobytes(), 34963),
                          "componentType": 5123 if len(v) < 65535 else 5125,
                          "count": len(idx), "type": "SCALAR"})
        meshes.append({"name": p.name, "primitives": [{
            "attributes": {"POSITION": a, "NORMAL": a + 1}, "indices": a + 2,
            "material": names.index(p.material), "mode": 4}]})
        nodes.append({"name": p.name, "mesh": len(meshes) - 1})
    sun = np.asarray(SUN_DIR, dtype=np.float64)
    sun /= np.linalg.norm(sun)
    # a directional light shines along its node's -Z: point +Z at the sun
    nodes.append({"name": "sun", "rotation": _quat_z_to(sun),
                  "extensions": {"KHR_lights_punctual": {"light": 0}}})
    while len(blob) % 4:
        blob.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": "baker environments/make_multistorey.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "sun", "type": "directional", "intensity": SUN_INTENSITY,
             "color": [1.0, 0.96, 0.9]}]}},
        "scene": 0,
        "scenes": [{"name": "multistorey", "nodes": list(range(len(nodes))),
                    "extras": {"body_length_m": BODY_LENGTH}}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [{"name": k, "pbrMetallicRoughness": {
            "baseColorFactor": list(MATERIALS[k]), "metallicFactor": 0.0,
            "roughnessFactor": 1.0}} for k in names],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return (struct.pack("<III", 0x46546C67, 2, total)
            + struct.pack("<II", len(js), 0x4E4F534A) + js
            + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


def write(path: Path) -> Path:
    data = build_glb(make_multistorey())
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    out = write(args.out)
    print(f"wrote {out} ({out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
