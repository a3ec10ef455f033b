"""The procedural skinned body mesh: a segmented, tapered tube with a rounded head, a closed
tail and static leg stubs, skinned to the spine joints.

Everything is built in the skeleton's bind space (rest pose straight along +Z, head at z=0,
trunk_k at z=-k*spacing), vectorized over rings and around each ring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.errors import RigError

MAX_INFLUENCES = 4
BODY, LEGS = 0, 1

RING_SIDES = 16          # vertices around the body cross-section
RINGS_PER_SEGMENT = 8    # rings along one segment (one sits exactly on each segment boundary)
PINCH_DEPTH = 0.14       # fraction the cross-section shrinks at a segment boundary
PINCH_WIDTH = 0.22       # [segments] half-width of the pinch
HEAD_CAP = 0.55          # [segments] length of the rounded head in front of the head segment
TAIL_CAP = 0.35          # [segments] length of the closed tail behind the last segment
CAP_RINGS = 6
LEG_SIDES = 6
STUB_STATIONS = (0.0, 0.55)  # ring stations along a leg stub, fraction of its length
STUB_RADII = (1.0, 0.55)     # ring radius at each station, fraction of the stub's base radius


@dataclass(frozen=True)
class SkinnedMesh:
    """A triangle mesh in the skeleton's bind space, with linear-blend skin weights.

    vertices      : (V, 3) float32, metres, bind space
    normals       : (V, 3) float32, unit, outward
    faces         : (M, 3) uint32, counter-clockwise seen from outside
    joints        : (V, 4) uint16, joint indices; unused slots are joint 0 with weight 0
    weights       : (V, 4) float32, sum to 1 within 2e-7, no joint repeated within a vertex
    face_material : (M,) uint8, index into `materials`
    materials     : ((name, (r, g, b) linear), ...)
    """

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    face_material: np.ndarray
    materials: tuple[tuple[str, tuple[float, float, float]], ...]

    def __post_init__(self) -> None:
        conv = {"vertices": np.float32, "normals": np.float32, "faces": np.uint32,
                "joints": np.uint16, "weights": np.float32, "face_material": np.uint8}
        for name, dt in conv.items():
            arr = np.ascontiguousarray(getattr(self, name), dtype=dt)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        v = len(self.vertices)
        if (self.vertices.shape != (v, 3) or self.normals.shape != (v, 3)
                or self.joints.shape != (v, MAX_INFLUENCES) or self.weights.shape != (v, MAX_INFLUENCES)
                or self.faces.ndim != 2 or self.faces.shape[1] != 3
                or self.face_material.shape != (len(self.faces),)):
            raise RigError("skinned mesh arrays have inconsistent shapes")
        if len(self.faces) and int(self.faces.max()) >= v:
            raise RigError("skinned mesh faces index past the vertex array")
        if len(self.face_material) and int(self.face_material.max()) >= len(self.materials):
            raise RigError("skinned mesh face_material indexes past the material list")

    def submesh(self, material: int) -> tuple[np.ndarray, np.ndarray]:
        """Vertex indices (k,) used by faces of `material` and those faces re-indexed (m, 3)."""
        f = self.faces[self.face_material == material]
        used, inv = np.unique(f, return_inverse=True)
        return used.astype(np.int64), inv.reshape(-1, 3).astype(np.uint32)


# --------------------------------------------------------------------------- weights
def normalize_weights(joints: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge repeated joints, keep the 4 largest influences, renormalize in float32.

    joints : (V, K) int, weights : (V, K) float, K >= 1
    returns (V, 4) uint16 joints, (V, 4) float32 weights: sorted by weight (largest first),
    unused slots joint 0 weight 0, sums within 2e-7 of 1.
    """
    joints = np.asarray(joints, dtype=np.int64)
    weights = np.asarray(weights, dtype=np.float64).copy()
    k = joints.shape[1]
    # merge duplicates: move each slot's weight to the first earlier slot with the same joint
    for a in range(1, k):
        for b in range(a):
            same = joints[:, a] == joints[:, b]
            weights[same, b] += weights[same, a]
            weights[same, a] = 0.0
    weights[weights < 0] = 0.0
    order = np.argsort(-weights, axis=1, kind="stable")[:, :MAX_INFLUENCES]
    w = np.take_along_axis(weights, order, axis=1)
    j = np.take_along_axis(joints, order, axis=1)
    if w.shape[1] < MAX_INFLUENCES:
        pad = MAX_INFLUENCES - w.shape[1]
        w = np.pad(w, ((0, 0), (0, pad)))
        j = np.pad(j, ((0, 0), (0, pad)))
    total = w.sum(axis=1, keepdims=True)
    if np.any(total <= 0):
        raise RigError("a vertex has no skin weight")
    w = (w / total).astype(np.float32)
    j[w == 0] = 0
    # put the float32 rounding remainder on the largest weight so sums are within 2e-7
    w[:, 0] += np.float32(1.0) - w.sum(axis=1, dtype=np.float32)
    return j.astype(np.uint16), w


