"""Judging a bake from its files (baker/inspect.py): the GLB and USD read back to the clip's own
joints, and each limit catches what it is about (a sliding foot, a foot in the ground, a joint
that flips, crowding feet, a bone through a rock, a stretched spine)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from baker.export.gltf import build_glb
from baker.export.usd import write_usd
from baker.geometry.transforms import quat_mul
from baker.inspect import failures, judge, read_glb, read_usd


@pytest.fixture(scope="module")
def clip(rig):
    """The creature on a flat sine path at its clearance, legs in their rest pose."""
    from baker.clip import build_clip
    from conftest import sine_trajectory

    traj = sine_trajectory(rig.spacing, len(rig.spine), clearance=rig.config.body.clearance,
                           bumpy=False)
    return build_clip(traj, rig)


@pytest.fixture(scope="module")
def files(tmp_path_factory, small_env, rig, clip, bake_extras):
    d = tmp_path_factory.mktemp("inspect")
    glb, usd = d / "c.glb", d / "c.usda"
    glb.write_bytes(build_glb(small_env, rig, clip, extras=bake_extras))
    write_usd(usd, small_env, rig, clip, fps=clip.fps, extras=bake_extras)
    return glb, usd


@pytest.fixture(scope="module")
def scene(files):
    return read_glb(files[0])


def test_both_files_read_back_to_the_clips_joints(files, scene, rig, clip):
    t, _ = clip.world(rig.skeleton.parents)
    assert scene.names == rig.skeleton.names
    assert np.abs(scene.positions - t).max() < 1e-5
    usd = read_usd(files[1])
    assert usd.names == scene.names and usd.n_frames == scene.n_frames
    assert np.abs(usd.positions - scene.positions).max() < 1e-5
    assert len(scene.env_faces) > 0


def test_each_limit_catches_its_fault(scene):
    # legs held in their rest pose drag their feet along the ground: that is skating
    base = judge(scene)["metrics"]
    assert set(failures(base)) == {"skate_median_pct_bl", "skate_ratio"}
    bl = base["body_length_m"]
    feet = [i for i, n in enumerate(scene.names) if n.startswith("leg_") and n.endswith("_foot")]
    lifted = scene.positions.copy()
    lifted[:, feet, 1] += 0.03 * bl                  # every foot clear of the ground: clean
    clean = replace(scene, positions=lifted)
    assert failures(judge(clean)["metrics"]) == []

    def with_joint(name, fn):
        pos = clean.positions.copy()
        j = clean.index(name)
        pos[:, j] = fn(pos[:, j])
        return judge(replace(clean, positions=pos))["metrics"]

    def slide(p):                                   # on the ground, 1 % BL a frame
        p = p.copy()
        p[:, 0] = p[0, 0] + 0.01 * bl * np.arange(len(p))
        p[:, 1] = 0.0
        return p

    assert "skate_ratio" in failures(with_joint("leg_L_05_foot", slide))
    # a foot 2 % BL into the ground (small_env's floor is y = 0)
    m = with_joint("leg_L_05_foot", lambda p: p * [1, 0, 1] - [0, 0.02 * bl, 0])
    assert "foot_penetration_max_pct_bl" in failures(m)
    # a foot on top of its neighbour's
    m = with_joint("leg_L_06_foot", lambda p: clean.positions[:, clean.index("leg_L_05_foot")])
    assert "neighbour_feet_min_spacing" in failures(m)
    # a stretched spine
    assert "spacing_error_max" in failures(with_joint("trunk_10", lambda p: p + [0, 0.3 * bl, 0]))
    # a knee pushed into the ground: its bones go through it
    m = with_joint("leg_R_07_tip", lambda p: p * [1, 0, 1] - [0, 0.05 * bl, 0])
    assert "leg_bone_hits" in failures(m)


def test_a_flipping_joint_fails_the_rotation_limit(scene):
    loc = scene.local.copy()
    j = scene.index("antenna_L_1")
    loc[5::2, j] = quat_mul(loc[5::2, j], np.array([0.0, 1.0, 0.0, 0.0]))   # 180 deg, every 2nd frame
    m = judge(replace(scene, local=loc))["metrics"]
    assert "rotation_max_deg" in failures(m) and m["rotation_local_antennae_deg"] > 90


def test_a_thin_wall_across_the_spine_is_a_spine_bone_hit(scene):
    # an open quad standing across the chord between two trunk joints at frame 0: no joint is
    # inside anything, but the body passes through the wall
    base = judge(scene)["metrics"]
    assert base["spine_bone_hits"] == 0
    a, b = (scene.positions[0, scene.index(n)] for n in ("trunk_09", "trunk_10"))
    mid, along = 0.5 * (a + b), (b - a) / np.linalg.norm(b - a)
    side = np.cross(along, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    h = 0.05 * base["body_length_m"]
    quad = np.array([mid - h * side - [0, h, 0], mid + h * side - [0, h, 0],
                     mid + h * side + [0, h, 0], mid - h * side + [0, h, 0]])
    n = len(scene.env_vertices)
    walled = replace(scene, env_vertices=np.concatenate([scene.env_vertices, quad]),
                     env_faces=np.concatenate([scene.env_faces,
                                               [[n, n + 1, n + 2], [n, n + 2, n + 3]]]))
    m = judge(walled)
    assert m["metrics"]["spine_bone_hits"] >= 1 and m["metrics"]["spine_inside_geometry"] == 0
    assert m["worst"]["spine_bone_hits"]["frame"] == 0
