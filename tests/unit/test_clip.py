"""Trajectory -> Clip: joint-local TRS."""

import numpy as np
import pytest
from conftest import sine_trajectory

from baker.clip import build_clip, sign_continuous
from baker.errors import ExportError
from baker.geometry.transforms import quat_mul
from baker.solve.trajectory import Trajectory


def test_shapes_dtypes_and_times(clip, trajectory, rig):
    f, j = trajectory.n_frames, rig.skeleton.n_joints
    assert clip.times.dtype == clip.translations.dtype == clip.rotations.dtype == np.float32
    assert clip.translations.shape == (f, j, 3) and clip.rotations.shape == (f, j, 4)
    assert clip.scales.shape == (f, j, 3) and np.all(clip.scales == 1)
    assert clip.fps == 30
    np.testing.assert_array_equal(clip.times, (np.arange(f) / 30).astype(np.float32))
    assert clip.times[0] == 0 and np.all(np.diff(clip.times) > 0)


def test_forward_kinematics_reproduces_the_trajectory(clip, trajectory, rig):
    wt, wq = clip.world(rig.skeleton.parents)
    assert np.abs(wt[:, rig.spine] - trajectory.spine_positions).max() < 1e-5
    # same rotation up to sign
    d = np.abs(np.sum(wq[:, rig.spine] * trajectory.spine_rotations, axis=-1))
    assert np.all(d > 1 - 1e-6)


def test_local_translations_are_the_bone_lengths(clip, rig):
    trunk = rig.spine[1:]
    lengths = np.linalg.norm(clip.translations[:, trunk].astype(np.float64), axis=-1)
    np.testing.assert_allclose(lengths, rig.spacing, rtol=2e-3)  # chord vs arc length
    # each trunk joint lies behind its parent, roughly along the parent's -Z (the parent looks at
    # the joint ahead of it, so the child is off its axis by the local bend angle)
    t = clip.translations[:, trunk].astype(np.float64) / rig.spacing
    assert np.all(t[..., 2] < -0.9)


def test_rotations_unit_in_float32_and_sign_continuous(clip):
    n = np.linalg.norm(clip.rotations, axis=-1)
    assert np.abs(n - 1).max() < 1e-6
    d = np.sum(clip.rotations[1:].astype(np.float64) * clip.rotations[:-1], axis=-1)
    assert np.all(d >= 0)


def test_sign_continuity_vectorized_flips():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 3, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    # a slowly turning rotation with random sign flips
    ang = np.linspace(0, 3 * np.pi, 50)
    base = np.stack([np.zeros(50), np.sin(ang / 2), np.zeros(50), np.cos(ang / 2)], -1)
    q = base[:, None, :] * rng.choice([-1.0, 1.0], size=(50, 3, 1))
    out = sign_continuous(q)
    assert np.all(np.sum(out[1:] * out[:-1], axis=-1) >= 0)
    assert np.all(out[0, :, 3] >= 0)
    np.testing.assert_allclose(np.abs(np.sum(out * q, -1)), 1.0)


def test_fps_inferred_or_given(trajectory, rig):
    c = build_clip(trajectory, rig, fps=30, name="walk_01")
    assert c.name == "walk_01" and c.fps == 30
    t60 = sine_trajectory(rig.spacing, len(rig.spine), seconds=1.0, fps=60)
    assert build_clip(t60, rig).fps == 60


def test_root_local_equals_world(clip, trajectory):
    np.testing.assert_allclose(clip.translations[:, 0], trajectory.spine_positions[:, 0], atol=1e-6)
    d = np.abs(np.sum(clip.rotations[:, 0] * trajectory.spine_rotations[:, 0], -1))
    assert np.all(d > 1 - 1e-6)


def test_rejects_bad_trajectories(trajectory, rig):
    bad = Trajectory(times=trajectory.times, spine_positions=trajectory.spine_positions[:, :5],
                     spine_rotations=trajectory.spine_rotations[:, :5],
                     head_surface_normal=trajectory.head_surface_normal,
                     ground_heights=trajectory.ground_heights[:, :5])
    with pytest.raises(ExportError):
        build_clip(bad, rig)
    pos = trajectory.spine_positions.copy()
    pos[3, 2, 1] = np.nan
    nan = Trajectory(times=trajectory.times, spine_positions=pos,
                     spine_rotations=trajectory.spine_rotations,
                     head_surface_normal=trajectory.head_surface_normal,
                     ground_heights=trajectory.ground_heights)
    with pytest.raises(ExportError):
        build_clip(nan, rig)
    with pytest.raises(ExportError):
        build_clip(trajectory, rig, name="bad name")


def test_local_rotation_composes_back(clip, trajectory, rig):
    # world(trunk_k) == world(parent) * local(trunk_k), computed independently of forward_kinematics
    w = trajectory.spine_rotations
    rebuilt = quat_mul(w[:, :-1], clip.rotations[:, rig.spine[1:]].astype(np.float64))
    d = np.abs(np.sum(rebuilt * w[:, 1:], -1))
    assert np.all(d > 1 - 1e-6)


def test_times_must_be_frames_at_the_fps(trajectory, rig):
    with pytest.raises(ExportError, match="resample"):
        build_clip(trajectory, rig, fps=24)
    odd = Trajectory(times=trajectory.times * 1.1, spine_positions=trajectory.spine_positions,
                     spine_rotations=trajectory.spine_rotations,
                     head_surface_normal=trajectory.head_surface_normal,
                     ground_heights=trajectory.ground_heights)
    with pytest.raises(ExportError):
        build_clip(odd, rig, fps=30)


def test_end_joints_sit_at_their_bone_end_in_every_frame(trajectory, rig):
    """Driven tip bones with arbitrary rotations: each end joint is posed rigidly at
    (0, length, 0) of its parent, so a foot is the tip origin + tip_length along the tip's +Y."""
    from dataclasses import replace

    from baker.geometry.transforms import quat_rotate

    skel = rig.skeleton
    rest = build_clip(trajectory, rig)
    wt, wq = rest.world(skel.parents)
    ends = [j for j, n in enumerate(skel.names) if not skel.children(j)]
    driven = sorted({int(skel.parents[j]) for j in ends})
    rng = np.random.default_rng(1)
    q = rng.normal(size=(trajectory.n_frames, len(driven), 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    traj = replace(trajectory, joint_names=tuple(skel.names[j] for j in driven),
                   joint_positions=wt[:, driven], joint_rotations=q)
    clip = build_clip(traj, rig)
    ct, cq = clip.world(skel.parents)
    for j in ends:
        p = skel.parents[j]
        k = driven.index(p)
        length = skel.rest_translations[j, 1]
        want = wt[:, p] + quat_rotate(q[:, k], np.array([0.0, length, 0.0]))
        assert np.abs(ct[:, j] - want).max() < 2e-6
        np.testing.assert_array_equal(clip.translations[:, j],
                                      np.broadcast_to(np.float32([0, length, 0]), (clip.n_frames, 3)))
        assert np.all(np.abs(clip.rotations[:, j, 3]) == 1.0)
