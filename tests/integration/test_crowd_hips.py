"""A multi-storey crowd whose creature turned its hips over a platform the trail never saw
(solve.solve raises the trail under placed hips: tests/unit/test_hip_clearance.py).

`baker bake environments/multistorey.glb --scale 8 --creatures 8 --prey 0 --seconds 30
--seed 114500`: creature 6 turned tightly beside a 0.18 m platform on the upper floor, and two
of its left hips sank 2 mm into the platform's top corner (leg_bone_hits 2, frames 873 and 881),
where no knee swivel could clear the bones. Every creature's leg bones now stay out of the
level.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from baker.config import BakeConfig, DEFAULT_RIG, load_rig_config, scale_rig
from baker.context import Context
from baker.environment import load_environment
from baker.metrics import leg_metrics
from baker.pipeline import in_local_frame, navigation_surface
from baker.run.crowd import run_crowd
from baker.solve.solve import solve

REPO = Path(__file__).resolve().parents[2]
RIG = scale_rig(load_rig_config(DEFAULT_RIG), 8.0)

pytestmark = pytest.mark.slow


def test_a_tight_turn_beside_a_platform_keeps_every_leg_bone_out(nav_cache_dir, tmp_path):
    cfg = BakeConfig(environment=REPO / "environments" / "multistorey.glb", seconds=30.0, seed=114500,
                     creatures=8, prey=0, workers=1, rig=RIG, out=tmp_path / "x",
                     nav_cache_dir=nav_cache_dir)
    env = load_environment(cfg.environment)
    cfg = in_local_frame(cfg, env.origin)
    nav, _ = navigation_surface(cfg, env)
    recs, _ = run_crowd(cfg, env, nav, cfg.seed, cfg.creatures, Context(), workers=1)
    lg = RIG.legs
    for i in (6, 0):
        traj = solve(recs[i], env.rays, RIG)
        m = leg_metrics(traj, env.rays, lg, spacing=RIG.body.spacing,
                        body_length=RIG.body.length,
                        lag_setting_deg=360.0 * lg.waves / (RIG.body.segments - 1),
                        max_speed=RIG.locomotion.max_speed)
        assert m["leg_bone_hits"] == 0, (i, m["leg_bone_hits"])
        assert m["foot_penetration_max_pct_bl"] < 0.5
