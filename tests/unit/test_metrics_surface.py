"""metrics.inside_geometry (joints inside solids) and metrics.surface_metrics (spine off the
walkable navigation surface) on scenes built in code."""

import math

import numpy as np
import trimesh

from baker.config import NavAgentConfig
from baker.environment.model import EnvMesh, Environment, Sun
from baker.metrics import inside_geometry, surface_metrics
from baker.navmesh import build


def env_of(*meshes) -> Environment:
    return Environment(tuple(EnvMesh(f"m{i}", np.asarray(m.vertices, np.float32),
                                     np.asarray(m.faces, np.uint32)) for i, m in enumerate(meshes)),
                       Sun(np.array([0.0, 1.0, 0.0])))


def floor(size=2.0):
    h = size / 2
    return trimesh.Trimesh([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h]],
                           [[0, 2, 1], [0, 3, 2]], process=False)  # one-sided, normal up


def box(centre, extents):
    b = trimesh.creation.box(extents=extents)
    b.apply_translation(centre)
    return b


def test_inside_a_closed_box_and_below_an_open_floor():
    env = env_of(floor(), box((0.5, 0.1, 0.5), (0.2, 0.2, 0.2)))
    pts = np.array([
        [0.5, 0.1, 0.5],     # in the box
        [0.45, 0.02, 0.55],  # in the box, near its bottom
        [0.0, 0.01, 0.0],    # on the floor
        [0.5, 0.25, 0.5],    # on the box
        [0.0, -0.05, 0.0],   # under the one-sided floor: inside the ground
        [0.3, 0.05, 0.5],    # beside the box
    ])
    assert inside_geometry(pts, env.rays).tolist() == [True, True, False, False, True, False]


def test_inside_is_winding_majority_not_single_face():
    b = box((0.0, 0.5, 0.0), (1.0, 1.0, 1.0))
    f = np.asarray(b.faces).copy()
    f[0] = f[0][::-1]  # one flipped triangle, on the x = -0.5 side
    env = env_of(trimesh.Trimesh(b.vertices, f, process=False))
    rng = np.random.default_rng(0)
    inner = rng.uniform([-0.45, 0.05, -0.45], [0.45, 0.95, 0.45], (200, 3))
    outer = inner + [0.0, 1.5, 0.0]
    # the flipped face is outvoted wherever it is not the nearest thing the point sees
    away = inner[inner[:, 0] > 0.0]
    assert len(away) > 80 and inside_geometry(away, env.rays).all()
    assert inside_geometry(inner, env.rays).mean() > 0.9
    assert not inside_geometry(outer, env.rays).any()
    # a one-sided deck overhead (normal up) with the floor below: not inside
    deck = floor(1.0)
    deck.apply_translation((0, 1.0, 0))
    env2 = env_of(floor(), deck)
    assert not inside_geometry([[0.0, 0.5, 0.0]], env2.rays).any()


def test_grazing_the_far_side_of_rough_ground_is_not_inside():
    """A foot 5 cm over the ground whose horizontal rays slip through seams of rough ground and
    meet the far side of two gentle slopes half a metre away (seen from behind, at a glancing
    angle): the ground straight below, met squarely from the front, outweighs them."""
    def slope(centre, normal):
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(n, a)
        c = np.asarray(centre, float)
        v = [c - 0.2 * a - 0.2 * b, c + 0.2 * a - 0.2 * b, c + 0.2 * a + 0.2 * b, c - 0.2 * a + 0.2 * b]
        tri = np.array([[0, 1, 2], [0, 2, 3]])
        m = trimesh.Trimesh(v, tri, process=False)
        if np.dot(m.face_normals[0], n) < 0:
            m = trimesh.Trimesh(v, tri[:, ::-1], process=False)
        return m

    foot = np.array([[0.0, 0.05, 0.0]])
    behind_x = slope((-0.5, 0.05, 0.0), (-0.22, 0.96, 0.0))   # ray -x meets its back at cos 0.22
    behind_z = slope((0.0, 0.05, -0.5), (0.0, 0.9, -0.44))    # ray -z meets its back at cos 0.44
    env = env_of(floor(), behind_x, behind_z)
    t, prim = env.rays.cast(np.repeat(foot, 6, axis=0), np.array(
        [[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1]], float))
    assert (prim >= 0).sum() == 3                      # below, and the two slopes from behind
    assert not inside_geometry(foot, env.rays).any()
    # the same slopes met squarely (a real solid around the point) still make it inside
    assert inside_geometry([[0.0, -0.05, 0.0]], env.rays).all()


