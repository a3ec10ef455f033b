"""Far from the world origin: the bundled rainforest floor moved 10 km away bakes exactly like the
original (the simulation runs in the environment's local frame) and both files read back every
joint within 1e-5 m of the simulation's own float64 positions (float32 data relative to a
double-precision node / Xform translation). The near-origin scene reads back the same way.
The two 8 s bakes take about 10 s together, so those tests are marked slow.

Also the writers' layout with an environment origin and a placement built in code: node and
Xform translations, the prey group, the debug layer, the end joints."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from glb_read import Glb
from sweep import moved_glb
from validator import gltf_validate, issues_summary, usd_validate

from baker.config import FLOOR_ENVIRONMENT, DEFAULT_RIG, BakeConfig, load_rig_config
from baker.geometry.transforms import quat_mul, quat_rotate

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdSkel  # noqa: E402

OFFSET = np.array([10000.0, 0.0, 10000.0])
SECONDS = 8.0
# start and prey in the near scene; exact binary fractions, so world -> local is exact and the
# far bake gets bit-identical inputs
START = np.array([0.5, 0.125, 0.5])
PREY = np.array([1.0, 0.125, 1.0])


def sim_world(traj, rig, origin):
    """(F, J, 3) world positions and (F, J, 4) rotations of every joint from the simulation's
    float64 frames: spine and limbs from the trajectory, other joints (end joints, forcipules)
    rigidly from their rest pose relative to their parent; plus the environment origin."""
    skel = rig.skeleton
    f, j_count = traj.n_frames, skel.n_joints
    wt, wq = np.zeros((f, j_count, 3)), np.zeros((f, j_count, 4))
    driven = np.zeros(j_count, bool)
    wt[:, rig.spine], wq[:, rig.spine] = traj.spine_positions, traj.spine_rotations
    driven[rig.spine] = True
    for k, name in enumerate(traj.joint_names):
        j = skel.index(name)
        wt[:, j], wq[:, j], driven[j] = traj.joint_positions[:, k], traj.joint_rotations[:, k], True
    for j, p in enumerate(skel.parents):
        if not driven[j]:
            wt[:, j] = wt[:, p] + quat_rotate(wq[:, p], skel.rest_translations[j])
            wq[:, j] = quat_mul(wq[:, p], skel.rest_rotations[j])
    return wt + origin, wq


def glb_joints(path: Path, names) -> tuple[np.ndarray, np.ndarray]:
    """(F, J, 4, 4) world matrices of the named nodes read back from a GLB (float64), and the
    world matrices of every node."""
    g = Glb(path.read_bytes())
    all_names, world = g.world_matrices(0)
    return world[:, [all_names.index(n) for n in names]], world


def usd_joints(stage, n_frames: int) -> np.ndarray:
    """(F, J, 4, 4) world joint matrices from UsdSkel (skeleton space, composed with the
    Skeleton prim's local-to-world in double precision)."""
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/World/Centipede")),
                   Usd.TraverseInstanceProxies())
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Centipede/Skeleton"))
    query = cache.GetSkelQuery(skel)
    assert query.GetAnimQuery()
    out = []
    for f in range(n_frames):
        tc = Usd.TimeCode(f)
        skel_space = np.array(query.ComputeJointSkelTransforms(tc)).transpose(0, 2, 1)
        l2w = np.array(UsdGeom.Xformable(skel.GetPrim()).ComputeLocalToWorldTransform(tc)).T
        out.append(l2w @ skel_space)
    return np.array(out)


def usd_prim_world(stage, path: str, n_frames: int) -> np.ndarray:
    x = UsdGeom.Xformable(stage.GetPrimAtPath(path))
    return np.array([np.array(x.ComputeLocalToWorldTransform(Usd.TimeCode(f))).T
                     for f in range(n_frames)])


