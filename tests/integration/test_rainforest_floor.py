"""The bundled environment environments/rainforest_floor.glb: content, determinism and the layers
a navigation surface needs (log tops above tunnels with headroom)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_ENVIRONMENT, FLOOR_ENVIRONMENT
from baker.environment import load_environment

REPO = Path(__file__).resolve().parents[2]
GLB = REPO / "environments" / "rainforest_floor.glb"
GENERATOR = REPO / "environments" / "make_rainforest_floor.py"

AGENT_HEIGHT = 0.05      # [m] headroom a 0.25 m centipede needs
MAX_SLOPE_DEG = 60.0
STEP = 0.05              # [m]


def _srgb(c):
    c = np.asarray(c, float) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.fixture(scope="module")
def env():
    return load_environment(GLB)


@pytest.fixture(scope="module")
def generator():
    spec = importlib.util.spec_from_file_location("make_rainforest_floor", GENERATOR)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _layers(env, xz: np.ndarray, top: float = 5.0, max_layers: int = 8):
    """Every surface crossed by a vertical ray at each (x, z): list of (y, normal_y) top down."""
    n = len(xz)
    origins = np.stack([xz[:, 0], np.full(n, top), xz[:, 1]], 1)
    out = [[] for _ in range(n)]
    alive = np.arange(n)
    for _ in range(max_layers):
        d = np.tile([0.0, -1.0, 0.0], (len(alive), 1))
        h = env.rays.first_hit(origins[alive], d)
        for k in np.nonzero(h.hit)[0]:
            out[alive[k]].append((h.points[k, 1], h.normals[k, 1]))
        origins[alive[h.hit]] = h.points[h.hit] - [0.0, 1e-5, 0.0]
        alive = alive[h.hit]
        if len(alive) == 0:
            break
    return out


def _log_frame(mesh):
    """(centre_xz, axis unit (2,), across unit (2,), half length) from the log's vertices."""
    xz = mesh.vertices[:, [0, 2]].astype(float)
    c = xz.mean(0)
    _, vecs = np.linalg.eigh((xz - c).T @ (xz - c))
    axis = vecs[:, 1]
    across = np.array([-axis[1], axis[0]])
    half = np.abs((xz - c) @ axis).max()
    return c, axis, across, half


def test_bundled_floor_is_small_and_not_the_default():
    """Bundled beside the default scene (environments/showcase.glb, tests/integration/
    test_showcase.py)."""
    assert Path(FLOOR_ENVIRONMENT).resolve() == GLB.resolve()
    assert Path(DEFAULT_ENVIRONMENT).resolve() != GLB.resolve()
    assert GLB.stat().st_size < 2_000_000


def test_content(env):
    names = [m.name for m in env.meshes]
    assert names[0] == "ground"
    logs = [n for n in names if n.startswith("log_")]
    assert len(logs) >= 3
    obstacles = [n for n in names if n.split("_")[0] in
                 ("rock", "stone", "twig", "slab", "stump", "block")]
    assert 24 <= len(obstacles) <= 80  # a few dozen
    lo, hi = env.bounds
    np.testing.assert_allclose(hi[[0, 2]] - lo[[0, 2]], [22.5, 22.5], atol=0.05)
    assert hi[1] - lo[1] < 2.0  # no tall trees

    ground = env.meshes[0]
    np.testing.assert_allclose(ground.color[:3], _srgb((72, 63, 57)), atol=1e-5)
    assert ground.roughness == 1.0 and ground.metallic == 0.0
    for m in env.meshes:
        if m.name.startswith("log_"):
            np.testing.assert_allclose(m.color[:3], _srgb((14, 64, 31)), atol=1e-5)


def test_ground_is_gentle(env):
    g = env.meshes[0]
    tm = trimesh.Trimesh(g.vertices, g.faces, process=False)
    slope = np.degrees(np.arccos(np.abs(tm.face_normals[:, 1])))
    assert slope.max() < 30.0
    assert 0.05 < np.ptp(g.vertices[:, 1]) < 1.0  # undulating, not flat


def test_sun_is_slightly_off_vertical(env):
    d = env.sun.direction
    zenith = math.degrees(math.acos(d[1]))
    assert 15.0 <= zenith <= 40.0
    assert np.isclose(np.linalg.norm(d), 1.0)


