"""The default scene environments/showcase.glb: its generator reproduces it, it validates, its
shade, slope and upper level are what the default bake needs, and the default bake (`baker
bake` with no option) shows every behaviour within its minute."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baker.behaviour.sun import sun_path
from baker.config import DEFAULT_ENVIRONMENT, DEFAULT_RIG, BakeConfig, load_rig_config
from baker.environment import load_environment
from baker.navmesh.cache import load_or_build
from validator import gltf_validate

REPO = Path(__file__).resolve().parents[2]
GLB = REPO / "environments" / "showcase.glb"
GENERATOR = REPO / "environments" / "make_showcase.py"
#: the states the default bake's timeline must hold (issue 14), besides 5 distinct ones
REQUIRED = {"hunt", "feed", "rest_in_shade", "cobra"}


@pytest.fixture(scope="module")
def env():
    return load_environment(GLB)


@pytest.fixture(scope="module")
def nav(env, nav_cache_dir):
    return load_or_build(env, load_rig_config(DEFAULT_RIG).navigation, nav_cache_dir)[0]


def shaded_share(env, nav, sun_dir) -> float:
    """Share of the walkable area in shade: the navigation samples of the largest walkable
    component (what the creature can reach; leaf tops and the like are left out), each raised
    by the body clearance, with a ray toward the sun."""
    p = nav.positions[nav.component == 0].astype(np.float64) + [0.0, 0.0075, 0.0]
    return float(env.rays.occluded(p, np.tile(sun_dir, (len(p), 1))).mean())


def test_default_environment_is_the_showcase():
    assert Path(DEFAULT_ENVIRONMENT).resolve() == GLB.resolve()
    assert GLB.stat().st_size < 1_500_000


def test_generator_reproduces_the_file_byte_for_byte(tmp_path):
    spec = importlib.util.spec_from_file_location("make_showcase", GENERATOR)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    out = mod.write(tmp_path / "showcase.glb")
    assert out.read_bytes() == GLB.read_bytes()


def test_khronos_validator_reports_nothing():
    report = gltf_validate(GLB)
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:5]


def test_sun_turns_slowly(env):
    """The file's light turns 0.5 deg/s about +Y (its extras), 40 deg from the zenith."""
    assert env.sun.azimuth_rate == pytest.approx(math.radians(0.5))
    assert math.degrees(math.acos(env.sun.direction[1])) == pytest.approx(40.0, abs=1e-3)
    path = sun_path(None, env.sun.direction, 60.0, env.sun.azimuth_rate)
    a, b = path.at(0.0), path.at(60.0)
    assert math.degrees(math.acos(np.clip(a[[0, 2]] @ b[[0, 2]] / np.hypot(*a[[0, 2]])
                                          / np.hypot(*b[[0, 2]]), -1, 1))) == pytest.approx(30.0)
    assert a[1] == pytest.approx(b[1])


def test_shade_covers_10_to_25_percent_of_the_walkable_area(env, nav):
    """At the file's sun and at the end of the default minute (the sun turned 30 deg)."""
    path = sun_path(None, env.sun.direction, 60.0, env.sun.azimuth_rate)
    for t in (0.0, 30.0, 60.0):
        share = shaded_share(env, nav, path.at(t))
        assert 0.10 <= share <= 0.25, (t, share)


def test_walkable_features(env, nav):
    """The reachable surface spans the patch, climbs the bank's ~50 deg slope, and includes the
    big log's top (0.25 m up, reached by the ramp) and the floor inside the hollow log."""
    p = nav.positions[nav.component == 0].astype(np.float64)
    lo, hi = p.min(0), p.max(0)
    assert hi[0] - lo[0] > 5.5 and hi[2] - lo[2] > 5.5
    # the upper level: walkable samples on the big log's crest, in the main component
    top = (p[:, 0] < -0.6) & (p[:, 0] > -2.4) & (p[:, 2] < -1.4) & (p[:, 2] > -1.9)
    assert (p[top, 1] > 0.25).sum() > 200
    # the bank: a steep walkable stretch (45-60 deg) east of x = 1.7
    h = env.rays.first_hit(p[:, [0, 1, 2]] + [0.0, 0.05, 0.0], np.tile([0.0, -1.0, 0.0], (len(p), 1)))
    slope = np.degrees(np.arccos(np.clip(h.normals[h.hit, 1], -1, 1)))
    bank = p[h.hit, 0] > 1.7
    assert slope[bank].max() > 45.0
    # inside the hollow log: walkable floor with the log's shell overhead
    c, axis = np.array([0.95, 0.75]), np.array([math.cos(math.radians(80)), math.sin(math.radians(80))])
    rel = p[:, [0, 2]] - c
    along, across = rel @ axis, rel @ np.array([-axis[1], axis[0]])
    inside = (np.abs(along) < 0.5) & (np.abs(across) < 0.05) & (p[:, 1] < 0.06)
    assert inside.sum() > 20
    up = env.rays.first_hit(p[inside] + [0.0, 0.01, 0.0], np.tile([0.0, 1.0, 0.0], (inside.sum(), 1)))
    assert up.hit.all()
    assert (up.points[:, 1] - p[inside, 1]).min() > 0.05


# ------------------------------------------------------------------------ the default bake
@pytest.mark.slow
def test_default_bake_shows_every_behaviour(tmp_path, nav_cache_dir):
    """`baker bake` with no option but where to write: 60 s, 2 prey, the showcase's turning
    sun; the timeline holds at least 5 states, hunt, feed, rest_in_shade and cobra among them."""
    from baker.cli import main

    out = tmp_path / "centipede"
    assert main(["bake", "--out", str(out), "--cache-dir", str(nav_cache_dir)]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["parameters"]["seconds"] == 60.0 and report["seed"] == 0
    assert report["parameters"]["prey"] == 2
    states = {e["state"] for e in report["timeline"]}
    assert len(states) >= 5 and REQUIRED <= states, sorted(states)
    feed = [e for e in report["timeline"] if e["state"] == "feed"]
    assert feed and all(e["end"] - e["start"] > 0 for e in feed)


#: seeds 1-6: the minute's story is a roll of the dice (the d10, the wander targets, where the
#: prey hide), so it is judged over several seeds, with room for the dice: measured over seeds
#: 0-29 when this test was written, 14 show every behaviour (1 of seeds 1-6), and each required
#: state is missing from at most 7 (rest_in_shade from 3 of seeds 1-6)
STORY_SEEDS = range(1, 7)


@pytest.mark.slow
def test_other_seeds_show_every_behaviour_often(tmp_path, nav_cache_dir):
    """On other seeds some bakes show every behaviour too, and each required behaviour shows
    in a good share of them (baked without legs, which is faster: the paths then differ a
    little, as a legless creature does not slow beside walls for its folded legs)."""
    from baker.pipeline import bake

    rig = load_rig_config(DEFAULT_RIG)
    seen = []
    for seed in STORY_SEEDS:
        cfg = BakeConfig(environment=GLB, seconds=60.0, prey=2, seed=seed,
                         rig=replace(rig, legs=replace(rig.legs, enabled=False)),
                         out=tmp_path / f"c{seed}", formats=("glb",), nav_cache_dir=nav_cache_dir)
        seen.append({e["state"] for e in bake(cfg).report["timeline"]})
    n = len(seen)
    full = [len(st) >= 5 and REQUIRED <= st for st in seen]
    assert sum(full) >= 1, seen
    for state in REQUIRED:
        assert sum(state in st for st in seen) >= n // 3, (state, seen)