@pytest.fixture(scope="module")
def bakes(tmp_path_factory, nav_cache_dir):
    from baker.pipeline import bake

    tmp = tmp_path_factory.mktemp("far")
    far_env = moved_glb(FLOOR_ENVIRONMENT, tmp / "far_floor.glb", OFFSET)
    rig = load_rig_config(DEFAULT_RIG)
    out = {}
    for name, env, o in (("near", FLOOR_ENVIRONMENT, np.zeros(3)), ("far", far_env, OFFSET)):
        out[name] = bake(BakeConfig(environment=env, seconds=SECONDS, seed=1, rig=rig,
                                    out=tmp / name, nav_cache_dir=nav_cache_dir,
                                    start=tuple(START + o), prey_positions=(tuple(PREY + o),),
                                    # wander (the prey is there, not hunted): the timeline
                                    # holds targets, world positions to compare
                                    behaviour="wander",
                                    tolerance=0.0))        # every key: exact to the simulation
    return out


@pytest.fixture(scope="module")
def files(bakes, rig):
    """Per bake: sim reference, GLB and USD world joint matrices, prey world positions."""
    out = {}
    for name, r in bakes.items():
        n = r.trajectory.n_frames
        ref_t, ref_q = sim_world(r.trajectory, rig, r.origin)
        glb, glb_all = glb_joints(r.outputs["glb"], rig.skeleton.names)
        stage = Usd.Stage.Open(str(r.outputs["usd"]))
        doc = Glb(r.outputs["glb"].read_bytes()).doc
        prey_node = [nd.get("name") for nd in doc["nodes"]].index("prey_01")
        out[name] = dict(ref_t=ref_t, ref_q=ref_q, glb=glb, usd=usd_joints(stage, n),
                         stage=stage, doc=doc, glb_prey=glb_all[:, prey_node, :3, 3],
                         usd_prey=usd_prim_world(stage, "/World/Prey/prey_01", n)[:, :3, 3])
    return out


