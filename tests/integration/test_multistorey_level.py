"""The generated multi-storey level environments/multistorey.glb (issue 10): its geometry, and
the navigation surface of the 2 m rig (the default rig at --scale 8: agent radius 0.16 m,
height 0.4 m, riser 0.2 m, cell 0.12 m) over it: rooms joined through their doorways, both
floors joined by the staircase (0.18 m risers) and by the ramp, the passage under the bridge,
the hollow log walkable inside and on top, wander targets spread over both floors by area.

Probe points are world coordinates read off environments/make_multistorey.py.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

from baker.behaviour import perception
from baker.config import DEFAULT_RIG, load_rig_config, scale_rig
from baker.environment import load_environment
from baker.navmesh import build

REPO = Path(__file__).resolve().parents[2]
GLB = REPO / "environments" / "multistorey.glb"
GENERATOR = REPO / "environments" / "make_multistorey.py"
RIG = scale_rig(load_rig_config(DEFAULT_RIG), 8.0)
UPPER_Y = 3.6   # [m] top of the upper floor
ROOF_Y = 6.9    # [m] top of room D's roof: not reachable

#: name -> world point on the walkable surface, all in the main component
PROBES = {
    "room A": (5.0, 0.0, 6.0), "room B": (15.0, 0.0, 6.0),
    "doorway A-B (arch)": (10.0, 0.0, 6.0), "doorway A-hall (lintel)": (7.0, 0.0, 12.0),
    "doorway B-hall (arch)": (17.5, 0.0, 12.0), "doorway B-yard (lintel)": (20.0, 0.0, 9.0),
    "hall": (8.0, 0.0, 20.0), "yard": (26.0, 0.0, 8.0),
    "passage under the bridge": (13.25, 0.0, 15.0),
    "inside the log": (25.5, 0.0, 19.5), "on the log": (25.5, 0.854, 19.5),
    "staircase": (2.25, 1.8, 15.75), "ramp": (24.7, 1.8, 2.5),
    "terrace C": (5.0, UPPER_Y, 6.0), "room D": (15.0, UPPER_Y, 6.0),
    "doorway C-D (arch)": (10.0, UPPER_Y, 4.0), "bridge": (13.25, UPPER_Y, 15.0),
    "tower": (13.25, UPPER_Y, 20.5),
}
STAIR_FOOT = (2.25, 0.0, 20.0)
STAIR_TOP = (2.25, UPPER_Y, 10.0)


@pytest.fixture(scope="session")
def generator():
    spec = importlib.util.spec_from_file_location("make_multistorey", GENERATOR)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def level():
    return load_environment(GLB)


@pytest.fixture(scope="session")
def level_nav(level):
    """The 2 m rig's navigation surface over the level (built once per session)."""
    return build(level, RIG.navigation)


def test_generator_rewrites_the_committed_file_byte_for_byte(generator):
    data = generator.build_glb(generator.make_multistorey())
    assert data == GLB.read_bytes()
    assert len(data) < 1_000_000


def test_parts_are_closed_outward_solids_sharing_no_vertex(generator):
    parts = generator.make_multistorey()
    owner = {}
    for i, p in enumerate(parts):
        m = trimesh.Trimesh(p.vertices, p.faces, process=True)
        assert m.is_watertight and m.is_winding_consistent and m.volume > 0, p.name
        for v in {tuple(np.round(x, 6)) for x in p.vertices}:
            assert owner.setdefault(v, i) == i, (p.name, parts[owner[v]].name, v)


def test_staircase_has_human_risers_and_treads(generator):
    p = next(p for p in generator.make_multistorey() if p.name == "stairs")
    v, f = p.vertices, p.faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    tops = np.unique(np.round(v[f[n[:, 1] > 0][:, 0], 1], 6))
    assert np.allclose(np.diff(np.r_[0.0, tops]), 0.18, atol=1e-4)
    assert tops[-1] == pytest.approx(UPPER_Y - 0.18, abs=1e-4)  # the last riser meets the floor
    z = np.unique(np.round(v[:, 2], 6))
    assert np.allclose(np.diff(z), 0.35, atol=1e-4)


def test_rooms_doorways_and_both_floors_are_one_component(level, level_nav):
    s = level_nav
    for name, p in PROBES.items():
        q = level.to_local(p)
        assert s.is_walkable(q[None], tol=0.05)[0], name
        assert s.component_of(q) == 0, name
    # everything below the roof is the main component: the roof is the only unreachable bit
    y = s.positions[:, 1] + level.origin[1]
    assert np.all(s.component[y < ROOF_Y - 0.5] == 0)
    assert s.component_area[0] / s.component_area.sum() > 0.85


def test_staircase_joins_the_floors(level, level_nav):
    """The 0.18 m risers are climbed: the path from the foot of the stairs to the terrace goes
    up the flight (the way round by the ramp is over 40 m)."""
    r = level_nav.find_path(level.to_local(STAIR_FOOT), level.to_local(STAIR_TOP))
    assert r.complete and r.length < 13.0
    assert np.all((r.points[:, 0] > 0.9) & (r.points[:, 0] < 3.6))


def test_risers_above_the_limit_are_not_climbed(level):
    """With a riser limit below the stairs' 0.18 m, the way up is the ramp."""
    s = build(level, replace(RIG.navigation, step_height=0.9 * 0.18))
    r = s.find_path(level.to_local(STAIR_FOOT), level.to_local(STAIR_TOP))
    assert r.complete and r.length > 40.0


