"""Navigation surface on scenes built in code, with known answers (issue 3).

Agent for every scene: radius r = 0.05 m, height h = 0.1 m, step s = 0.05 m, slope 60 deg,
cell 0.01 m (small scenes of about 1 x 1 m, so each build takes milliseconds).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from baker.config import NavAgentConfig
from baker.environment.model import EnvMesh, Environment, Sun
from baker.errors import NavError
from baker.navmesh import NavSurface, build

R, H, STEP, CELL = 0.05, 0.1, 0.05, 0.01
AGENT = NavAgentConfig(radius=R, height=H, step_height=STEP, max_slope=math.radians(60.0),
                       cell_size=CELL)


# --------------------------------------------------------------------------- scene helpers
def env_of(*meshes, flip: bool = False) -> Environment:
    """Environment from trimesh meshes; flip=True reverses every face's winding."""
    out = []
    for i, m in enumerate(meshes):
        f = np.asarray(m.faces)
        out.append(EnvMesh(f"m{i}", np.asarray(m.vertices, np.float32),
                           np.asarray(f[:, ::-1] if flip else f, np.uint32)))
    return Environment(tuple(out), Sun(np.array([0.0, 1.0, 0.0])))


def quad(p0, p1, p2, p3) -> trimesh.Trimesh:
    """Open, zero-thickness quad (two triangles)."""
    return trimesh.Trimesh(np.array([p0, p1, p2, p3], float), [[0, 1, 2], [0, 2, 3]],
                           process=False)


def floor(x0=0.0, x1=1.0, z0=0.0, z1=1.0, y=0.0) -> trimesh.Trimesh:
    return quad((x0, y, z0), (x0, y, z1), (x1, y, z1), (x1, y, z0))


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def ramp_scene(deg: float) -> Environment:
    """Floor x in [0, 0.3] at y = 0, a ramp from x = 0.3 rising at `deg` over 0.2 m of x, a
    platform 0.4 m long on top; all 0.6 m wide in z."""
    L = 0.2
    top = L * math.tan(math.radians(deg))
    return env_of(floor(0.0, 0.3, 0.0, 0.6),
                  quad((0.3, 0, 0), (0.3, 0, 0.6), (0.3 + L, top, 0.6), (0.3 + L, top, 0)),
                  floor(0.3 + L, 0.9 + L, 0.0, 0.6, y=top))


def bridge_scene() -> Environment:
    """A road along X (y = 0, z in [0.35, 0.65]) under a 0.02 m thick bridge deck along Z
    (top at y = 0.3, x in [0.35, 0.65])."""
    return env_of(floor(0.0, 1.0, 0.35, 0.65),
                  box((0.35, 0.28, 0.0), (0.65, 0.30, 1.0)))


def half_log(r_in=0.16, r_out=0.2, length=0.8, centre=(0.5, 0.0, 0.5),
             sections=96) -> trimesh.Trimesh:
    """Closed half-annulus shell lying on y = 0 with its axis along Z, open at both ends."""
    cx, cy, cz = centre
    th = np.linspace(0.0, np.pi, sections + 1)
    z0, z1 = cz - length / 2, cz + length / 2
    v = []
    for t in th:  # per angle: outer z0, outer z1, inner z0, inner z1
        for r in (r_out, r_in):
            for z in (z0, z1):
                v.append((cx + r * np.cos(t), cy + r * np.sin(t), z))
    f = []
    for i in range(sections):
        a, b = 4 * i, 4 * (i + 1)
        for o0, o1 in ((0, 1), (2, 3), (0, 2), (1, 3)):  # outer, inner, cap z0, cap z1
            f += [(a + o0, b + o0, b + o1), (a + o0, b + o1, a + o1)]
    for a in (0, 4 * sections):  # the two strips standing on the floor
        f += [(a, a + 2, a + 3), (a, a + 3, a + 1)]
    m = trimesh.Trimesh(np.array(v), np.array(f), process=False)
    assert m.is_watertight
    return m


def wall_scene() -> Environment:
    """Floor 1 x 1 m with a zero-thickness wall at x = 0.503 from z = 0 to z = 0.7, 0.3 m
    high."""
    return env_of(floor(), quad((0.503, 0, 0), (0.503, 0.3, 0), (0.503, 0.3, 0.7),
                                (0.503, 0, 0.7)))


def segments_cross_wall(points: np.ndarray, x=0.503, z0=0.0, z1=0.7) -> bool:
    for a, b in zip(points[:-1], points[1:]):
        if (a[0] - x) * (b[0] - x) < 0:
            t = (x - a[0]) / (b[0] - a[0])
            z = a[2] + t * (b[2] - a[2])
            if z0 <= z <= z1:
                return True
    return False