# --------------------------------------------------------------------------- geometry helpers
def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (V, 3) float64; zero-area fans fall back to +Y."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for c in range(3):
        np.add.at(n, f[:, c], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 1e-20, n / np.maximum(length, 1e-30), np.array([0.0, 1.0, 0.0]))
    return n


def _tube_faces(n_rings: int, sides: int, offset: int = 0) -> np.ndarray:
    """Quads between consecutive rings of `sides` vertices, as triangles, outward for rings
    ordered front (+Z) to back with vertices counter-clockwise seen from the front (+X toward +Y).
    """
    r = np.arange(n_rings - 1)[:, None]
    k = np.arange(sides)[None, :]
    a = r * sides + k
    b = (r + 1) * sides + k
    c = r * sides + (k + 1) % sides
    d = (r + 1) * sides + (k + 1) % sides
    tris = np.stack([np.stack([a, b, c], -1), np.stack([c, b, d], -1)], axis=2)
    return tris.reshape(-1, 3) + offset


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


# --------------------------------------------------------------------------- the body
def build_body_mesh(width_profile: np.ndarray, spacing: float, height_ratio: float,
                    leg_stub_length: float, body_rgb, legs_rgb, spine: np.ndarray,
                    clearance: float | None = None) -> SkinnedMesh:
    """Procedural centipede body in bind space.

    width_profile : (S,) float, metres, half-width per spine segment, head to tail
    spacing       : metres between neighbouring spine joints (joint s sits at z = -s*spacing)
    spine         : (S,) int, skeleton joint index of spine segment s
    clearance     : metres from the centre line down to the ground; leg stub tips are aimed
                    just above it (None: a fixed downward slope)
    """
    wp = np.asarray(width_profile, dtype=np.float64)
    spine = np.asarray(spine, dtype=np.int64)
    s_count = len(wp)
    if s_count < 2 or spine.shape != (s_count,):
        raise RigError("body mesh needs a width per spine segment (at least 2)")
    if not (spacing > 0 and height_ratio > 0 and np.all(wp > 0)):
        raise RigError("body mesh needs positive spacing, widths and height ratio")

    c, cap_scale = _ring_stations(s_count)
    half_w, half_h = _ring_half_sizes(c, cap_scale, wp, height_ratio)
    body_v, body_f = _body_tube(c, half_w, half_h, spacing, s_count)
    body_j, body_w = _body_skin(c, spine, s_count)

    vertices, faces = body_v, body_f
    face_mat = np.zeros(len(body_f), dtype=np.uint8)
    joints4, weights4 = body_j, body_w
    if leg_stub_length > 0:
        lv, lf, lj = _leg_stubs(wp, spacing, height_ratio, leg_stub_length, spine, clearance)
        vertices = np.concatenate([body_v, lv])
        faces = np.concatenate([body_f, lf + len(body_v)])
        face_mat = np.concatenate([face_mat, np.ones(len(lf), dtype=np.uint8)])
        joints4 = np.concatenate([body_j, np.stack([lj, np.zeros_like(lj)], -1)])
        weights4 = np.concatenate([body_w, np.stack([np.ones(len(lj)), np.zeros(len(lj))], -1)])
    body_faces = faces[face_mat == BODY]
    if _signed_volume(vertices, body_faces) < 0:
        faces[face_mat == BODY] = body_faces[:, ::-1]

    j4, w4 = normalize_weights(joints4, weights4)
    normals = _vertex_normals(vertices, faces)
    materials = (("body", tuple(float(x) for x in body_rgb)),
                 ("legs", tuple(float(x) for x in legs_rgb)))
    return SkinnedMesh(vertices=vertices, normals=normals, faces=faces, joints=j4, weights=w4,
                       face_material=face_mat, materials=materials)


