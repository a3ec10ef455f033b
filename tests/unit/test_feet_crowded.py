"""pipeline.feet_crowded: the frames at which neighbouring walking feet come within the judged
gap plus two tolerances, held tight by the keyframe reduction (a crowd creature's feet,
simulated 0.2105 spacing apart, came 0.1946 apart in its reduced file: seed 6064489,
creature 46; its clip reduced with them held keeps 0.2105)."""

from __future__ import annotations

import numpy as np

from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.pipeline import FEET_GAP, feet_crowded
from baker.rig import build_rig
from baker.rig.limbs import leg_layout


class _Clip:
    """A clip stand-in whose world positions are given."""

    def __init__(self, world: np.ndarray):
        self._world = world
        self.n_frames = len(world)

    def world(self, parents):
        return self._world, None


def test_neighbouring_feet_within_the_gap_and_two_tolerances_are_held_tight():
    cfg = BakeConfig(rig=load_rig_config(DEFAULT_RIG))
    rig = build_rig(cfg.rig)
    skel = rig.skeleton
    feet = [skel.index(n) for n in leg_layout(cfg.rig).foot_names]   # L_01, R_01, L_02, ...
    spacing, tol = cfg.rig.body.spacing, 0.00025
    F = 6
    world = np.zeros((F, skel.n_joints, 3))
    for k, j in enumerate(feet):            # each side's feet a spacing apart along z
        world[:, j] = [(-1.0) ** k * 0.05, 0.0, (k // 2) * spacing]
    limit = FEET_GAP * spacing + 2.0 * tol
    l03, l04 = feet[4], feet[6]              # leg_L_03 and leg_L_04: neighbours on the left
    world[2, l04, 2] = world[2, l03, 2] + 0.999 * limit      # just within: held
    world[3, l04, 2] = world[3, l03, 2] + 1.001 * limit      # just beyond: free
    world[4, feet[1], :] = world[4, feet[0], :] + [0.0, 0.0, 0.1 * spacing]  # R_01 on L_01: not neighbours
    got = feet_crowded(cfg, skel, _Clip(world), tol)
    assert got.shape == (F, skel.n_joints)
    assert np.flatnonzero(got.any(axis=1)).tolist() == [2]
    assert np.flatnonzero(got[2]).tolist() == sorted([l03, l04])
    assert feet_crowded(cfg, skel, _Clip(world), 0.0) is None       # --tolerance 0: no keys
