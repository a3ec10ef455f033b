"""Foot penetration is depth inside a solid (baker.metrics.depth_inside), the same measure for
the bake's report and for the files' judge: a surface just above a foot (under a root's arch or
a stone's lip) is not penetration."""

import numpy as np

from baker.environment.model import Environment, Sun
from baker.metrics import depth_inside
from conftest import box_mesh, flat_ground


def test_depth_counts_inside_only():
    # a 2 cm thick slab whose underside is 8 mm above the ground: a lip over the foot
    slab = box_mesh("lip", (0.0, 0.018, 0.0), (0.2, 0.01, 0.2), (0.2, 0.2, 0.2, 1.0))
    stone = box_mesh("stone", (0.6, 0.05, 0.0), (0.05, 0.05, 0.05), (0.2, 0.2, 0.2, 1.0))
    env = Environment(meshes=(flat_ground(), slab, stone), sun=Sun(direction=np.array([0, 1.0, 0])))
    pts = np.array([[0.0, 0.001, 0.0],     # on the ground under the lip
                    [0.6, 0.09, 0.0],      # 1 cm deep in the stone's top
                    [0.6, 0.05, 0.0],      # in the stone's middle: 5 cm from every face
                    [-0.6, 0.001, 0.0]])   # on open ground
    d = depth_inside(pts, env.rays, cap=0.03)
    assert d[0] == 0.0 and d[3] == 0.0
    assert abs(d[1] - 0.01) < 1e-6
    assert d[2] == 0.03                    # deeper than the cap reads as the cap
