"""PLY triangle strips (a `tristrips` element, as in old Stanford files: it was refused as 'no
triangle faces') and face lists declared float (2.5 was cut to 2)."""

import struct

import numpy as np
import pytest

from baker.environment import load_environment
from baker.environment.ply import strip_triangles
from baker.errors import EnvironmentLoadError

#: the 4 corners of a 1 x 1 m floor, around it (strip 0 1 3 2 covers it)
FLOOR = [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0)]
#: two 2 x 1 m rows of quads apart: a0 b0 a1 b1 a2 b2 at x = 0..2, c0 d0 c1 d1 at x = 4..5
ROWS = [(0, 0, 0), (0, 0, 1), (1, 0, 0), (1, 0, 1), (2, 0, 0), (2, 0, 1),
        (4, 0, 0), (4, 0, 1), (5, 0, 0), (5, 0, 1)]


def _ply(points, strips, fmt="ascii", count="int", item="int") -> bytes:
    head = (f"ply\nformat {fmt} 1.0\nelement vertex {len(points)}\nproperty float x\n"
            f"property float y\nproperty float z\nelement tristrips {len(strips)}\n"
            f"property list {count} {item} vertex_indices\nend_header\n").encode()
    if fmt == "ascii":
        return head + "".join(f"{x} {y} {z}\n" for x, y, z in points).encode() + "".join(
            f"{len(s)} " + " ".join(map(str, s)) + "\n" for s in strips).encode()
    o = "<" if fmt == "binary_little_endian" else ">"
    c, i = {"int": "i", "uchar": "B"}[count], {"int": "i", "float": "f"}[item]
    return head + b"".join(struct.pack(o + "3f", *p) for p in points) + b"".join(
        struct.pack(f"{o}{c}{len(s)}{i}", len(s), *s) for s in strips)


def _triangles(env) -> tuple[set, np.ndarray]:
    """({triangle as its corners' coordinates from its least corner on}, each one's area
    facing +Y)."""
    t = (env.mesh.vertices + env.origin)[env.mesh.faces]
    out = set()
    for tri in np.round(t, 6).tolist():
        k = tri.index(min(tri))
        out.add(tuple(map(tuple, tri[k:] + tri[:k])))
    return out, 0.5 * np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 1]


FORMATS = ["ascii", "binary_little_endian", "binary_big_endian"]


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_strip_is_its_triangles_wound_alike(tmp_path, fmt):
    """0 1 3 2: (0 1 3) then (3 1 2): the second reversed, so both face up."""
    p = tmp_path / "floor.ply"
    p.write_bytes(_ply(FLOOR, [[0, 1, 3, 2]], fmt))
    tris, up = _triangles(load_environment(p))
    assert tris == {((0, 0, 0), (0, 0, 1), (1, 0, 0)), ((0, 0, 1), (1, 0, 1), (1, 0, 0))}
    assert np.allclose(up, 0.5)


@pytest.mark.parametrize("fmt", FORMATS)
def test_minus_1_restarts_a_strip(tmp_path, fmt):
    """0 1 3 -1 3 1 2: two strips of one triangle each; the second starts afresh (not
    reversed), so (3 1 2) faces up as written."""
    p = tmp_path / "floor.ply"
    p.write_bytes(_ply(FLOOR, [[0, 1, 3, -1, 3, 1, 2]], fmt))
    tris, up = _triangles(load_environment(p))
    assert tris == {((0, 0, 0), (0, 0, 1), (1, 0, 0)), ((0, 0, 1), (1, 0, 1), (1, 0, 0))}
    assert np.allclose(up, 0.5)


@pytest.mark.parametrize("fmt", FORMATS)
def test_strips_of_several_lengths_and_stitched_ones(tmp_path, fmt):
    """Rows of different lengths (trimesh reads a binary file's lists as if all had the
    first's length), and two strips stitched into one row by repeated corners (the
    degenerate triangles are left out; the winding carries on through them)."""
    p = tmp_path / "rows.ply"
    p.write_bytes(_ply(ROWS, [[0, 1, 2, 3, 3, 6, 6, 7, 8, 9], [2, 3, 4], [3, 5, 4]], fmt))
    tris, up = _triangles(load_environment(p))
    assert len(up) == len(tris) == 6    # 2 + 2 (4 degenerate ones between), 1, 1
    assert np.all(up > 0) and np.isclose(up.sum(), 3.0)


