"""The straight line the body lies on at the start (run.loop.start_line): long enough that the
trail's rounding, which pulls a line's ends in, never leaves the tail short of trail at frame 0
(a tail clamped to the trail's start breaks the spine spacing for the first frames)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.context import Context
from baker.navmesh import build
from baker.sim.loop import simulate
from baker.streams import Streams
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
RIG = replace(RIG, legs=replace(RIG.legs, enabled=False))


def test_the_trail_reaches_well_behind_the_tail_at_the_start():
    env = env_of(floor(-1.0, 1.0, -1.0, 1.0))
    nav = build(env, RIG.navigation)
    cfg = BakeConfig(seconds=1.0, prey=0, rig=RIG, behaviour="wander", start=(0.3, 0.0, 0.0),
                     start_heading=(1.0, 0.0, 0.0))
    traj = simulate(cfg, env, nav, Streams(5), Context())
    body = RIG.body
    # the tail's arc at frame 0 is at least two spacings into the trail
    assert traj.head_arc[0] - body.length >= 2.0 * body.spacing, traj.head_arc[0]
    sp = traj.spine_positions
    err = np.abs(np.linalg.norm(np.diff(sp, axis=1), axis=2) / body.spacing - 1.0)
    assert err.max() <= 0.02, (err.max(), np.unravel_index(err.argmax(), err.shape))