@pytest.mark.slow
def test_the_far_level_gets_a_local_origin_and_simulates_exactly_like_the_near_one(bakes):
    near, far = bakes["near"], bakes["far"]
    assert near.origin.tolist() == [0.0, 0.0, 0.0]
    assert far.origin.tolist() == OFFSET.tolist()
    a, b = near.trajectory, far.trajectory
    for key in ("spine_positions", "spine_rotations", "joint_positions", "joint_rotations",
                "prey_positions", "foot_contacts"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    # the navigation surface is shared: it is keyed by the local geometry
    assert far.report["navmesh_cache_hit"] is True
    assert far.report["environment"]["content_hash"] == near.report["environment"]["content_hash"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["near", "far"])
def test_joints_read_back_within_1e5_of_the_simulation(files, name):
    d = files[name]
    for fmt in ("glb", "usd"):
        err = np.abs(d[fmt][..., :3, 3] - d["ref_t"]).max()
        assert err < 1e-5, (fmt, err)
        # rotations too: the joint axes agree to float32 precision
        rot = d[fmt][..., :3, :3]
        from scipy.spatial.transform import Rotation

        want = Rotation.from_quat(d["ref_q"].reshape(-1, 4)).as_matrix().reshape(rot.shape)
        assert np.abs(rot - want).max() < 1e-5, fmt


@pytest.mark.slow
@pytest.mark.parametrize("name", ["near", "far"])
def test_glb_and_usd_agree_at_every_frame(files, name):
    d = files[name]
    assert np.abs(d["glb"] - d["usd"]).max() < 1e-4
    assert np.abs(d["glb"][..., :3, 3] - d["usd"][..., :3, 3]).max() < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("name", ["near", "far"])
def test_prey_read_back_in_world(bakes, files, name):
    r, d = bakes[name], files[name]
    want = r.trajectory.prey_positions[:, 0] + r.origin
    assert np.abs(d["glb_prey"] - want).max() < 1e-5
    assert np.abs(d["usd_prey"] - want).max() < 1e-5


@pytest.mark.slow
@pytest.mark.parametrize("name", ["near", "far"])
def test_files_validate(bakes, files, name):
    report = gltf_validate(bakes[name].outputs["glb"])
    assert issues_summary(report, 0) == []
    assert issues_summary(report, 1) == []
    assert usd_validate(files[name]["stage"]) == []


@pytest.mark.slow
def test_far_layout_translations_are_doubles_near_the_path(bakes, files):
    r, d = bakes["far"], files["far"]
    doc, stage = d["doc"], d["stage"]
    nodes = {n.get("name"): n for n in doc["nodes"]}
    place = r.clip.placement
    assert np.all(place == np.round(place))                       # whole metres
    head = d["ref_t"][:, 0]
    assert np.all(np.abs(head - place) <= 0.5 * np.ptp(head, axis=0) + 0.5)
    assert nodes["Centipede"]["translation"] == place.tolist()
    assert nodes["Prey"]["translation"] == place.tolist()
    assert nodes["Environment"]["translation"] == OFFSET.tolist()
    # float32 data stays small: root keys within the path's extent, vertices within the level's
    tracks = Glb(r.outputs["glb"].read_bytes()).animation_tracks()
    assert np.abs(tracks[("head", "translation")][1]).max() < 10.0
    for i in nodes["Environment"]["children"]:
        prim = doc["meshes"][doc["nodes"][i]["mesh"]]["primitives"][0]
        assert max(map(abs, doc["accessors"][prim["attributes"]["POSITION"]]["max"])) < 12.0
    # USD: double3 translate ops on the SkelRoot, the prey group and the environment
    for path, want in (("/World/Centipede", place), ("/World/Prey", place),
                       ("/World/Environment", OFFSET)):
        ops = UsdGeom.Xformable(stage.GetPrimAtPath(path)).GetOrderedXformOps()
        assert [op.GetOpType() for op in ops] == [UsdGeom.XformOp.TypeTranslate], path
        assert ops[0].GetPrecision() == UsdGeom.XformOp.PrecisionDouble
        assert list(ops[0].Get()) == want.tolist()
    # the environment's points are local too; world = Environment translation + points
    ground = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Environment/ground"))
    pts = np.array(ground.GetPointsAttr().Get())
    assert np.abs(pts).max() < 12.0
    l2w = np.array(ground.ComputeLocalToWorldTransform(0)).T
    np.testing.assert_array_equal(l2w[:3, 3], OFFSET)


@pytest.mark.slow
def test_report_positions_are_world(bakes):
    near, far = bakes["near"].report, bakes["far"].report
    assert far["environment"]["origin"] == OFFSET.tolist()
    np.testing.assert_allclose(np.array(far["environment"]["bounds"]),
                               np.array(near["environment"]["bounds"]) + OFFSET, atol=1e-9)
    targets = 0
    for a, b in zip(near["timeline"], far["timeline"], strict=True):
        assert a["state"] == b["state"] and a["start"] == b["start"]
        for key in ("target", "spot"):
            if a["details"].get(key) is not None:
                np.testing.assert_allclose(b["details"][key], np.add(a["details"][key], OFFSET),
                                           atol=1.5e-4)
                targets += 1
    assert targets > 0
    doc = Glb(bakes["far"].outputs["glb"].read_bytes()).doc
    assert doc["scenes"][0]["extras"]["timeline"] == far["timeline"]


@pytest.mark.slow
def test_foot_joints_sit_at_the_tip_bone_ends_in_the_files(files, rig):
    """Read back from the far GLB and USD: every foot joint is its tip bone's end (tip origin +
    tip_length along the tip's +Y) at every frame; the foot contacts name real foot joints."""
    skel = rig.skeleton
    feet = [j for j, n in enumerate(skel.names) if n.endswith("_foot")]
    assert len(feet) == 2 * (rig.config.body.segments - 1) + 2
    for fmt in ("glb", "usd"):
        m = files["far"][fmt]
        for j in feet:
            tip = m[:, skel.parents[j]]
            length = skel.rest_translations[j, 1]
            want = tip[:, :3, 3] + length * tip[:, :3, 1]
            assert np.abs(m[:, j, :3, 3] - want).max() < 1e-5
    contacts = files["far"]["doc"]["scenes"][0]["extras"]["foot_contacts"]
    assert set(contacts) == {n for n in skel.names if n.startswith("leg_") and n.endswith("_foot")}
    cd = files["far"]["stage"].GetPrimAtPath("/World").GetCustomData()
    assert {k: json.loads(v) for k, v in cd["foot_contacts"].items()} == contacts


# ----------------------------------------------------------------- writers, scenes built in code


@pytest.fixture(scope="module")
def far_scene(small_env, rig, trajectory):
    """small_env with origin (-20000, 3, 40000) (its meshes local to it) and the conftest
    trajectory (in that local frame) with two prey, as a clip with its automatic placement."""
    from baker.clip import build_clip
    from baker.environment.model import Environment

    env = Environment(meshes=small_env.meshes, sun=small_env.sun, name="far_env",
                      origin=(-20000.0, 3.0, 40000.0))
    f = trajectory.n_frames
    prey = np.stack([trajectory.spine_positions[:, 0] + [0.3, 0.0, 0.2],
                     trajectory.spine_positions[:, 5] - [0.3, 0.0, 0.1]], 1)
    traj = replace(trajectory, prey_names=("prey_01", "prey_02"), prey_positions=prey,
                   prey_rotations=np.tile([0.0, 0.0, 0.0, 1.0], (f, 2, 1)),
                   prey_visible=np.ones((f, 2), bool))
    clip = build_clip(traj, rig, origin=env.origin)
    from conftest import box_mesh

    capsule = box_mesh("cap", (0, 0, 0), (0.01, 0.01, 0.02), (1, 0, 0, 1))
    props = tuple((n, capsule.vertices, capsule.faces, (0.8, 0.2, 0.1, 1.0)) for n in traj.prey_names)
    debug = (("navmesh", np.array([[0, 0.001, 0], [0.5, 0.001, 0], [0, 0.001, 0.5]]),
              np.array([[0, 2, 1]]), (0.1, 0.6, 1.0, 0.5)),)
    return dict(env=env, traj=traj, clip=clip, props=props, debug=debug)


def test_placement_is_the_rounded_centre_of_the_head_path(far_scene, rig):
    from baker.clip import export_origin

    env, traj, clip = far_scene["env"], far_scene["traj"], far_scene["clip"]
    head = traj.spine_positions[:, 0] + env.origin
    centre = 0.5 * (head.min(0) + head.max(0))
    np.testing.assert_array_equal(clip.placement, np.floor(centre + 0.5))
    np.testing.assert_array_equal(export_origin(head), clip.placement)
    # root keys and prey keys are relative to it
    np.testing.assert_allclose(clip.translations[:, 0] + clip.placement, head, atol=1e-5)
    world, _ = clip.world(rig.skeleton.parents)
    np.testing.assert_allclose(world[:, 0], head, atol=1e-5)
    prey = {t.node: t for t in clip.tracks}["prey_01"]
    np.testing.assert_allclose(prey.translations + clip.placement,
                               traj.prey_positions[:, 0] + env.origin, atol=1e-5)
    seg = clip.segment(3, 9, "wander_00")
    np.testing.assert_array_equal(seg.placement, clip.placement)


def test_writers_place_everything_in_world(tmp_path, far_scene, rig):
    from baker.export.gltf import build_glb
    from baker.export.usd import write_usd

    env, traj, clip = far_scene["env"], far_scene["traj"], far_scene["clip"]
    scene = dict(extras={"seed": 1}, props=far_scene["props"], debug_meshes=far_scene["debug"],
                 extra_clips=(clip.segment(0, 30, "wander_00"),))
    glb_path = tmp_path / "far.glb"
    glb_path.write_bytes(build_glb(env, rig, clip, **scene))
    usd_path = tmp_path / "far.usda"
    write_usd(usd_path, env, rig, clip, fps=30, **scene)
    report = gltf_validate(glb_path)
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []
    stage = Usd.Stage.Open(str(usd_path))
    assert usd_validate(stage) == []

    g = Glb(glb_path.read_bytes())
    names, world = g.world_matrices(0)
    nodes = {n.get("name"): n for n in g.doc["nodes"]}
    roots = [g.doc["nodes"][i]["name"] for i in g.doc["scenes"][0]["nodes"]]
    assert roots == ["Environment", "Sun", "Prey", "Centipede", "centipede_mesh", "navmesh"]
    assert [g.doc["nodes"][c]["name"] for c in nodes["Prey"]["children"]] == ["prey_01", "prey_02"]
    assert not any(k in nodes["centipede_mesh"] for k in ("translation", "rotation", "scale"))
    # the debug layer and the environment sit at the environment origin, in both files
    assert nodes["navmesh"]["translation"] == env.origin.tolist()
    assert nodes["Environment"]["translation"] == env.origin.tolist()
    dbg = usd_prim_world(stage, "/World/Debug/navmesh", 1)[0]
    np.testing.assert_array_equal(dbg[:3, 3], env.origin)
    # joints and prey in world, both files, every frame
    ref, _ = sim_world(traj, rig, env.origin)
    glb = world[:, [names.index(n) for n in rig.skeleton.names]]
    usd = usd_joints(stage, clip.n_frames)
    assert np.abs(glb[..., :3, 3] - ref).max() < 1e-5
    assert np.abs(usd[..., :3, 3] - ref).max() < 1e-5
    assert np.abs(glb - usd).max() < 1e-4
    for k, name in enumerate(traj.prey_names):
        want = traj.prey_positions[:, k] + env.origin
        assert np.abs(world[:, names.index(name), :3, 3] - want).max() < 1e-5
        got = usd_prim_world(stage, f"/World/Prey/{name}", clip.n_frames)[:, :3, 3]
        assert np.abs(got - want).max() < 1e-5


def test_glb_skinned_vertices_follow_the_joints(tmp_path, far_scene, rig):
    """Skin the bind-pose mesh with the GLB's joints and inverse bind matrices (float64): the
    vertices land where the simulation's joint frames put them, 20 km from the origin."""
    from baker.export.gltf import build_glb
    from scipy.spatial.transform import Rotation

    env, traj, clip = far_scene["env"], far_scene["traj"], far_scene["clip"]
    g = Glb(build_glb(env, rig, clip, extras={}, props=far_scene["props"]))
    names, world = g.world_matrices(0)
    node = g.doc["nodes"][g.node_index("centipede_mesh")]
    skin = g.doc["skins"][node["skin"]]
    ibm = g.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    joint_world = world[:, skin["joints"]]                                  # (F, J, 4, 4)
    ref_t, ref_q = sim_world(traj, rig, env.origin)
    ref = np.zeros_like(joint_world)
    ref[..., :3, :3] = Rotation.from_quat(ref_q.reshape(-1, 4)).as_matrix().reshape(ref_t.shape + (3,))
    ref[..., :3, 3] = ref_t
    ref[..., 3, 3] = 1.0
    ref = ref @ np.linalg.inv(rig.skeleton.world_bind())
    worst = 0.0
    for prim in g.doc["meshes"][node["mesh"]]["primitives"]:
        a = prim["attributes"]
        v = np.c_[g.accessor(a["POSITION"]).astype(np.float64), np.ones(g.doc["accessors"][a["POSITION"]]["count"])]
        j = g.accessor(a["JOINTS_0"]).astype(np.int64)
        w = g.accessor(a["WEIGHTS_0"]).astype(np.float64)
        for f in (0, clip.n_frames // 2, clip.n_frames - 1):
            skin_m = np.einsum("vk,vkij->vij", w, joint_world[f][j] @ ibm[j].astype(np.float64))
            got = np.einsum("vij,vj->vi", skin_m, v)[:, :3]
            want = np.einsum("vk,vkij->vij", w, ref[f][j])
            want = np.einsum("vij,vj->vi", want, v)[:, :3]
            worst = max(worst, float(np.abs(got - want).max()))
            assert np.all(np.linalg.norm(got - env.origin, axis=1) < 5.0)
    assert worst < 1e-5, worst
