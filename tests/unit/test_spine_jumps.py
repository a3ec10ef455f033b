"""metrics.spine_jumps: frames in which a spine joint moves more than JUMP spacings farther than
the head (a body whose chord placement jumps along its trail past a sharp corner)."""

import numpy as np

from baker.metrics import JUMP, spine_jumps

SPACING = 0.0125


def _walking(frames: int = 40, joints: int = 21, step: float = 0.3) -> np.ndarray:
    """A straight body walking along +Z at `step` spacings a frame (every joint with the head)."""
    z = step * SPACING * np.arange(frames)[:, None] - SPACING * np.arange(joints)[None, :]
    pos = np.zeros((frames, joints, 3))
    pos[..., 2] = z
    return pos


def test_a_body_walking_with_its_head_never_jumps():
    for step in (0.0, 0.3, 2.5):               # still, walking, a hunt's fastest frames
        frames, excess = spine_jumps(_walking(step=step), SPACING)
        assert frames == 0 and excess < 1e-9


def test_joints_jumping_along_the_trail_count_once_per_frame():
    pos = _walking()
    pos[25:, 6:, 2] += 2.0 * SPACING           # the joints behind trunk_05 jump two spacings
    pos[31:, 9:, 2] += 0.4 * SPACING           # a smaller hitch, under JUMP
    frames, excess = spine_jumps(pos, SPACING)
    assert frames == 1
    assert abs(excess - 2.0) < 1e-9
    assert 0.4 < JUMP


def test_one_frame_and_empty_trajectories():
    assert spine_jumps(np.zeros((1, 21, 3)), SPACING) == (0, 0.0)
