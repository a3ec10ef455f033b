"""pipeline.limbs_grazed: the frames at which a limb bone as the reduced clip plays it passes
through the environment where the simulation's bone does not, so that the reduction is done
again with those joints held tight. limbs_near's offset rays missed a swinging tip bone
0.07 mm past a leaf's edge, and the reduction moved it 0.15 mm into the leaf (default scene,
seed 7281934, frame 715: one leg bone hit judged from the file)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

import baker.export.reduce as red
import baker.metrics as metrics
from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.environment.rays import RayCaster
from baker.pipeline import limbs_grazed
from baker.rig import build_rig

F = 4


@pytest.fixture(scope="module")
def setup():
    cfg = BakeConfig(rig=load_rig_config(DEFAULT_RIG))
    skel = build_rig(cfg.rig).skeleton
    J = skel.n_joints
    q = np.zeros((F, J, 4))
    q[..., 3] = 1.0
    clip = SimpleNamespace(translations=np.zeros((F, J, 3)), rotations=q)
    env = SimpleNamespace(rays=RayCaster(trimesh.creation.box((0.1, 0.1, 0.1))))  # top y=0.05
    # one tip bone across the box's top: frame 0 0.2 mm over it, frame 1 through it, frame 2
    # 0.2 mm over it, frame 3 far away
    starts, ends = np.zeros((F, 1, 3)), np.zeros((F, 1, 3))
    for f, y in enumerate((0.0502, 0.04, 0.0502, 1.0)):
        starts[f, 0], ends[f, 0] = (-0.08, y, 0.0), (0.08, y, 0.0)
    return cfg, skel, clip, env, (starts, ends, ["leg_L_01_tip"])


def _grazed(setup, monkeypatch, foot_drop: np.ndarray, keys=True, root_motion="world",
            bone=("leg_L_01_tip", "leg_L_01_foot")):
    """limbs_grazed with the reduced clip's end joint of the bone (its name, its end joint's:
    by default leg_L_01's tip bone, ending at its foot) lowered by foot_drop (F,) metres at
    each frame."""
    cfg, skel, clip, env, (starts, ends, _) = setup
    cfg = replace(cfg, root_motion=root_motion)
    monkeypatch.setattr(metrics, "limb_bones", lambda traj, legs: (starts, ends, [bone[0]]))
    t = clip.translations.copy()
    t[:, skel.index(bone[1]), 1] -= foot_drop
    monkeypatch.setattr(red, "played_joints", lambda c: (t, clip.rotations, None))
    reduced = SimpleNamespace(keys=object() if keys else None)
    return skel, limbs_grazed(cfg, skel, SimpleNamespace(), env, clip, reduced)


def test_a_bone_the_reduction_moves_into_the_environment_is_marked_on_its_joints(setup,
                                                                                  monkeypatch):
    # the foot 0.5 mm lower at every frame: frame 0 now crosses the box's top; frame 1 went
    # through it already (not the reduction's doing); frame 2 is lowered less; frame 3 is far
    skel, got = _grazed(setup, monkeypatch, np.array([0.0005, 0.0005, 0.0001, 0.0005]))
    assert got.shape == (F, skel.n_joints)
    assert np.flatnonzero(got.any(axis=1)).tolist() == [0]
    assert np.flatnonzero(got[0]).tolist() == sorted(
        [skel.index("leg_L_01_tip"), skel.index("leg_L_01_foot")])


def test_nothing_is_marked_where_the_reduced_bones_clear_as_simulated(setup, monkeypatch):
    assert _grazed(setup, monkeypatch, np.zeros(F))[1] is None
    assert _grazed(setup, monkeypatch, np.full(F, 0.0005), keys=False)[1] is None  # --tolerance 0
    # an in-place clip's joints move in its root's frame (as limbs_near: not checked)
    assert _grazed(setup, monkeypatch, np.full(F, 0.0005), root_motion="in-place")[1] is None


def test_an_antenna_bone_the_reduction_moves_into_the_environment_is_marked(setup, monkeypatch):
    # antennae are limbs too: an antenna tip 2 cm along its bone inside a wall met at a
    # grazing angle (tower-big at 8x, seed 12017432, frame 330), where the simulation's
    # antenna was clear
    skel, got = _grazed(setup, monkeypatch, np.array([0.0005, 0.0005, 0.0001, 0.0005]),
                        bone=("antenna_L_2", "antenna_L_tip"))
    assert np.flatnonzero(got.any(axis=1)).tolist() == [0]
    assert np.flatnonzero(got[0]).tolist() == sorted(
        [skel.index("antenna_L_2"), skel.index("antenna_L_tip")])


def test_limb_bones_are_the_leg_bones_then_the_antennae_along_their_own_y():
    from baker.geometry.transforms import quat_rotate

    cfg = load_rig_config(DEFAULT_RIG)
    names = ["leg_L_01_upper", "leg_L_01_tip", "antenna_L_1", "antenna_L_2"]
    rng = np.random.default_rng(3)
    q = rng.normal(size=(2, 4, 4))
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    traj = SimpleNamespace(joint_names=names, joint_positions=rng.normal(size=(2, 4, 3)),
                           joint_rotations=q, n_frames=2)
    starts, ends, got = metrics.limb_bones(traj, cfg.legs)
    assert got == ["leg_L_01_upper", "leg_L_01_tip", "antenna_L_1", "antenna_L_2"]
    assert np.allclose(starts[:, 2:], traj.joint_positions[:, 2:])
    along = quat_rotate(q[:, 2:], np.broadcast_to([0.0, cfg.legs.antenna_length, 0.0], (2, 2, 3)))
    assert np.allclose(ends[:, 2:] - starts[:, 2:], along)
    assert np.allclose(np.linalg.norm(ends[:, 2:] - starts[:, 2:], axis=2), cfg.legs.antenna_length)
