"""Skeleton and procedural skinned mesh."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from baker.errors import RigError
from baker.rig import Skeleton, build_rig
from baker.rig.mesh import normalize_weights
from baker.rig.skeleton import spine_skeleton


def test_spine_names_parents_and_rest_pose(spine_rig):
    rig = spine_rig
    skel = rig.skeleton
    s = rig.config.body.segments
    assert skel.names[0] == "head"
    assert skel.names[1:] == tuple(f"trunk_{k:02d}" for k in range(1, s))
    assert skel.parents.dtype == np.int32 and skel.parents.tolist() == list(range(-1, s - 1))
    wb = skel.world_bind()
    assert wb.shape == (s, 4, 4)
    np.testing.assert_allclose(wb[:, :3, :3], np.broadcast_to(np.eye(3), (s, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(wb[:, 2, 3], -np.arange(s) * rig.config.body.spacing, atol=1e-12)
    np.testing.assert_allclose(wb[:, :2, 3], 0.0)
    assert rig.spine.tolist() == list(range(s))


def test_joint_paths_are_parent_first(rig):
    paths = rig.skeleton.joint_paths()
    assert paths[0] == "head" and paths[1] == "head/trunk_01"
    assert paths[20] == "/".join(rig.skeleton.names[:21])
    for j, p in enumerate(rig.skeleton.parents[1:], start=1):
        assert paths[j].startswith(paths[p] + "/")


def test_with_joints_appends_without_changing_existing(spine_rig):
    rig = spine_rig
    skel = rig.skeleton
    i = skel.index("trunk_05")
    more = skel.with_joints(["leg_L_05_upper", "leg_L_05_tip"], [i, skel.n_joints],
                            [[0.01, 0, 0], [0.01, 0, 0]], [[0, 0, 0, 1], [0, 0, 0, 1]])
    assert more.n_joints == skel.n_joints + 2
    np.testing.assert_allclose(more.world_bind()[: skel.n_joints], skel.world_bind())
    np.testing.assert_allclose(more.world_bind()[-1][:3, 3], [0.02, 0, -5 * rig.config.body.spacing])
    assert more.joint_paths()[-1].endswith("trunk_05/leg_L_05_upper/leg_L_05_tip")


@pytest.mark.parametrize("names,parents", [
    (("head", "head"), [-1, 0]),            # duplicate
    (("head", "bad name"), [-1, 0]),        # invalid characters
    (("head", "a"), [-1, 1]),               # parent not before child
    (("head", "a"), [0, -1]),               # root not first
])
def test_skeleton_rejects_bad_topology(names, parents):
    n = len(names)
    with pytest.raises(RigError):
        Skeleton(names=names, parents=np.array(parents), rest_translations=np.zeros((n, 3)),
                 rest_rotations=np.tile([0, 0, 0, 1.0], (n, 1)))


def test_spine_skeleton_rejects_bad_sizes():
    with pytest.raises(RigError):
        spine_skeleton(1, 0.1)
    with pytest.raises(RigError):
        spine_skeleton(5, 0.0)


def test_skin_weight_rules(rig):
    m = rig.mesh
    assert m.joints.dtype == np.uint16 and m.weights.dtype == np.float32
    assert m.joints.shape == m.weights.shape == (len(m.vertices), 4)
    assert np.all(np.abs(m.weights.sum(axis=1, dtype=np.float32) - 1) <= 2e-7)
    assert np.all(np.abs(m.weights.astype(np.float64).sum(axis=1) - 1) <= 2e-7)
    assert np.all(m.weights >= 0)
    unused = m.weights == 0
    assert np.all(m.joints[unused] == 0)
    assert int(m.joints.max()) < rig.skeleton.n_joints
    for k in range(4):
        for l in range(k + 1, 4):
            both = (m.weights[:, k] > 0) & (m.weights[:, l] > 0)
            assert not np.any(m.joints[both, k] == m.joints[both, l])


def test_skin_blends_each_segment_with_the_one_behind(rig):
    spine = set(rig.spine.tolist())
    m = rig.mesh
    body = np.unique(m.faces[m.face_material == 0])
    z = m.vertices[body, 2].astype(np.float64)
    c = -z / rig.config.body.spacing
    blended = (m.weights[body, 1] > 0.05)
    assert blended.mean() > 0.3                     # smooth blending, not rigid segments
    # the dominant joint is the segment nearest the vertex
    dom = m.joints[body, 0].astype(int)
    near = np.clip(np.rint(c), 0, rig.config.body.segments - 1).astype(int)
    assert np.all(np.abs(dom - near) <= 1)
    # every joint drives some body vertex
    assert set(np.unique(m.joints[body][m.weights[body] > 0])) == spine


def test_mesh_is_closed_and_outward(rig):
    m = rig.mesh
    for mat in range(len(m.materials)):
        used, faces = m.submesh(mat)
        t = trimesh.Trimesh(m.vertices[used].astype(np.float64), faces, process=False)
        assert t.is_watertight and t.is_winding_consistent
        assert t.volume > 0
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-6)
    # body normals point away from the spine axis
    used, _ = m.submesh(0)
    v = m.vertices[used].astype(np.float64)
    radial = v.copy()
    radial[:, 2] = 0
    side = np.linalg.norm(radial, axis=1) > 1e-4
    assert np.all(np.einsum("ij,ij->i", radial[side], m.normals[used][side]) > 0)


def test_mesh_shape_follows_the_profile(spine_rig):
    rig = spine_rig
    b = rig.config.body
    m = rig.mesh
    used, _ = m.submesh(0)
    v = m.vertices[used]
    assert np.isclose(v[:, 0].max(), max(b.width_profile), rtol=0.02)
    assert np.isclose(v[:, 1].max(), max(b.width_profile) * b.height_ratio, rtol=0.02)
    assert v[:, 2].max() > 0                                     # rounded head in front of z=0
    assert v[:, 2].min() < -(b.segments - 1) * b.spacing        # closed tail behind the last joint
    legs, _ = m.submesh(1)
    assert len(legs) > 0
    lv = m.vertices[legs]
    assert lv[:, 1].min() >= -b.clearance - 1e-6                 # stubs stay above the ground
    assert np.abs(lv[:, 0]).max() > max(b.width_profile) + 0.5 * b.leg_stub_length
    assert [n for n, _ in m.materials] == ["body", "legs"]
    np.testing.assert_allclose(m.materials[0][1], rig.config.colors.body)


def test_no_leg_stubs_when_length_is_zero(spine_rig_config):
    rig_config = spine_rig_config
    r = build_rig(replace(rig_config, body=replace(rig_config.body, leg_stub_length=0.0)))
    assert not np.any(r.mesh.face_material == 1)


def test_other_segment_counts(spine_rig_config):
    rig_config = spine_rig_config
    body = replace(rig_config.body, segments=7, width_profile=(0.01,) * 7)
    r = build_rig(replace(rig_config, body=body))
    assert r.skeleton.n_joints == 7 and r.skeleton.names[-1] == "trunk_06"
    assert int(r.mesh.joints.max()) == 6


def test_normalize_weights_merges_duplicates_and_keeps_four():
    j = np.array([[3, 3, 1, 2, 5, 0]])
    w = np.array([[0.2, 0.2, 0.1, 0.3, 0.15, 0.05]])
    jj, ww = normalize_weights(j, w)
    assert jj.tolist() == [[3, 2, 5, 1]]
    assert abs(float(ww.sum(dtype=np.float64)) - 1) <= 2e-7
    np.testing.assert_allclose(ww[0], np.array([0.4, 0.3, 0.15, 0.1]) / 0.95, rtol=1e-6)


def _end_joints(cfg):
    """{end joint: (parent, bone length)} the rig must have."""
    lg = cfg.legs
    out = {}
    for side in "LR":
        for k in range(1, cfg.body.segments):
            out[f"leg_{side}_{k:02d}_foot"] = (f"leg_{side}_{k:02d}_tip", lg.tip_length)
        out[f"ultimate_{side}_foot"] = (f"ultimate_{side}_tip", lg.ultimate_tip)
        out[f"antenna_{side}_tip"] = (f"antenna_{side}_2", lg.antenna_length)
        out[f"forcipule_{side}_end"] = (f"forcipule_{side}_tip", 0.9 * lg.forcipule_length)
    return out


def test_end_joints_names_parents_and_lengths(rig):
    skel = rig.skeleton
    ends = _end_joints(rig.config)
    assert len(ends) == 2 * (rig.config.body.segments - 1) + 6
    for name, (parent, length) in ends.items():
        j = skel.index(name)
        assert skel.names[skel.parents[j]] == parent
        assert skel.rest_translations[j].tolist() == [0.0, length, 0.0]
        assert skel.rest_rotations[j].tolist() == [0.0, 0.0, 0.0, 1.0]
    # the end joints are exactly the leaves: every other bone ends at a child joint
    leaves = {n for j, n in enumerate(skel.names) if not skel.children(j)}
    assert leaves == set(ends)
    # names are legal and unique also without regard to case
    assert len({n.lower() for n in skel.names}) == skel.n_joints


def test_feet_rest_on_the_ground_and_carry_no_weights(rig):
    skel = rig.skeleton
    cfg = rig.config
    wb = skel.world_bind()
    feet = [j for j, n in enumerate(skel.names) if n.startswith("leg_") and n.endswith("_foot")]
    np.testing.assert_allclose(wb[feet, 1, 3], -cfg.body.clearance, atol=1e-9)
    for j in feet:   # the foot is the tip bone's end: tip origin + tip_length along its +Y
        tip = wb[skel.parents[j]]
        np.testing.assert_allclose(wb[j, :3, 3], tip[:3, 3] + cfg.legs.tip_length * tip[:3, 1],
                                   atol=1e-12)
    ends = [skel.index(n) for n in _end_joints(cfg)]
    m = rig.mesh
    assert not np.isin(m.joints[m.weights > 0], ends).any()


def test_skeleton_rejects_names_equal_ignoring_case():
    with pytest.raises(RigError, match="case"):
        Skeleton(names=("head", "Head"), parents=np.array([-1, 0]),
                 rest_translations=np.zeros((2, 3)), rest_rotations=np.tile([0, 0, 0, 1.0], (2, 1)))


def test_readme_tables_match_the_schema():
    """The README's rig-key and option tables are rendered from baker/schema.py."""
    import readme_tables

    text = readme_tables.README.read_text()
    for name, body in readme_tables.tables().items():
        assert readme_tables.section(text, name) == body.strip(), (
            f"README '{name}' table is stale: run python tests/tools/readme_tables.py")


def test_a_tiny_prey_capsule_keeps_its_faces():
    """trimesh drops every face of a capsule thinner than about 1e-5 m as degenerate; a rig
    may ask for one (prey radius down to any positive BL): it is made at unit size and
    scaled, a closed capsule of the asked size."""
    from baker.rig.props import capsule_mesh

    for radius in (0.01, 1e-6, 1e-9):
        v, f = capsule_mesh(4.0 * radius, radius)
        assert len(f) >= 448 and f.max() < len(v)
        assert np.allclose(np.abs(v).max(axis=0), [radius, radius, 2.0 * radius], rtol=2e-2)