def test_open_air_under_a_leaf_is_not_inside():
    """A foot 6 cm over the floor, under a one-sided leaf (normal up) 27 cm overhead, with a wall
    4 m away facing away from it: two back faces against one front, but the nearest thing it
    sees is the floor, from the front."""
    leaf = floor(0.4)
    leaf.apply_translation((0.0, 0.33, 0.0))
    wall = trimesh.Trimesh([[-4.0, -1, -1], [-4.0, 2, -1], [-4.0, 2, 1], [-4.0, -1, 1]],
                           [[0, 1, 2], [0, 2, 3]], process=False)
    if wall.face_normals[0][0] > 0:
        wall.invert()                                       # faces -x: seen from behind
    env = env_of(floor(), leaf, wall)
    assert not inside_geometry([[0.0, 0.06, 0.0]], env.rays).any()
    # still inside: a point under the floor (its back face is the nearest hit)
    assert inside_geometry([[0.0, -0.02, 0.0]], env.rays).all()


class _Traj:
    def __init__(self, pos, ground):
        self.spine_positions = pos
        self.ground_heights = ground


def test_surface_metrics_counts_only_beyond_the_agent_radius():
    # floor 2 x 2 m with a wall-less edge: the eroded surface ends `radius` inside the edge
    env = env_of(floor())
    agent = NavAgentConfig(radius=0.05, height=0.1, step_height=0.02, max_slope=math.radians(60),
                           cell_size=0.01)
    nav = build(env, agent)
    xs = np.array([0.0, 0.9, 0.94, 0.99])  # 0.95 is the eroded edge
    pos = np.zeros((len(xs), 3, 3))
    pos[:, :, 0] = xs[:, None] - np.array([0.0, 0.02, 0.04])[None]
    pos[:, :, 1] = 0.01
    tr = _Traj(pos, np.zeros((len(xs), 3)))
    m = surface_metrics(tr, nav, clearance=0.01)
    assert m["head_off_navmesh_frames"] == 1          # x = 0.99 is past the eroded edge
    assert 0.03 < m["head_off_navmesh_max_m"] < 0.05
    assert m["head_off_walkable_frames"] == 0         # but within the radius of it
    far = replace_x(pos, 1.2)
    m = surface_metrics(_Traj(far, np.full((len(xs), 3), np.nan)), nav, clearance=0.01)
    assert m["head_off_walkable_frames"] == len(xs)
    assert m["trunk_off_walkable"] == 2 * len(xs)


def replace_x(pos, x):
    p = pos.copy()
    p[:, :, 0] = x
    return p


def test_open_sky_between_two_overlapping_leaves_is_not_inside():
    """A spine joint 2.4 cm over a one-sided leaf, beside the edge of a second leaf that
    overlaps it and slopes down away from the joint (the showcase's seedling, default seeds
    110613 and 110742): its +z ray meets the upper leaf from below, nearer than the leaf under
    it, and its -x and -z rays meet a stem and a far leaf from behind. Three back faces
    against one front, the nearest a back face, but nothing is overhead: it is in the open.
    Inside a closed solid or under a one-sided ground something always is."""
    def sheet(corners):
        m = trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]], process=False)
        return m if m.face_normals[0][1] > 0 else trimesh.Trimesh(corners, [[0, 2, 1], [0, 3, 2]],
                                                                 process=False)
    lower = floor(0.4)                                                 # normal up
    upper = sheet([[-0.1, 0.026, 0.015], [0.1, 0.026, 0.015], [0.1, 0.004, 0.035],
                   [-0.1, 0.004, 0.035]])                              # slopes down to +z
    stem = trimesh.Trimesh([[-0.15, -1, -1], [-0.15, 1, -1], [-0.15, 1, 1], [-0.15, -1, 1]],
                           [[0, 1, 2], [0, 2, 3]], process=False)
    if stem.face_normals[0][0] > 0:
        stem.invert()                                                  # faces -x: seen from behind
    far = sheet([[-0.3, 0.0, -0.8], [0.3, 0.0, -0.8], [0.3, 0.3, -0.6], [-0.3, 0.3, -0.6]])
    env = env_of(lower, upper, stem, far)
    joint = np.array([[0.0, 0.024, 0.0]])
    t, prim = env.rays.cast(np.repeat(joint, 6, axis=0), np.array(
        [[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1]], float))
    assert prim[0] < 0 and (prim[1:] >= 0).tolist() == [True, False, True, True, True]
    assert t[4] < t[1]                                  # the upper leaf, from below, is nearest
    assert not inside_geometry(joint, env.rays).any()
    # under the upper leaf (it is overhead now), in the wedge: still not inside, the leaf
    # below is nearer; below the lower leaf: inside, as under any one-sided ground
    assert not inside_geometry([[0.0, 0.006, 0.025]], env.rays).any()
    assert inside_geometry([[0.0, -0.01, 0.0]], env.rays).all()


def test_the_circular_mean_of_no_strides_is_none_without_a_warning():
    import warnings

    from baker.metrics import circular_mean_deg

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert circular_mean_deg(np.array([])) is None
        assert abs(circular_mean_deg(np.array([0.25, 0.25])) - 90.0) < 1e-9
        # 350 deg and 10 deg average to 0 deg round the circle, not 180
        assert abs(circular_mean_deg(np.array([350.0, 10.0]) / 360.0)) < 1e-9
