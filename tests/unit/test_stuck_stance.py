"""A planted leg whose bones still pass through something once its knee has swivelled, or whose
bones as solved turn too fast in a frame, lifts off before that frame, and the legs are planned
again (legs._lift_stuck, walking_legs).

Multi-storey seed 111106: a foot planted on the floor beside the staircase's first step, the
body walking past it; from the frame after touchdown the knee stood over the step and no
swivel cleared it: 19 bone hits in the files."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import trimesh

from baker.environment.rays import RayCaster
from baker.geometry.ik import bone_frames
from baker.locomotion.legs import SWING_TURN, _cycles, _lift_stuck, _Steps

L1 = L2 = 0.25
TOL = 0.001


def _floor() -> RayCaster:
    return RayCaster(trimesh.Trimesh([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]],
                                     [[0, 2, 1], [0, 3, 2]], process=False))


def _frames(hip):
    """The stand-in for legs._Frames that _lift_stuck reads: the layout, hips, segment frames."""
    q = np.zeros(hip.shape[:2] + (4,))
    q[..., 3] = 1.0
    return SimpleNamespace(lay=SimpleNamespace(l1=L1, l2=L2), hip=hip, q=q)


def _stuck(rays, st, cidx, contact, hip, mid, end):
    hinge = np.broadcast_to([0.0, 0.0, 1.0], hip.shape)
    return _lift_stuck(rays, _frames(hip), st, cidx, contact, mid, end,
                       bone_frames(hip, mid, hinge), bone_frames(mid, end, hinge), TOL)


def _leg(bad_frames, F=25):
    """One leg, hip 0.1 m over the floor, foot 0.4 m out on it; the knee above the hip -> foot
    line, or (at `bad_frames`) the same distance below it, under the floor."""
    hip = np.tile([0.0, 0.1, 0.0], (F, 1, 1))
    end = np.tile([0.4, 0.0, 0.0], (F, 1, 1))
    d = end[0, 0] - hip[0, 0]
    half = 0.5 * np.linalg.norm(d)
    perp = np.array([-d[1], d[0], 0.0]) / np.linalg.norm(d)
    h = np.sqrt(L1 ** 2 - half ** 2)
    mid = np.tile(hip[0, 0] + 0.5 * d + h * perp, (F, 1, 1))
    mid[bad_frames, 0] = hip[0, 0] + 0.5 * d - h * perp
    return hip, mid, end


def test_a_stuck_stance_lifts_off_the_frame_before_and_never_before_its_touchdown():
    rays = _floor()
    st = _Steps(Ts=np.array([[0], [10], [20]]), LOs=np.array([[5], [18]]),
                xs=np.zeros((3, 1)), phase_td=np.ones((3, 1), bool))
    F = 25
    # stance 0 is stuck from its touchdown (frame 0), stance 1 from frame 13
    hip, mid, end = _leg([0, 1, 2, 13, 14, 15, 16, 17], F)
    cidx, contact = _cycles(st, F)
    assert _stuck(rays, st, cidx, contact, hip, mid, end)
    assert st.LOs[:, 0].tolist() == [0, 12]
    cidx, contact = _cycles(st, F)
    assert not _stuck(rays, st, cidx, contact, hip, mid, end)
    assert st.LOs[:, 0].tolist() == [0, 12]


def test_a_clear_stance_is_left_alone():
    st = _Steps(Ts=np.array([[0], [10], [20]]), LOs=np.array([[5], [18]]),
                xs=np.zeros((3, 1)), phase_td=np.ones((3, 1), bool))
    hip, mid, end = _leg([], 25)
    # the knee under the floor in swing frames only (6-9): not a stance's business
    hip2, mid2, end2 = _leg([6, 7, 8, 9], 25)
    cidx, contact = _cycles(st, 25)
    for h, m, e in ((hip, mid, end), (hip2, mid2, end2)):
        assert not _stuck(_floor(), st, cidx, contact, h, m, e)
        assert st.LOs[:, 0].tolist() == [5, 18]


def _swivelled(mid, hip, end, frames, degrees):
    """mid with the knee of `frames` swivelled about the hip -> foot axis by `degrees`."""
    from baker.locomotion.legs import _swivel
    out = mid.copy()
    axis = (end - hip) / np.linalg.norm(end - hip, axis=-1, keepdims=True)
    a = np.radians(degrees)
    out[frames] = _swivel(mid[frames], hip[frames], axis[frames], np.full(mid[frames].shape[:-1], a))
    return out


def test_a_planted_leg_whose_solved_knee_turns_too_fast_lifts_off_the_frame_before():
    """The stance check measures the plain IK; a knee swivel easing in as the body jumps adds
    to it (a 100-creature minute, 1781984: 26.6 deg measured, 30.49 deg in the file). Here the
    knee alone swivels SWING_TURN + 2 deg from frame 13 on: the stance ends at frame 12; a
    swivel of SWING_TURN - 2 deg is left alone."""
    st = _Steps(Ts=np.array([[0], [10], [20]]), LOs=np.array([[5], [18]]),
                xs=np.zeros((3, 1)), phase_td=np.ones((3, 1), bool))
    hip, mid, end = _leg([], 25)
    cidx, contact = _cycles(st, 25)
    # the swivelled knee stays above the floor (a turn toward +z/-z of the leg's plane)
    calm = _swivelled(mid, hip, end, slice(13, 25), SWING_TURN - 2.0)
    assert not _stuck(_floor(), st, cidx, contact, hip, calm, end)
    assert st.LOs[:, 0].tolist() == [5, 18]
    fast = _swivelled(mid, hip, end, slice(13, 25), SWING_TURN + 2.0)
    assert _stuck(_floor(), st, cidx, contact, hip, fast, end)
    assert st.LOs[:, 0].tolist() == [5, 12]
