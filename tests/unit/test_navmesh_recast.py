"""Agreement with Recast on the Recast demo level (../shared/fixtures/nav_test.obj).

Reference figures measured once with Recast 1.5.1 (Debian librecast-dev) by
benchmarks/recast_reference.cpp (RecastDemo's solo-mesh steps up to the regions: rasterize,
the three span filters, erode by the radius, regions with min area 8 x 8 cells), agent
radius 0.6 m, height 2.0 m, climb 0.9 m, slope 45 deg, cell height 0.1 m (0.05 m for cs 0.05):

    cell size   Recast walkable area   baker.navmesh (same cell)
    0.30 m      3997.98 m^2            4174.3 m^2  (+4.4 %)
    0.10 m      4261.33 m^2            4195.3 m^2  (-1.5 %)
    0.05 m      4309.23 m^2            4194.9 m^2  (-2.7 %)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from baker.config import NavAgentConfig
from baker.environment import load_environment
from baker.navmesh import build

FIXTURE = Path(__file__).resolve().parents[3] / "shared" / "fixtures" / "nav_test.obj"
RECAST_AREA = {0.3: 3997.98, 0.1: 4261.33, 0.05: 4309.23}


@pytest.mark.skipif(not FIXTURE.exists(), reason="nav_test.obj fixture not available")
def test_walkable_area_agrees_with_recast():
    env = load_environment(FIXTURE)
    agent = NavAgentConfig(radius=0.6, height=2.0, step_height=0.9,
                           max_slope=math.radians(45.0), cell_size=0.3)
    s = build(env, agent)
    assert abs(s.walkable_area / RECAST_AREA[0.3] - 1.0) < 0.10
    # several levels: the ground, the raised walkways and the ramp
    levels = np.unique(np.round(s.positions[:, 1] / 2.0))
    assert len(levels) >= 3
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = s.positions[rng.integers(s.n_samples)]
        b = s.random_point_near(a, 20.0, rng)
        r = s.find_path(a, b)
        assert r.complete
        assert s.is_walkable(r.points, tol=1e-3).all()
