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


def _grazed(setup, monkeypatch, foot_drop: np.ndarray, keys=True, root_motion="world"):
    """limbs_grazed with the reduced clip's foot end joint of leg_L_01 lowered by foot_drop
    (F,) metres at each frame."""
    cfg, skel, clip, env, bones = setup
    cfg = replace(cfg, root_motion=root_motion)
    monkeypatch.setattr(metrics, "leg_bones", lambda traj, legs: bones)
    t = clip.translations.copy()
    t[:, skel.index("leg_L_01_foot"), 1] -= foot_drop
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