def test_wander_targets_reach_the_upper_floor_by_its_share_of_area(level, level_nav):
    """Wander targets (the wander radius, 40 m, holds the whole level) fall on the upper floor
    as often as its share of the reachable surface area."""
    s = level_nav
    main = s.component == 0
    area = s.cell_size ** 2 / s.normals[:, 1].astype(np.float64)
    upper = s.positions[:, 1] + level.origin[1] > UPPER_Y - 0.5
    share = area[main & upper].sum() / area[main].sum()
    assert 0.2 < share < 0.35
    rng = np.random.default_rng(10)
    start = level.to_local(PROBES["hall"])
    q = np.array([s.random_point_near(start, RIG.wander.radius, rng) for _ in range(2000)])
    frac = np.mean(q[:, 1] + level.origin[1] > UPPER_Y - 0.5)
    assert abs(frac - share) < 0.04  # 4 standard deviations


@pytest.mark.parametrize("a, b, expected", [
    ("room A", "terrace C", True), ("terrace C", "yard", True), ("hall", "tower", True),
    ("room D", "inside the log", True), ("yard", "ramp", False), ("hall", "on the log", False),
    ("room A", "yard", False), ("terrace C", "bridge", False)])
def test_a_wander_target_on_the_other_floor_is_a_journey(level, level_nav, a, b, expected):
    """Up to the terrace or the tower (only reached over the bridge), or down from the upper
    floor: a journey. Half-way up the ramp, onto the log, or on the same floor: not one."""
    got = perception.on_another_floor(level_nav, level.to_local(PROBES[a]),
                                      level.to_local(PROBES[b]), RIG.wander.journey_rise)
    assert got is expected


# --------------------------------------------------------------------------- a bake over it
@pytest.fixture(scope="module")
def climb(tmp_path_factory, nav_cache_dir):
    """A 120 s wander bake of the 2 m rig from the foot of the staircase, judged from its GLB."""
    from baker.config import BakeConfig
    from baker.inspect import judge, read_glb
    from baker.pipeline import bake

    out = tmp_path_factory.mktemp("climb") / "ms"
    bake(BakeConfig(environment=GLB, seconds=120.0, seed=2, rig=RIG, out=out, formats=("glb",),
                    nav_cache_dir=nav_cache_dir, start=STAIR_FOOT, behaviour="wander", prey=0))
    scene = read_glb(out.with_suffix(".glb"))
    return scene, judge(scene)["metrics"]


@pytest.mark.slow
def test_a_bake_visits_both_floors_and_climbs_the_staircase(climb):
    scene, m = climb
    head = scene.positions[:, scene.index("head")]
    assert np.count_nonzero(head[:, 1] < 0.5) > 0 and np.count_nonzero(head[:, 1] > UPPER_Y - 0.3) > 0
    on_stairs = ((head[:, 0] > 1.0) & (head[:, 0] < 3.5) & (head[:, 2] > 10.0) & (head[:, 2] < 20.0)
                 & (head[:, 1] > 0.5) & (head[:, 1] < UPPER_Y - 0.3))
    assert np.count_nonzero(on_stairs) > 120            # four seconds on the flight, between floors
    # the head climbs: its height rises across the flight
    z_on = head[on_stairs]
    assert np.corrcoef(z_on[:, 2], z_on[:, 1])[0, 1] < -0.9     # higher toward the top (-z)
    # the skate and rotation limits hold, judged from the file
    assert m["skate_median_pct_bl"] < 0.2 and m["skate_ratio"] < 0.02
    assert m["rotation_max_deg"] < 30.0


@pytest.mark.slow
def test_feet_and_leg_bones_stay_out_of_the_steps(climb):
    _, m = climb
    assert m["foot_penetration_max_pct_bl"] < 0.5 and m["leg_bone_hits"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_a_default_bake_visits_both_floors(seed, nav_cache_dir, tmp_path):
    """`baker bake environments/multistorey.glb --scale 8 --seconds 120 --seed S`: from the
    default start (on either floor), with shade, rest and the d10 as they are, the head spends
    more than 2 % of the frames on each floor: a wander target on the other floor is a journey
    that the d10 does not cut short. (Legs off, for speed: the head's path is the same.)"""
    from baker.config import BakeConfig
    from baker.pipeline import bake

    rig = replace(RIG, legs=replace(RIG.legs, enabled=False))
    r = bake(BakeConfig(environment=GLB, seconds=120.0, seed=seed, rig=rig, prey=0,
                        out=tmp_path / "ms", formats=("glb",), nav_cache_dir=nav_cache_dir))
    y = r.trajectory.spine_positions[:, 0, 1] + r.origin[1]
    assert np.mean(y < 0.5) > 0.02 and np.mean(y > UPPER_Y - 0.4) > 0.02
    assert any(e["details"].get("journey") for e in r.report["timeline"])


@pytest.mark.slow
def test_a_crowd_s_legs_are_planned_again_until_no_stance_is_stuck(nav_cache_dir, tmp_path):
    """A crowd of 6 for 40 s, seed 14190077 (as benchmarks/quality_sweep.py bakes it): one
    creature's foot, lifted from under a step's edge (legs._lift_stuck), landed under it again,
    and the third planning round, then the last, left its tip bone through the step in 2
    frames of the files. The legs are planned again until no stance is shortened: every
    creature's leg bones stay out of the level, judged from the GLB."""
    from baker.config import BakeConfig
    from baker.inspect import judge_creatures
    from baker.pipeline import bake

    out = tmp_path / "crowd"
    bake(BakeConfig(environment=GLB, seconds=40.0, fps=30, seed=14190077, rig=RIG, out=out,
                    formats=("glb",), nav_cache_dir=nav_cache_dir, prey=0, creatures=6,
                    workers=1))
    hits = [r["metrics"]["leg_bone_hits"] for r in judge_creatures(out.with_suffix(".glb"))]
    assert hits == [0] * 6, f"leg bone hits per creature {hits}"