def path_on_surface(s: NavSurface, pts: np.ndarray) -> bool:
    return bool(s.is_walkable(pts, tol=1e-4).all())


# --------------------------------------------------------------------------- tests
@pytest.mark.parametrize("deg, walkable", [(59.0, True), (61.0, False)])
def test_ramp_slope_limit(deg, walkable):
    s = build(ramp_scene(deg), AGENT)
    mid = np.array([0.4, 0.1 * math.tan(math.radians(deg)), 0.3])
    assert bool(s.is_walkable(mid[None])[0]) == walkable
    top = 0.2 * math.tan(math.radians(deg))
    r = s.find_path([0.1, 0.0, 0.3], [0.8, top, 0.3])
    assert r.complete == walkable
    assert path_on_surface(s, r.points)
    if walkable:
        assert abs(r.points[-1][1] - top) < 1e-3


@pytest.mark.parametrize("factor, linked", [(0.9, True), (1.1, False)])
def test_step_height(factor, linked):
    hgt = factor * STEP
    s = build(env_of(floor(), box((0.5, 0.0, 0.0), (1.0, hgt, 1.0))), AGENT)
    r = s.find_path([0.2, 0.0, 0.5], [0.8, hgt, 0.5])
    assert r.complete == linked
    assert path_on_surface(s, r.points)
    if not linked:  # ends at the closest reachable point: the foot of the step
        assert r.points[-1][0] < 0.5 and abs(r.points[-1][1]) < 1e-6
        assert s.component_of([0.2, 0, 0.5]) != s.component_of([0.8, hgt, 0.5])


@pytest.mark.parametrize("factor, clear", [(0.9, False), (1.1, True)])
def test_ceiling_clearance(factor, clear):
    y = factor * H
    ceiling = quad((0.3, y, 0.0), (0.3, y, 1.0), (0.7, y, 1.0), (0.7, y, 0.0))
    s = build(env_of(floor(), ceiling), AGENT)
    assert bool(s.is_walkable([[0.5, 0.0, 0.5]])[0]) == clear
    assert bool(s.is_walkable([[0.5, y, 0.5]])[0])  # the ceiling's top is a floor
    r = s.find_path([0.1, 0.0, 0.5], [0.9, 0.0, 0.5])
    assert r.complete == clear
    if clear:
        assert np.all(np.abs(r.points[:, 1]) < 1e-6)  # stays under the ceiling


@pytest.mark.parametrize("factor, passable", [(1.9, False), (2.1, True)])
def test_corridor_width(factor, passable):
    """Corridor width = clear distance between the wall faces; an agent of radius r passes
    when it is at least 2 r."""
    w = factor * R
    zc = 0.505
    walls = [box((0.3, 0.0, 0.0), (0.7, 0.3, zc - w / 2)),
             box((0.3, 0.0, zc + w / 2), (0.7, 0.3, 1.0))]
    s = build(env_of(floor(), *walls), AGENT)
    r = s.find_path([0.1, 0.0, zc], [0.9, 0.0, zc])
    assert r.complete == passable
    inside = s.positions[(s.positions[:, 0] > 0.35) & (s.positions[:, 0] < 0.65)
                         & (s.positions[:, 1] < 0.1)]
    assert (len(inside) > 0) == passable
    if passable:  # every sample keeps the radius from both walls
        assert np.all(inside[:, 2] - (zc - w / 2) >= R - 1e-6)
        assert np.all((zc + w / 2) - inside[:, 2] >= R - 1e-6)


@pytest.mark.parametrize("flip", [False, True])
def test_thin_wall_is_walked_around(flip):
    s = build(wall_scene() if not flip else env_of(
        floor(), quad((0.503, 0, 0), (0.503, 0.3, 0), (0.503, 0.3, 0.7), (0.503, 0, 0.7)),
        flip=True), AGENT)
    a, b = np.array([0.2, 0.0, 0.3]), np.array([0.8, 0.0, 0.3])
    r = s.find_path(a, b)
    assert r.complete
    assert not segments_cross_wall(r.points)
    assert max(p[2] for p in r.points) > 0.7 + R * 0.9  # around the end of the wall
    assert r.length > np.linalg.norm(b - a) + 0.5
    assert path_on_surface(s, r.points)
    # no sample within the radius of the wall's face
    near = (np.abs(s.positions[:, 0] - 0.503) < R - 1e-6) & (s.positions[:, 2] < 0.7)
    assert not near.any()


def test_gap_is_not_crossed():
    s = build(env_of(floor(0.0, 0.45), floor(0.55, 1.0)), AGENT)
    r = s.find_path([0.2, 0.0, 0.5], [0.8, 0.0, 0.5])
    assert not r.complete
    assert np.all(r.points[:, 0] < 0.45)
    assert r.points[-1][0] > 0.35  # got as close as it could
    assert s.component_of([0.2, 0, 0.5]) != s.component_of([0.8, 0, 0.5])
    rng = np.random.default_rng(1)
    for _ in range(50):
        q = s.random_point_near([0.4, 0.0, 0.5], 0.3, rng)
        assert q is not None and q[0] < 0.45


