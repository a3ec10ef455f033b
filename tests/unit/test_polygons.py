"""geometry.polygons: convex polygons keep their fan, concave ones are ear-cut in their plane,
and the loaders (OBJ, USD) triangulate a concave face so that its triangles cover it once."""

import numpy as np
import pytest

from baker.environment import load_environment
from baker.geometry import polygons

#: an L-shaped floor (x, z) listed from an outer corner: its fan covers the notch
L_SHAPE = [(2, 2), (0, 2), (0, 0), (1, 0), (1, 1), (2, 1)]


def _lifted(xz, y=0.0):
    """(n, 3) points of (x, z) pairs at height y."""
    xz = np.asarray(xz, dtype=np.float64)
    return np.stack([xz[:, 0], np.full(len(xz), y), xz[:, 1]], axis=1)


def _areas(points, tris):
    """(T, 3) area-weighted normals of the triangles."""
    t = np.asarray(points)[tris]
    return 0.5 * np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def _shoelace(xz) -> float:
    x, z = np.asarray(xz, dtype=np.float64).T
    return 0.5 * float(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1)))


def test_fan_of_a_convex_polygon_is_kept():
    square = _lifted([(0, 0), (0, 1), (1, 1), (1, 0)])
    counts, idx = np.array([4, 3]), np.array([0, 1, 2, 3, 0, 1, 2])
    assert not polygons.concave(square, counts, idx).any()
    assert polygons.triangulate(square, counts, idx).tolist() == [[0, 1, 2], [0, 2, 3],
                                                                  [0, 1, 2]]


@pytest.mark.parametrize("shape, bent", [
    (L_SHAPE, True),
    ([(0, 0), (2, 1), (0, 2), (0.5, 1)], True),           # a dart: a concave quad
    ([(0, 0), (1, 0), (2, 0), (2, 1), (0, 1)], False),    # a corner on a straight edge
    ([(0, 0), (1, 0), (2, 0), (3, 0)], False),            # no area
])
def test_concave_polygons_are_found(shape, bent):
    pts = _lifted(shape)
    assert polygons.concave(pts, np.array([len(pts)]), np.arange(len(pts))).tolist() == [bent]


def test_random_polygons_are_covered_once():
    """Star-shaped polygons with random radii, in random planes, either winding: the triangles'
    areas add up to the polygon's and each faces as the polygon does."""
    rng = np.random.default_rng(20261202)
    for n in [4, 5, 6, 9, 16, 40] * 5:
        # one corner in each of n equal sectors: simple, the origin inside
        angle = 2 * np.pi * (np.arange(n) + rng.uniform(0.0, 1.0, n)) / n
        radius = rng.uniform(0.2, 1.0, n)
        xz = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
        if rng.random() < 0.5:
            xz = xz[::-1]
        turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        pts = _lifted(xz) @ turn.T + rng.normal(size=3) * 100.0
        tris = polygons.triangulate(pts, np.array([n]), np.arange(n))
        normal = turn @ np.array([0.0, 1.0, 0.0])
        facing = _areas(pts, tris) @ normal
        # (x, z) counter-clockwise seen from +y faces -y: x cross z = -y
        assert np.all(facing * -np.sign(_shoelace(xz)) >= -1e-9)
        assert np.isclose(np.abs(facing).sum(), abs(_shoelace(xz)), rtol=1e-9)


def test_obj_concave_polygon_is_cut(tmp_path):
    """An OBJ's L-shaped n-gon (with texture and normal indices, CRLF) covers 3 square metres
    facing up, beside a convex quad kept as trimesh fans it."""
    lines = [f"v {x} 0 {z}" for x, z in L_SHAPE[::-1]] + ["vt 0 0", "vn 0 1 0"]
    lines += ["v 5 0 5", "v 5 0 6", "v 6 0 6", "v 6 0 5"]
    lines += ["f " + " ".join(f"{k}/1/1" for k in range(1, 7)), "f  7 8  9 10 "]
    p = tmp_path / "floor.obj"
    p.write_bytes(("\r\n".join(lines) + "\r\n").encode())
    env = load_environment(p)
    up = _areas(env.mesh.vertices, env.mesh.faces)[:, 1]
    assert len(env.mesh.faces) == 6 and np.all(up > 0)
    assert np.isclose(up.sum(), 4.0)


USD_NGON = """#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 1
)
def Mesh "floor"
{{
    uniform token orientation = "{orientation}"
    int[] faceVertexCounts = [6, 3, 4]
    int[] faceVertexIndices = [{ring}, 0, 1, 2, 0, 1, 2, 3]
    int[] holeIndices = [{hole}]
    point3f[] points = [{points}]
}}
"""


@pytest.mark.parametrize("orientation", ["rightHanded", "leftHanded"])
def test_usd_concave_face_is_cut(tmp_path, orientation):
    """A USD mesh's concave hexagon is ear-cut (its hole face left out, its convex quad
    fanned as before), wound as its orientation says."""
    ring = list(range(6)) if orientation == "leftHanded" else list(range(5, -1, -1))
    pts = ", ".join(f"({x}, 0, {z})" for x, z in L_SHAPE)
    p = tmp_path / "floor.usda"
    p.write_text(USD_NGON.format(orientation=orientation, ring=", ".join(map(str, ring)),
                                 hole=1, points=pts))
    env = load_environment(p)
    up = _areas(env.mesh.vertices, env.mesh.faces)[:, 1]
    # the hexagon's 4 triangles, facing up, and the quad's 2
    assert len(env.mesh.faces) == 6
    assert np.all(up[:4] > 0) and np.isclose(up[:4].sum(), 3.0)
    assert np.isclose(np.abs(up[4:]).sum(), abs(_shoelace(L_SHAPE[:4])))


@pytest.mark.parametrize("binary", [False, True])
def test_ply_concave_polygon_is_cut(tmp_path, binary):
    """A PLY's L-shaped hexagon (ASCII and binary, with face colours) covers 3 square metres
    facing up, its colour kept."""
    import struct

    pts = _lifted(L_SHAPE[::-1])
    head = ("ply\nformat {} 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
    if binary:
        body = b"".join(struct.pack("<3f", *p) for p in pts)
        body += struct.pack("<B6i3B", 6, *range(6), 255, 0, 0)
        data = head.format("binary_little_endian").encode() + body
    else:
        data = (head.format("ascii") + "".join(f"{x} {y} {z}\n" for x, y, z in pts)
                + "6 0 1 2 3 4 5 255 0 0\n").encode()
    p = tmp_path / "floor.ply"
    p.write_bytes(data)
    env = load_environment(p)
    up = _areas(env.mesh.vertices, env.mesh.faces)[:, 1]
    assert len(env.mesh.faces) == 4 and np.all(up > 0) and np.isclose(up.sum(), 3.0)
    assert env.meshes[0].color[0] > 0.9 and env.meshes[0].color[1] < 0.1
