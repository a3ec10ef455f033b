"""Loop planning, the seam measures, residual distribution and blending (baker.cycles.looping),
whole-cycle chain frequencies and the scripted intent, on small clips built in code."""

from __future__ import annotations

import math

import numpy as np
import pytest

from baker.behaviour.brain import Senses
from baker.behaviour.script import Drive, ScriptedIntent
from baker.clip import Clip, times_for
from baker.cycles import looping
from baker.locomotion.legs import whole_cycles

PARENTS = np.array([-1, 0, 1])       # root -> body -> tip


def circling(n_frames: int, period: float, fps: int = 30, phase: float = 0.0,
             drift: float = 0.0) -> Clip:
    """A root walking along +Z at 0.2 m/s; its child sways (period [frames]) and its tip
    circles; `drift` [m] adds a slow non-periodic offset to the child."""
    f = np.arange(n_frames, dtype=np.float64)
    a = 2.0 * math.pi * f / period + phase
    t = np.zeros((n_frames, 3, 3))
    t[:, 0, 2] = 0.2 * f / fps
    t[:, 1] = np.stack([0.02 * np.sin(a), 0.01 + 0.0 * a, drift * f / n_frames], 1)
    t[:, 2] = [0.0, 0.0, 0.05]
    q = np.zeros((n_frames, 3, 4))
    q[..., 3] = 1.0
    q[:, 2, 1], q[:, 2, 3] = np.sin(0.25 * a), np.cos(0.25 * a)   # the tip turns about +Y
    return Clip(name="c", times=times_for(n_frames, fps), translations=t.astype(np.float32),
                rotations=q.astype(np.float32), scales=np.ones((n_frames, 3, 3), np.float32),
                fps=fps)


def test_plan_window_fits_whole_cycles():
    slither, gait = 1.0 / 1.5708, 1.0 / 0.3727            # Hz: the default walk's rates
    w = looping.plan_window((slither, gait), 30, 2.0, 10.0, tol=0.01)
    assert w.worst() <= 0.01
    for count, rate, scale in zip(w.counts, (slither, gait), w.scales):
        assert count == pytest.approx(rate * scale * w.frames / 30, abs=1e-9)
        assert count >= 1
    # no window fits within 1e-6: the smallest nudge is taken
    w2 = looping.plan_window((0.3,), 30, 2.0, 2.1, tol=1e-6)
    assert w2.frames in range(60, 64)


def test_plan_window_extra_rates_only():
    w = looping.plan_window((), 30, 2.0, 10.0, extra=(1.3, 0.65), extra_tol=0.05)
    t = w.frames / 30
    for r in (1.3, 0.65):
        assert abs(round(r * t) / (r * t) - 1.0) <= 0.05


def test_whole_cycles():
    assert whole_cycles(1.3, None) == 1.3
    assert whole_cycles(1.3, 3.0) == pytest.approx(4.0 / 3.0)
    assert whole_cycles(0.1, 3.0) == 0.0


def test_periodic_clip_has_no_seam_and_matching_velocities():
    full = circling(64, 20.0)                     # frames -1 .. 61: a window of 60 frames
    loop = full.segment(1, 62, "c")               # keys 0..60: three periods
    assert looping.seam_error(PARENTS, loop.translations, loop.rotations) < 1e-6
    v = looping.seam_velocity(PARENTS, (loop.translations, loop.rotations),
                              (full.translations[:63], full.rotations[:63]))
    assert v["velocity_mismatch"] < 1e-4 and v["joint_velocity_mismatch"] < 1e-4


def test_a_wrong_window_shows_at_the_seam():
    full = circling(64, 23.0)                     # 60 frames are not whole periods
    loop = full.segment(1, 62, "c")
    assert looping.seam_error(PARENTS, loop.translations, loop.rotations) > 1e-3
    closed = looping.close_loop(loop)
    assert looping.seam_error(PARENTS, closed.translations, closed.rotations) < 1e-6
    v = looping.seam_velocity(PARENTS, (closed.translations, closed.rotations),
                              (full.translations[:63], full.rotations[:63]))
    assert v["velocity_mismatch"] > 0.02


def test_close_loop_distributes_a_residual_linearly():
    full = circling(64, 20.0, drift=0.001)
    loop = full.segment(1, 62, "c")
    closed = looping.close_loop(loop)
    d = closed.translations.astype(np.float64) - loop.translations
    # the child loses f / N of the 1 mm drift; the root's motion is untouched
    assert np.allclose(d[:, 0], 0.0)
    n = loop.n_frames - 1
    ramp = (np.arange(n + 1) / n)[:, None]
    expected = -(loop.translations[-1, 1] - loop.translations[0, 1]) * ramp
    assert np.allclose(d[:, 1], expected, atol=1e-6)
    assert np.array_equal(closed.rotations[-1, 1:], closed.rotations[0, 1:])


def test_start_at_origin_keeps_the_pose():
    clip = circling(30, 20.0)
    moved = looping.start_at_origin(clip.segment(5, 30, "c"))
    assert np.allclose(moved.translations[0, 0], 0.0, atol=1e-7)
    a = looping.root_relative(PARENTS, clip.translations[5:], clip.rotations[5:])
    b = looping.root_relative(PARENTS, moved.translations, moved.rotations)
    assert np.allclose(a, b, atol=1e-6)


def test_blend_weights_and_blend():
    w = looping.blend_weights(40, 10)
    assert w[0] == 0.0 and w[-1] == 0.0 and w[20] == 1.0
    assert np.abs(np.diff(w)).max() <= 1.5 / 10 + 1e-12
    a, b = circling(40, 20.0), circling(40, 20.0, phase=1.0)
    out = looping.blend(a, b, w)
    assert np.array_equal(out.translations[:, 0], b.translations[:, 0])   # the root: b's
    assert np.allclose(out.translations[[0, -1], 1:], a.translations[[0, -1], 1:])
    assert np.allclose(out.translations[20, 1:], b.translations[20, 1:])


def test_scripted_intent_plays_its_drives():
    route = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 5.0]])
    it = ScriptedIntent([Drive(1.0, "strike", ahead=0.1, speed_scale=2.0, cobra=1.0),
                         Drive(0.0, "walk", route=route), Drive(2.0, "idle", halt=True)])
    head, fwd = np.array([1.0, 0.0, 2.0]), np.array([0.0, 0.0, 1.0])
    seen = []
    for t in (0.0, 0.5, 1.0, 1.5, 2.0):
        it.step(Senses(t, head, fwd, False))
        seen.append((it.new_target, it.halt, it.speed_scale, it.cobra))
        if t == 0.0:
            assert np.array_equal(it.route, route)
        if t == 1.0:
            assert np.allclose(it.target, [1.0, 0.0, 2.1])
    assert seen == [(True, False, 1.0, 0.0), (False, False, 1.0, 0.0), (True, False, 2.0, 1.0),
                    (False, False, 2.0, 1.0), (False, True, 1.0, 0.0)]
    events = it.finish(3.0)
    assert [(e["state"], e["start"], e["end"]) for e in events] == [
        ("walk", 0.0, 1.0), ("strike", 1.0, 2.0), ("idle", 2.0, 3.0)]
