"""Issue 5: the legs' rhythm over a 10-minute bake of the bundled rainforest floor (in a file of its own,
so the suite's workers share it out with the other long bakes)."""

from __future__ import annotations

import pytest

from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, BakeConfig, load_rig_config
from simulated import simulated

pytestmark = pytest.mark.slow


def test_rhythm_holds_over_ten_minutes(nav_cache_dir):
    """Over 10 minutes the phase lag between neighbouring legs stays within 5 degrees of its
    setting (per-minute window means), and feet still do not skate (the simulation's own
    metrics: the files of a shorter bake are judged in test_legs.py)."""
    cfg = BakeConfig(environment=FLOOR_ENVIRONMENT, prey=0, seconds=600.0,
                     rig=load_rig_config(DEFAULT_RIG), nav_cache_dir=nav_cache_dir)
    _, motion = simulated(cfg)
    legs = motion["legs"]
    print("phase lag windows", legs["phase_lag_window_means_deg"])
    assert legs["phase_lag_samples"] > 10000
    assert len(legs["phase_lag_window_means_deg"]) >= 8
    assert legs["phase_lag_max_window_error_deg"] < 5.0
    assert legs["skate_frames_over_0p5pct_fraction"] < 0.02
