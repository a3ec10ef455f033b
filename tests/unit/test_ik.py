"""Analytic two-bone IK: exact in reach, lengths preserved, smooth clamping, no flips."""

import numpy as np

from baker.geometry.ik import bone_frames, soft_clamp, two_bone_ik
from baker.geometry.transforms import quat_rotate

L1, L2 = 0.6, 0.7


def _random_problem(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    root = rng.normal(size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dist = rng.uniform(0.2, 0.95 * (L1 + L2), size=n)
    pole = rng.normal(size=(n, 3))
    return root, root + d * dist[:, None], pole


def test_reaches_targets_exactly_and_keeps_bone_lengths():
    root, target, pole = _random_problem()
    s = two_bone_ik(root, target, pole, L1, L2)
    np.testing.assert_allclose(s.end, target, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.mid - root, axis=1), L1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.end - s.mid, axis=1), L2, atol=1e-12)
    assert not s.clamped.any()


def test_knee_bends_toward_the_pole():
    root, target, pole = _random_problem(seed=1)
    s = two_bone_ik(root, target, pole, L1, L2)
    u = (target - root) / np.linalg.norm(target - root, axis=1, keepdims=True)
    perp = pole - np.sum(pole * u, 1, keepdims=True) * u
    assert np.all(np.sum((s.mid - root) * perp, 1) > 0)
    # the hinge is normal to the bend plane
    assert np.abs(np.sum(s.hinge * (s.mid - root), 1)).max() < 1e-12
    assert np.abs(np.sum(s.hinge * (s.end - s.mid), 1)).max() < 1e-12


def test_unreachable_targets_are_clamped_smoothly_along_the_line():
    d = np.linspace(0.01, 2.5 * (L1 + L2), 4001)
    target = np.stack([d, np.zeros_like(d), np.zeros_like(d)], -1)
    s = two_bone_ik(np.zeros_like(target), target, np.tile([0.0, 1.0, 0.0], (len(d), 1)), L1, L2)
    reach = np.linalg.norm(s.end, axis=1)
    assert reach.max() <= L1 + L2 + 1e-12 and reach.min() > abs(L1 - L2)
    assert np.all(np.diff(reach) >= -1e-12)                    # monotone
    slope = np.diff(reach) / np.diff(d)
    assert np.all(slope <= 1 + 1e-9) and np.abs(np.diff(slope)).max() < 0.05   # C1: no kinks
    np.testing.assert_allclose(s.end[:, 1:], 0.0, atol=1e-12)  # stays on the root-target line
    np.testing.assert_allclose(np.linalg.norm(s.mid, axis=1), L1, atol=1e-12)
    inside = (d > abs(L1 - L2) + 0.05 * (L1 + L2)) & (d < 0.96 * (L1 + L2))
    np.testing.assert_allclose(reach[inside], d[inside], atol=1e-12)


def test_soft_clamp_is_identity_inside_and_bounded_outside():
    x = np.linspace(0, 10, 1001)
    y = soft_clamp(x, 1.0, 5.0)
    assert y.min() >= 1.0 and y.max() <= 5.0
    mid = (x > 1.5) & (x < 4.7)
    np.testing.assert_allclose(y[mid], x[mid])


def test_no_flips_over_a_foot_circling_its_hip():
    # a leg's foot sweeps fore and aft, rises above its hip and drops below it: the knee and the
    # bone frames turn smoothly (the pole is across the leg, as locomotion.legs uses it)
    t = np.linspace(0, 4 * np.pi, 2000)
    hip = np.zeros((len(t), 3))
    side = np.array([1.0, 0.0, 0.0])
    fwd = np.array([0.0, 0.0, 1.0])
    foot = np.stack([0.9 + 0.2 * np.cos(3 * t), 0.5 * np.sin(2 * t), 0.6 * np.sin(t)], -1)
    u = foot / np.linalg.norm(foot, axis=1, keepdims=True)
    pole = np.cross(fwd, u) + 0.35 * side
    s = two_bone_ik(hip, foot, pole, L1, L2)
    q1 = bone_frames(hip, s.mid, s.hinge)
    q2 = bone_frames(s.mid, s.end, s.hinge)
    for q in (q1, q2):
        dots = np.abs(np.sum(q[1:] * q[:-1], -1))
        step = np.degrees(2 * np.arccos(np.clip(dots, 0, 1)))
        assert step.max() < 5.0                           # 2000 samples: no jumps anywhere
    assert np.all(s.mid[:, 1] > -0.2)                     # the knee stays up


def test_bone_frames_point_y_along_the_bone_and_x_along_the_hinge():
    root, target, pole = _random_problem(n=200, seed=3)
    s = two_bone_ik(root, target, pole, L1, L2)
    q = bone_frames(root, s.mid, s.hinge)
    y = quat_rotate(q, np.tile([0.0, 1.0, 0.0], (len(q), 1)))
    x = quat_rotate(q, np.tile([1.0, 0.0, 0.0], (len(q), 1)))
    np.testing.assert_allclose(y, (s.mid - root) / L1, atol=1e-12)
    np.testing.assert_allclose(x, s.hinge, atol=1e-12)


def test_cross_gives_numpys_bits_on_every_broadcast_shape():
    """geometry.transforms.cross (the IK's, the legs' and quat_rotate's cross product) is
    np.cross's arithmetic without its axis handling: the same bits, so bakes do not change."""
    from baker.geometry.transforms import cross

    rng = np.random.default_rng(3)
    for sa, sb in (((3,), (3,)), ((50, 3), (50, 3)), ((50, 3), (3,)), ((7, 1, 3), (5, 3)),
                   ((20, 40, 3), (20, 40, 3))):
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        out = cross(a, b)
        assert out.shape == np.cross(a, b).shape
        assert np.array_equal(out, np.cross(a, b))
    assert np.array_equal(cross([1, 0, 0], [0, 1, 0]), [0.0, 0.0, 1.0])