def _ring_stations(s_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Ring positions c along the body in segment units (c = s at joint s; z = -c*spacing),
    head cap to tail cap, and each ring's cap scale (quarter-ellipse in the caps, 1 elsewhere).
    """
    body_c = np.arange(-0.5 * RINGS_PER_SEGMENT, (s_count - 0.5) * RINGS_PER_SEGMENT + 1) / RINGS_PER_SEGMENT
    # rounded caps: quarter-ellipse profiles
    th = np.linspace(0.0, 0.5 * np.pi, CAP_RINGS + 1)[1:-1]          # excludes tip and joint ring
    head_c = -0.5 - HEAD_CAP * np.cos(th)
    head_scale = np.sin(th)
    tail_c = (s_count - 0.5) + TAIL_CAP * np.cos(th[::-1])
    tail_scale = np.sin(th[::-1])
    c = np.concatenate([head_c, body_c, tail_c])
    cap_scale = np.concatenate([head_scale, np.ones_like(body_c), tail_scale])
    return c, cap_scale


def _ring_half_sizes(c: np.ndarray, cap_scale: np.ndarray, wp: np.ndarray,
                     height_ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-width and half-height [m] of each ring: the width profile, pinched at each segment
    boundary (c = k + 0.5) and scaled down in the caps."""
    s_count = len(wp)
    half_w = np.interp(np.clip(c, 0, s_count - 1), np.arange(s_count), wp)
    d = np.abs(c - (np.floor(c - 0.5) + 0.5))
    d = np.minimum(d, 1.0 - d)                                    # distance to nearest boundary
    pinch = 1.0 - PINCH_DEPTH * np.clip(1.0 - d / PINCH_WIDTH, 0.0, 1.0) ** 2
    half_w = half_w * pinch * cap_scale
    half_h = half_w * height_ratio
    return half_w, half_h


def _body_tube(c: np.ndarray, half_w: np.ndarray, half_h: np.ndarray, spacing: float,
               s_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Elliptical rings at stations c closed by a tip vertex at each end: vertices (V, 3)
    (rings, then the front tip, then the back tip) and faces (M, 3), not yet oriented."""
    phi = np.arange(RING_SIDES) * (2.0 * np.pi / RING_SIDES)
    ring_x = half_w[:, None] * np.cos(phi)[None, :]
    ring_y = half_h[:, None] * np.sin(phi)[None, :]
    ring_z = np.broadcast_to((-c * spacing)[:, None], ring_x.shape)
    ring_v = np.stack([ring_x, ring_y, ring_z], -1).reshape(-1, 3)
    tip_front = np.array([[0.0, 0.0, (0.5 + HEAD_CAP) * spacing]])
    tip_back = np.array([[0.0, 0.0, -(s_count - 0.5 + TAIL_CAP) * spacing]])
    body_v = np.concatenate([ring_v, tip_front, tip_back])
    body_f = _capped_tube_faces(len(c), RING_SIDES)
    return body_v, body_f


def _capped_tube_faces(n_rings: int, sides: int) -> np.ndarray:
    """Faces (M, 3) of a tube of `n_rings` rings (see _tube_faces) closed by two fans: one to
    vertex n_rings*sides in front of the first ring, one to the next vertex behind the last."""
    i_front = n_rings * sides
    i_back = i_front + 1
    k = np.arange(sides)
    kn = (k + 1) % sides
    front_fan = np.stack([np.full(sides, i_front), k, kn], -1)
    last = (n_rings - 1) * sides
    back_fan = np.stack([np.full(sides, i_back), last + kn, last + k], -1)
    return np.concatenate([_tube_faces(n_rings, sides), front_fan, back_fan])


def _body_skin(c: np.ndarray, spine: np.ndarray, s_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Two-influence skin of the body vertices (rings, then both tips): joints (V, 2) and
    weights (V, 2), blending smoothly from joint floor(c) to the next joint behind it."""
    c_v = np.concatenate([np.repeat(c, RING_SIDES), [-0.5 - HEAD_CAP, s_count - 0.5 + TAIL_CAP]])
    cc = np.clip(c_v, 0.0, s_count - 1.0)
    s0 = np.minimum(np.floor(cc).astype(np.int64), s_count - 2)
    t = _smoothstep(cc - s0)
    body_j = np.stack([spine[s0], spine[s0 + 1]], -1)
    body_w = np.stack([1.0 - t, t], -1)
    return body_j, body_w


def _leg_stubs(wp: np.ndarray, spacing: float, height_ratio: float, leg_stub_length: float,
               spine: np.ndarray, clearance: float | None) -> tuple[np.ndarray, np.ndarray,
                                                                    np.ndarray]:
    """One small closed, tapered tube per side per trunk segment, pointing out and down, each
    rigid on its segment: vertices (V, 3), outward faces (M, 3) indexing them, joint (V,)."""
    seg2, base, length, axis = _stub_placement(wp, spacing, height_ratio, leg_stub_length,
                                               clearance)
    n_legs = len(seg2)
    r0 = np.minimum(0.28 * wp[seg2], 0.25 * length)
    leg_vertices = _stub_vertices(base, length, axis, r0)
    per_leg = leg_vertices.shape[1]                                 # rings + base centre + tip
    # faces for one leg, local indices; rings go base -> tip along `axis`
    one = _capped_tube_faces(len(STUB_STATIONS), LEG_SIDES)
    # the winding is made outward per leg by a signed-volume test (_orient_outward)
    offs = (np.arange(n_legs) * per_leg)[:, None, None]
    lv = leg_vertices.reshape(-1, 3)
    lf = _orient_outward(lv, (one[None] + offs).reshape(-1, 3), per_leg)
    lj = np.repeat(spine[seg2], per_leg)            # each stub is rigid on its segment
    return lv, lf, lj


def _stub_placement(wp: np.ndarray, spacing: float, height_ratio: float,
                    leg_stub_length: float, clearance: float | None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the stubs sit and point, left then right on each trunk segment 1..S-1:
    segment (L,), base (L, 3) inside the body, length (L,) [m], unit axis (L, 3) out and down
    (tip just above the ground at `clearance`, or a fixed slope when it is None)."""
    seg = np.arange(1, len(wp))
    n_legs = 2 * len(seg)
    side = np.tile([1.0, -1.0], len(seg))                       # +X is the creature's left
    seg2 = np.repeat(seg, 2)
    w = wp[seg2]
    h = w * height_ratio
    base = np.stack([side * 0.75 * w, -0.35 * h, -seg2 * spacing], -1)     # (L, 3)
    length = leg_stub_length + 0.75 * w                       # reach out of the body
    if clearance is None:
        sin_down = np.full(n_legs, 0.45)
    else:   # tip just above the ground: drop = clearance - base height - a small margin
        drop = clearance * 0.9 + base[:, 1]
        sin_down = np.clip(drop / length, 0.1, 0.8)
    cos_down = np.sqrt(1.0 - sin_down ** 2)
    axis = np.stack([side * cos_down * 0.97, -sin_down, -cos_down * 0.243], -1)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return seg2, base, length, axis


def _stub_vertices(base: np.ndarray, length: np.ndarray, axis: np.ndarray,
                   r0: np.ndarray) -> np.ndarray:
    """Vertices (L, R*LEG_SIDES + 2, 3) of each stub: its rings at STUB_STATIONS (radius
    r0 * STUB_RADII), then the base centre, then the tip."""
    # frame around the axis: u along +Z-ish (perpendicular), v = axis x u
    ref = np.array([0.0, 0.0, 1.0])
    u = ref - (axis @ ref)[:, None] * axis
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    vv = np.cross(axis, u)
    ts = np.array(STUB_STATIONS)
    radii = np.array(STUB_RADII)
    ang = np.arange(LEG_SIDES) * (2.0 * np.pi / LEG_SIDES)
    # rings: (L, R, K, 3)
    centre = base[:, None, :] + (ts[None, :, None] * length[:, None, None]) * axis[:, None, :]
    rad = (radii[None, :] * r0[:, None])[:, :, None, None]
    circ = (np.cos(ang)[None, None, :, None] * u[:, None, None, :]
            + np.sin(ang)[None, None, :, None] * vv[:, None, None, :])
    rings = centre[:, :, None, :] + rad * circ
    tips = base + length[:, None] * axis
    return np.concatenate([rings.reshape(len(base), -1, 3), base[:, None, :], tips[:, None, :]],
                          axis=1)


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    v = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def _orient_outward(vertices: np.ndarray, faces: np.ndarray, per_leg: int) -> np.ndarray:
    """Flip each closed leg's faces when its signed volume is negative."""
    faces = np.array(faces)
    n_legs = len(vertices) // per_leg
    per_f = len(faces) // n_legs
    fv = np.asarray(vertices, np.float64)[faces.astype(np.int64)].reshape(n_legs, per_f, 3, 3)
    vol = np.einsum("lfi,lfi->lf", fv[:, :, 0], np.cross(fv[:, :, 1], fv[:, :, 2])).sum(1)
    flip = np.repeat(vol < 0, per_f)
    faces[flip] = faces[flip][:, ::-1]
    return faces


# --------------------------------------------------------------------------- limbs
LIMB_SIDES = 6
# stations along a two-bone limb: (bone 0 or 1, fraction along it, radius factor)
_LIMB_STATIONS = ((0, 0.0, 1.0), (0, 0.5, 0.9), (0, 0.9, 0.75), (1, 0.0, 0.7),
                  (1, 0.15, 0.66), (1, 0.55, 0.45), (1, 0.85, 0.2))


def build_limb_mesh(start: np.ndarray, rotations: np.ndarray, lengths: np.ndarray,
                    radii: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                    np.ndarray, np.ndarray]:
    """Tapered tubes ending in a point, one per two-bone limb, in bind space.

    start     : (N, 2, 3) float, bind-space origins of each limb's two bones
    rotations : (N, 2, 4) float, xyzw bind rotations; local +Y runs along the bone
    lengths   : (N, 2) float, bone lengths [m]
    radii     : (N,) float, tube radius at the limb's base [m]
    joints    : (N, 2) int, skeleton joint of each bone
    returns (vertices (V, 3), faces (M, 3), joints (V, 2), weights (V, 2)): rings on the
    first bone follow it rigidly, the knee ring blends both bones, the rest follow the second.
    """
    from baker.geometry.transforms import quat_rotate

    n = len(start)
    ax_x = quat_rotate(rotations, np.broadcast_to([1.0, 0.0, 0.0], rotations.shape[:-1] + (3,)))
    ax_y = quat_rotate(rotations, np.broadcast_to([0.0, 1.0, 0.0], rotations.shape[:-1] + (3,)))
    ax_z = np.cross(ax_x, ax_y)
    ang = np.arange(LIMB_SIDES) * (2.0 * np.pi / LIMB_SIDES)
    rings, rj, rw = [], [], []
    for bone, frac, rf in _LIMB_STATIONS:
        c = start[:, bone] + (frac * lengths[:, bone])[:, None] * ax_y[:, bone]
        if bone == 1 and frac == 0.0:      # the knee: average the two bones' cross-sections
            u = ax_x[:, 0] + ax_x[:, 1]
            y = ax_y[:, 0] + ax_y[:, 1]
            u = u - np.sum(u * y, -1, keepdims=True) * y / np.sum(y * y, -1, keepdims=True)
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            v = np.cross(u, y / np.linalg.norm(y, axis=1, keepdims=True))
            w = (0.5, 0.5)
        else:
            u, v = ax_x[:, bone], ax_z[:, bone]
            w = (1.0, 0.0) if bone == 0 else (0.0, 1.0)
        r = (radii * rf)[:, None, None]
        rings.append(c[:, None, :] + r * (np.cos(ang)[None, :, None] * u[:, None, :]
                                          + np.sin(ang)[None, :, None] * v[:, None, :]))
        rj.append(np.broadcast_to(joints[:, None, :], (n, LIMB_SIDES, 2)))
        rw.append(np.broadcast_to(np.array(w), (n, LIMB_SIDES, 2)))
    n_st = len(_LIMB_STATIONS)
    tip = start[:, 1] + lengths[:, 1][:, None] * ax_y[:, 1]
    base = start[:, 0] - (0.3 * radii)[:, None] * ax_y[:, 0]
    per = n_st * LIMB_SIDES + 2
    verts = np.concatenate([np.stack(rings, 1).reshape(n, -1, 3), base[:, None], tip[:, None]], 1)
    vj = np.concatenate([np.stack(rj, 1).reshape(n, -1, 2), joints[:, None, :], joints[:, None, :]], 1)
    vw = np.concatenate([np.stack(rw, 1).reshape(n, -1, 2),
                         np.broadcast_to([1.0, 0.0], (n, 1, 2)),
                         np.broadcast_to([0.0, 1.0], (n, 1, 2))], 1)
    kk = np.arange(LIMB_SIDES)
    kn = (kk + 1) % LIMB_SIDES
    i_base, i_tip = n_st * LIMB_SIDES, n_st * LIMB_SIDES + 1
    last = (n_st - 1) * LIMB_SIDES
    one = np.concatenate([_tube_faces(n_st, LIMB_SIDES),
                          np.stack([np.full(LIMB_SIDES, i_base), kk, kn], -1),
                          np.stack([np.full(LIMB_SIDES, i_tip), last + kn, last + kk], -1)])
    offs = (np.arange(n) * per)[:, None, None]
    v = verts.reshape(-1, 3)
    f = _orient_outward(v, (one[None] + offs).reshape(-1, 3), per)
    return v, f, vj.reshape(-1, 2), vw.reshape(-1, 2)


def add_limbs(mesh: SkinnedMesh, limb_vertices: np.ndarray, limb_faces: np.ndarray,
              limb_joints: np.ndarray, limb_weights: np.ndarray) -> SkinnedMesh:
    """`mesh` plus limb tubes in the "legs" material (index LEGS)."""
    nv = len(mesh.vertices)
    vertices = np.concatenate([mesh.vertices.astype(np.float64), limb_vertices])
    faces = np.concatenate([mesh.faces.astype(np.int64), limb_faces + nv])
    face_mat = np.concatenate([mesh.face_material, np.full(len(limb_faces), LEGS, np.uint8)])
    j4, w4 = normalize_weights(limb_joints, limb_weights)
    joints = np.concatenate([mesh.joints.astype(np.int64), j4.astype(np.int64)])
    weights = np.concatenate([mesh.weights, w4])
    normals = _vertex_normals(vertices, faces)
    return SkinnedMesh(vertices=vertices, normals=normals, faces=faces, joints=joints,
                       weights=weights, face_material=face_mat, materials=mesh.materials)
