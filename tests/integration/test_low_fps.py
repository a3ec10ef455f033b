"""A bake at a low export rate meets the per-frame limits (locomotion.legs._turn_limited_antenna).

`baker bake environments/multistorey.glb --scale 8 --fps 12 --seconds 3 --seed 115912`: the
antennae's sweep is timed in seconds, and at 12 fps it added to the head's turn between frames:
antenna_L_2 turned 35.1 degrees in frame 13, where the limit is 30. Every limit is judged from
the files (the GLB and the USD).
"""

from __future__ import annotations

from pathlib import Path

from baker.config import BakeConfig, DEFAULT_RIG, load_rig_config, scale_rig
from baker.context import Context
from baker.inspect import failures, judge_creatures
from baker.pipeline import bake

REPO = Path(__file__).resolve().parents[2]


def test_antennae_turn_within_the_limit_at_12_fps(nav_cache_dir, tmp_path):
    cfg = BakeConfig(environment=REPO / "environments" / "multistorey.glb", seconds=3.0, fps=12,
                     seed=115912, rig=scale_rig(load_rig_config(DEFAULT_RIG), 8.0),
                     out=tmp_path / "c", nav_cache_dir=nav_cache_dir)
    res = bake(cfg, ctx=Context())
    (judged,) = judge_creatures(res.outputs["glb"], res.outputs["usd"])
    m = judged["metrics"]
    assert m["rotation_world_antennae_deg"] < 27.0, judged["worst"].get("rotation_max_deg")
    assert failures(m) == [], failures(m)