def test_strip_triangles_direct():
    tris = strip_triangles(np.array([6, 4]), np.array([0, 1, 2, 2, 3, 4, 5, 6, -1, 7]))
    assert tris.tolist() == [[0, 1, 2], [3, 2, 4]]      # (1 2 2) and (2 2 3) left out
    # a row of fewer than 3 corners and a -1 at either end make nothing
    assert strip_triangles(np.array([2, 1, 3]), np.array([0, 1, -1, -1, 1, 2])).shape == (0, 3)


def test_faces_and_strips_together(tmp_path):
    """A file with both a face element and strips: the triangles of both (the floor's
    first two quads of ROWS as faces, the last as a strip)."""
    data = _ply(ROWS, [[6, 7, 8, 9]]).replace(
        b"element tristrips 1\n", b"element face 2\nproperty list uchar int vertex_indices\n"
        b"element tristrips 1\n")
    at = data.index(b"4 6 7 8 9")
    data = data[:at] + b"3 0 1 2\n3 2 1 3\n" + data[at:]
    p = tmp_path / "both.ply"
    p.write_bytes(data)
    tris, up = _triangles(load_environment(p))
    assert len(tris) == 4 and np.all(up > 0) and np.isclose(up.sum(), 2.0)


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("strip, match", [
    ([0, 1, 3, 7], "tristrips row 0 has vertex index 7, outside its 4 vertices"),
    ([0, 1, 3, -2], "tristrips row 0 has vertex index -2, outside"),
])
def test_strip_index_outside_refused(tmp_path, fmt, strip, match):
    p = tmp_path / "bad.ply"
    p.write_bytes(_ply(FLOOR, [[0, 1, 3, 2], strip], fmt))
    with pytest.raises(EnvironmentLoadError, match=match.replace("row 0", "row 1")):
        load_environment(p)


def _float_faces(faces, fmt) -> bytes:
    head = (f"ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(faces)}\n"
            "property list uchar float vertex_indices\nend_header\n").encode()
    if fmt == "ascii":
        return head + "".join(f"{x} {y} {z}\n" for x, y, z in FLOOR).encode() + "".join(
            f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces).encode()
    return head + np.array(FLOOR, "<f4").tobytes() + b"".join(
        struct.pack(f"<B{len(f)}f", len(f), *f) for f in faces)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("faces", [[[0, 1, 2.0], [0, 2, 3]], [[0, 1, 2.0, 3.0]]])
def test_float_face_list_of_whole_numbers_loads(tmp_path, fmt, faces):
    p = tmp_path / "f.ply"
    p.write_bytes(_float_faces(faces, fmt))
    tris, up = _triangles(load_environment(p))
    assert np.all(up > 0) and np.isclose(up.sum(), 1.0)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("faces, match", [
    ([[0, 1, 2], [0, 2, 2.5]], "PLY face row 1 has vertex index 2.5, not a whole number"),
    ([[0, 1, 2.5], [0, 2, 3, 1]], "PLY face row 0 has vertex index 2.5, not a whole number"),
    ([[0, 1, 2], [0, 2, 4.0]], "PLY face row 1 has vertex index 4, outside its 4 vertices"),
    ([[0, 1, 2], [0, 2, -1.0]], "PLY face row 1 has vertex index -1, outside"),
    ([[0, 1, 2], [0, 2, 3e9]], "PLY face row 1 has vertex index 3e\\+09, outside"),
])
def test_float_face_list_fraction_or_outside_refused(tmp_path, fmt, faces, match):
    p = tmp_path / "f.ply"
    p.write_bytes(_float_faces(faces, fmt))
    with pytest.raises(EnvironmentLoadError, match=match):
        load_environment(p)
