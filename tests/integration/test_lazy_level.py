"""A level too big to build whole for the default 0.25 m rig: 120 x 120 m of ground with 400
rocks, built in code. At the rig's 1.5 cm cells the whole grid would be 64 million columns
(over MAX_COLUMNS), so `--nav-build auto` builds it lazily, in windows around where the creature
goes (navmesh/lazy.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from baker.config import BakeConfig
from baker.environment import load_environment
from baker.environment.model import Environment, Sun
from baker.errors import NavError
from baker.export.gltf import build_glb
from baker.navmesh import build
from baker.navmesh.build import MAX_COLUMNS
from baker.navmesh.lazy import LAZY_ABOVE_COLUMNS, full_columns
from baker.pipeline import bake
from conftest import box_mesh, flat_ground

pytestmark = pytest.mark.slow

SIZE = 120.0


@pytest.fixture(scope="module")
def level(tmp_path_factory) -> Path:
    rng = np.random.default_rng(0)
    meshes = [flat_ground(SIZE, 60)]
    for i in range(400):
        c = rng.uniform(-0.48 * SIZE, 0.48 * SIZE, 2)
        h = rng.uniform(0.02, 0.3, 3)
        meshes.append(box_mesh(f"rock_{i}", (c[0], h[1], c[1]), (h[0] + 0.05, h[1], h[2] + 0.05),
                               (0.3, 0.3, 0.3, 1.0)))
    env = Environment(meshes=tuple(meshes), sun=Sun(direction=np.array([0.3, 0.9, 0.2]) / 0.9695))
    path = tmp_path_factory.mktemp("lazy") / "big_level.glb"
    path.write_bytes(build_glb(env, None, None, extras={}))
    return path


def run(level: Path, out: Path, cache, seconds=20.0, seed=0):
    return bake(BakeConfig(environment=level, seconds=seconds, seed=seed, out=out, prey=0,
                           formats=("glb",), nav_cache_dir=cache))


@pytest.fixture(scope="module")
def cold(level, tmp_path_factory):
    """A bake with a cold navigation cache of its own (not the session's: the tests below are
    about what the lazy windows do to a cache), and that cache."""
    tmp = tmp_path_factory.mktemp("lazy_bakes")
    return run(level, tmp / "cold", tmp / "cache"), tmp / "cache"


def test_whole_level_is_too_big_to_build_at_once(level):
    from baker.config import DEFAULT_RIG, load_rig_config

    agent = load_rig_config(DEFAULT_RIG).navigation
    env = load_environment(level)
    n = full_columns(env, agent.cell_size)
    assert n > MAX_COLUMNS and n > LAZY_ABOVE_COLUMNS
    # refused before any ray: over the memory budget here (half the RAM), or over the column
    # limit on a machine with more than ~33 GB of RAM
    with pytest.raises(NavError, match="too large|memory limit"):
        build(env, agent)
    from baker.navmesh.budget import memory_limit

    with memory_limit(1e6), pytest.raises(NavError, match="too large"):
        build(env, agent)


def test_lazy_bake_walks_the_big_level(cold):
    r, _ = cold
    windows = r.report["navmesh"]["lazy_windows"]
    assert 1 <= len(windows) <= 3
    x0, z0, x1, z1 = windows[-1]
    assert (x1 - x0) * (z1 - z0) < 0.05 * SIZE * SIZE   # a small part of the level
    m = r.report["metrics"]
    assert m["distance_walked_m"] > 2.0
    assert m["trunk_inside_geometry"] == 0
    assert m["head_off_walkable_frames"] == 0
    assert m["clearance_violations"] == 0
    # the creature stayed inside the built windows
    p = r.trajectory.spine_positions[:, 0]
    assert (p[:, 0] > x0).all() and (p[:, 0] < x1).all()
    assert (p[:, 2] > z0).all() and (p[:, 2] < z1).all()


def test_lazy_bake_is_the_same_cold_and_warm(level, cold, tmp_path):
    a, cache = cold
    b = run(level, tmp_path / "warm", cache)
    assert a.report["navmesh_cache_hit"] is False and b.report["navmesh_cache_hit"] is True
    assert a.outputs["glb"].read_bytes() == b.outputs["glb"].read_bytes()
    c = run(level, tmp_path / "none", None)
    assert c.outputs["glb"].read_bytes() == a.outputs["glb"].read_bytes()


def test_cli_full_build_of_the_big_level_is_a_user_error(level, tmp_path, capsys):
    from baker.cli import main

    out = tmp_path / "o" / "c"
    code = main(["bake", str(level), "--nav-build", "full", "--no-cache", "--seconds", "1",
                 "--out", str(out)])
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err
    assert ("too large" in lines[0] or "memory limit" in lines[0]) and "--nav-build lazy" in lines[0]
    assert not out.parent.exists() or not any(out.parent.iterdir())
    code = main(["bake", str(level), "--nav-build", "sideways", "--out", str(out)])
    assert code == 2
