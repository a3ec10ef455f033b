"""Binary PLY levels whose faces mix sizes (Blender's default PLY export of triangles and
quads): trimesh refuses them, environment.ply reads them."""

import struct

import numpy as np
import pytest

from baker.environment import load_environment
from baker.errors import EnvironmentLoadError

#: a square, a triangle beside it and an L-shaped floor (concave) apart from them
POINTS = [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0), (2, 0, 0),
          (0, 0, 5), (1, 0, 5), (1, 0, 6), (2, 0, 6), (2, 0, 7), (0, 0, 7)]
#: all facing +Y
FACES = [(0, 1, 2, 3), (3, 2, 4), (5, 10, 9, 8, 7, 6)]


def _ply(order="<", colours=False, faces=FACES, cut=0) -> bytes:
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    head = (f"ply\nformat {fmt} 1.0\ncomment made by a test\nelement vertex {len(POINTS)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            + ("property uchar red\nproperty uchar green\nproperty uchar blue\n" if colours
               else "")
            + f"element face {len(faces)}\nproperty list uchar int vertex_indices\n"
            "property float quality\nend_header\n")
    body = b"".join(struct.pack(order + "3f", *p) + (struct.pack("3B", 200, 10, 10) if colours
                                                       else b"") for p in POINTS)
    body += b"".join(struct.pack(f"{order}B{len(f)}if", len(f), *f, 0.5) for f in faces)
    data = head.encode() + body
    return data[:len(data) - cut]


def _covered(env) -> np.ndarray:
    t = (env.mesh.vertices + env.origin)[env.mesh.faces]
    return 0.5 * np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 1]


@pytest.mark.parametrize("order", ["<", ">"])
def test_mixed_face_sizes_load(tmp_path, order):
    p = tmp_path / "level.ply"
    p.write_bytes(_ply(order))
    env = load_environment(p)
    up = _covered(env)
    # 2 + 1 + 4 triangles, all facing +Y (the L ear-cut: its fan covers more, wound both ways)
    assert len(env.mesh.faces) == 7
    assert np.all(up > 0) and np.isclose(up.sum(), 1.0 + 0.5 + 3.0)


def test_mixed_face_sizes_keep_their_colour(tmp_path):
    p = tmp_path / "level.ply"
    p.write_bytes(_ply(colours=True))
    r, g, b, a = load_environment(p).meshes[0].color
    assert r > 0.5 > 0.01 > g and a == 1.0


def test_uniform_faces_read_as_before(tmp_path):
    """Faces of one size take trimesh's own reading, as before."""
    p = tmp_path / "level.ply"
    p.write_bytes(_ply(faces=[(0, 1, 2), (0, 2, 3)]))
    assert len(load_environment(p).mesh.faces) == 2


@pytest.mark.parametrize("cut", [1, 9, 40])
def test_truncated_mixed_faces_refused(tmp_path, cut):
    p = tmp_path / "cut.ply"
    p.write_bytes(_ply(cut=cut))
    with pytest.raises(EnvironmentLoadError, match="cut.ply"):
        load_environment(p)


def test_face_index_out_of_range_refused(tmp_path):
    p = tmp_path / "far.ply"
    p.write_bytes(_ply(faces=FACES + [(0, 1, 99, 2)]))
    with pytest.raises(EnvironmentLoadError, match="outside its 11 vertices"):
        load_environment(p)


def test_row_count_past_the_file_refused_before_reading(tmp_path):
    """A header claiming 3 billion faces in a 0.3 kB file is refused before any row is read."""
    p = tmp_path / "huge.ply"
    p.write_bytes(_ply().replace(b"element face 3\n", b"element face 3000000000\n"))
    with pytest.raises(EnvironmentLoadError, match="3,000,000,000 rows"):
        load_environment(p)


@pytest.mark.parametrize("cut", [20, 60, 150])
def test_header_cut_short_says_so(tmp_path, cut):
    p = tmp_path / "short.ply"
    p.write_bytes(_ply()[:cut])
    with pytest.raises(EnvironmentLoadError, match="no end_header"):
        load_environment(p)


@pytest.mark.parametrize("order", ["<", ">"])
def test_mixed_sizes_adding_up_to_uniform_rows_load_as_modelled(tmp_path, order):
    """A quad, a triangle and a pentagon take as many bytes as three quads (the lists' rows:
    17 + 13 + 21 = 3 x 17 bytes with the quality float): trimesh took them for three quads,
    read misaligned, with no error of size to send the file here."""
    faces = [(0, 1, 2, 3), (3, 2, 4), (5, 10, 9, 8, 6)]      # the pentagon: 4 m^2 less 0.5
    p = tmp_path / "level.ply"
    p.write_bytes(_ply(order, faces=faces))
    env = load_environment(p)
    up = _covered(env)
    assert len(env.mesh.faces) == 2 + 1 + 3
    assert np.all(up > 0) and np.isclose(up.sum(), 1.0 + 0.5 + 3.5)


def test_uniform_lists_is_exact():
    from baker.environment.ply import uniform_lists

    assert uniform_lists(_ply(faces=[(0, 1, 2), (0, 2, 3)]))
    assert uniform_lists(_ply(">", colours=True, faces=[(0, 1, 2, 3)] * 3))
    assert not uniform_lists(_ply(faces=[(0, 1, 2, 3), (3, 2, 4), (5, 10, 9, 8, 6)]))
    assert not uniform_lists(_ply())
    assert not uniform_lists(_ply(faces=[(0, 1, 2), (0, 2, 3)], cut=3))   # past the file