def test_generator_is_deterministic(generator, tmp_path):
    out = tmp_path / "floor.glb"
    generator.write(out)
    assert out.read_bytes() == GLB.read_bytes()
    parts, sun = generator.make_rainforest_floor(generator.DEFAULT_SEED)
    assert len(parts) == len(load_environment(GLB).meshes)
    other = tmp_path / "other.glb"
    generator.write(other, seed=generator.DEFAULT_SEED + 1)
    assert other.read_bytes() != GLB.read_bytes()


def test_logs_are_hollow_with_headroom(env):
    for m in (m for m in env.meshes if m.name.startswith("log_")):
        c, axis, across, half = _log_frame(m)
        s = np.linspace(-0.9 * half, 0.9 * half, 15)
        t = np.linspace(-0.08, 0.08, 9)
        S, T = np.meshgrid(s, t, indexing="ij")
        xz = c + S.reshape(-1, 1) * axis + T.reshape(-1, 1) * across
        layers = _layers(env, xz)
        for lay in layers:
            # outer top, inner ceiling, ground (at least)
            assert len(lay) >= 3, m.name
            top_y, ceiling_y, floor_y = lay[0][0], lay[1][0], lay[-1][0]
            assert lay[0][1] > math.cos(math.radians(MAX_SLOPE_DEG))  # walkable top
            assert top_y - ceiling_y < AGENT_HEIGHT  # the shell itself is no tunnel
            assert ceiling_y - floor_y >= AGENT_HEIGHT, (m.name, ceiling_y - floor_y)
            assert lay[-1][1] > 0.9  # the floor inside is the (gentle) ground


def test_logs_can_be_climbed_from_the_ground(env):
    """Across each log, the topmost surface rises from the ground with no slope over 60 deg
    and no jump over the step height between 1.5 cm samples."""
    for m in (m for m in env.meshes if m.name.startswith("log_")):
        c, axis, across, half = _log_frame(m)
        for frac in (-0.5, 0.0, 0.5):
            t = np.arange(-0.45, 0.45, 0.015)
            xz = c + frac * half * axis + t[:, None] * across
            h = env.rays.cast_down(np.stack([xz[:, 0], np.zeros(len(t)), xz[:, 1]], 1), 5.0)
            assert h.hit.all()
            y = h.points[:, 1]
            assert np.all(np.abs(np.diff(y)) <= STEP), m.name
            slope = np.degrees(np.arccos(np.clip(h.normals[:, 1], -1, 1)))
            assert slope.max() <= MAX_SLOPE_DEG + 1e-6, (m.name, slope.max())
            assert y.max() - min(y[0], y[-1]) > 0.06  # it is really on top of the log


def test_obstacles_low_and_tall(env):
    """Stones, slabs and twigs rise at most a few cm above the ground; rocks, stumps and
    blocks are tall enough to need a detour."""
    ground = env.meshes[0]
    gtm = trimesh.Trimesh(ground.vertices, ground.faces, process=False)
    from baker.environment.rays import RayCaster

    ground_rays = RayCaster(gtm)
    low, tall = 0, 0
    for m in env.meshes[1:]:
        kind = m.name.split("_")[0]
        if kind == "log":
            continue
        v = m.vertices.astype(float)
        g = ground_rays.cast_down(v, 5.0)
        rise = (v[:, 1] - g.points[:, 1])[g.hit].max()
        if kind in ("stone", "slab", "twig"):
            assert rise <= 0.05, (m.name, rise)
            low += 1
        else:
            assert rise >= 0.1, (m.name, rise)
            tall += 1
        assert (v[:, 1] < g.points[:, 1]).any(), m.name  # partly embedded
    assert low >= 10 and tall >= 10


def test_low_stones_are_walkable(env):
    """The topmost surface over each stone is at most 60 deg steep."""
    for m in (m for m in env.meshes if m.name.startswith("stone_")):
        lo, hi = m.vertices.min(0), m.vertices.max(0)
        xs = np.linspace(lo[0], hi[0], 12)
        zs = np.linspace(lo[2], hi[2], 12)
        X, Z = np.meshgrid(xs, zs)
        pts = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], 1)
        h = env.rays.cast_down(pts, 5.0)
        slope = np.degrees(np.arccos(np.clip(h.normals[h.hit, 1], -1, 1)))
        assert slope.max() <= MAX_SLOPE_DEG, (m.name, slope.max())


def test_glb_passes_the_khronos_validator():
    validator = pytest.importorskip("validator")
    report = validator.gltf_validate(GLB)
    assert report["issues"]["numErrors"] == 0, validator.issues_summary(report, 0)
    assert report["issues"]["numWarnings"] == 0, validator.issues_summary(report, 1)