@pytest.mark.parametrize("flip", [False, True])
def test_hollow_half_log(flip):
    log = half_log()
    s = build(env_of(floor(0.0, 1.0, -0.3, 1.3), log, flip=flip), AGENT)
    # top of the log and the floor inside it are both walkable; the shell's inside is not
    assert s.is_walkable([[0.5, 0.2, 0.5]])[0]
    assert s.is_walkable([[0.5, 0.0, 0.5]])[0]
    inside_floor = s.component_of([0.5, 0.0, 0.5])
    assert s.component_of([0.5, 0.2, 0.5]) != inside_floor
    top = s.nearest([0.5, 0.19, 0.5])
    assert abs(top[1] - 0.2) < 2e-3
    # inside floor and outside floor connect through the open ends, not through the shell
    assert s.component_of([0.05, 0.0, 0.5]) == inside_floor
    r = s.find_path([0.5, 0.0, 0.5], [0.1, 0.0, 0.5])
    assert r.complete
    assert r.points[:, 2].max() > 0.9 - R or r.points[:, 2].min() < 0.1 + R
    assert path_on_surface(s, r.points)
    # no walkable sample inside the solid shell
    p = s.positions
    rr = np.hypot(p[:, 0] - 0.5, p[:, 1])
    inshell = (rr > 0.16 + 1e-3) & (rr < 0.2 - 1e-3) & (p[:, 2] > 0.1) & (p[:, 2] < 0.9)
    assert not inshell.any()


def test_bridge_over_road_two_layers():
    s = build(bridge_scene(), AGENT)
    road = s.find_path([0.05, 0.0, 0.5], [0.95, 0.0, 0.5])
    assert road.complete and np.all(np.abs(road.points[:, 1]) < 1e-6)
    deck = s.find_path([0.5, 0.3, 0.05], [0.5, 0.3, 0.95])
    assert deck.complete and np.all(np.abs(deck.points[:, 1] - 0.3) < 1e-6)
    assert s.component_of([0.5, 0.0, 0.5]) != s.component_of([0.5, 0.3, 0.5])
    assert abs(s.nearest([0.5, 0.29, 0.5])[1] - 0.3) < 1e-6
    assert abs(s.nearest([0.5, 0.02, 0.5])[1]) < 1e-6
    under = np.array([[0.5, 0.0, 0.5], [0.5, 0.3, 0.5]])
    assert s.is_walkable(under).all()
    # the column under the bridge holds both layers
    ix, iz = 50, 50
    c = ix * s.shape[1] + iz
    assert s.col_start[c + 1] - s.col_start[c] == 2


def test_no_walkable_surface_raises():
    wall = quad((0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1))
    with pytest.raises(NavError, match="no walkable surface"):
        build(env_of(wall), AGENT)
    with pytest.raises(NavError, match="no walkable surface"):
        build(env_of(floor(0, 0.05, 0, 0.05)), AGENT)  # narrower than the agent


def test_links_are_symmetric_and_components_consistent():
    s = build(env_of(floor(), half_log(), box((0.1, 0, 0.1), (0.2, 0.04, 0.2))), AGENT)
    from baker.navmesh.surface import OPPOSITE

    src, d = np.nonzero(s.links >= 0)
    dst = s.links[src, d]
    assert np.all(s.links[dst, OPPOSITE[d]] == src)
    assert np.all(s.component[src] == s.component[dst])
    assert np.all(np.diff(s.component_area) <= 0)
    assert np.all(s.normals[:, 1] >= math.cos(AGENT.max_slope) - 1e-6)


@pytest.mark.parametrize("deg", [0.0, 30.0, 45.0])
def test_erosion_keeps_the_radius_from_slanted_walls(deg):
    """A tall thin wall at any angle: no sample closer than about the radius to its plane."""
    a = math.radians(deg)
    d = np.array([math.cos(a), 0.0, math.sin(a)])
    c = np.array([0.5, 0.0, 0.5])
    p0, p1 = c - 0.6 * d, c + 0.6 * d
    wall = quad(p0, p0 + [0, 0.3, 0], p1 + [0, 0.3, 0], p1)
    s = build(env_of(floor(-0.2, 1.2, -0.2, 1.2), wall), AGENT)
    n = np.array([-d[2], 0.0, d[0]])
    q = s.positions.astype(float) - c
    along = q @ d
    perp = np.abs(q @ n)
    mid = np.abs(along) < 0.5  # away from the wall's ends
    assert perp[mid].min() >= R - 0.2 * CELL
