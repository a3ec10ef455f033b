"""`--creatures N` end to end (issue 15, crowds): a 3-creature 4 s bake on the bundled default
scene, judged from its files: the Khronos validator and UsdValidation, three skins sharing one
skinned mesh, one `bake` animation driving them all, every creature's joints read back from the
GLB and the USD agreeing (and matching the simulation within the reduction's tolerance), spines
kept apart, the report's and the files' per-creature entries; a 2-creature bake with
per-behaviour clips and in-place root motion; the option's errors on the command line and in a
jobs file."""

from __future__ import annotations

import json
import numpy as np
import pytest
from scipy.spatial.distance import cdist

from baker import batch
from baker.cli import main
from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, BakeConfig, load_rig_config
from baker.inspect import judge_creatures, read_glb, read_usd
from baker.pipeline import bake
from glb_read import Glb
from validator import gltf_validate, usd_issues, usd_validate

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdSkel  # noqa: E402

N = 3


@pytest.fixture(scope="module")
def crowd(tmp_path_factory, nav_cache_dir):
    return bake(crowd_config(tmp_path_factory.mktemp("crowd") / "crowd", nav_cache_dir, 2))


def crowd_config(out, nav_cache_dir, workers: int) -> BakeConfig:
    return BakeConfig(seconds=4.0, seed=0, creatures=N, rig=load_rig_config(DEFAULT_RIG),
                      environment=FLOOR_ENVIRONMENT, prey=0,
                      out=out, nav_cache_dir=nav_cache_dir, workers=workers)


@pytest.fixture(scope="module")
def doc(crowd):
    return Glb(crowd.outputs["glb"].read_bytes()).doc


@pytest.fixture(scope="module")
def stage(crowd):
    return Usd.Stage.Open(str(crowd.outputs["usd"]))


def test_the_glb_passes_the_khronos_validator(crowd):
    issues = gltf_validate(crowd.outputs["glb"])["issues"]
    assert issues["numErrors"] == 0, issues["messages"][:5]
    assert issues["numWarnings"] == 0, issues["messages"][:5]


def test_the_usd_passes_usd_validation(stage):
    assert usd_validate(stage) == []
    assert [(e.GetName(), e.GetMessage()) for e in usd_issues(stage)] == []


def test_three_skins_share_one_skinned_mesh(doc):
    nodes = doc["nodes"]
    skinned = [n for n in nodes if "skin" in n]
    assert len(doc["skins"]) == N and len(skinned) == N
    assert len({n["mesh"] for n in skinned}) == 1                    # one mesh, used N times
    assert sorted(n["skin"] for n in skinned) == list(range(N))
    assert [n["name"] for n in skinned] == ["centipede_mesh", "centipede_mesh_01",
                                            "centipede_mesh_02"]
    joints = [set(s["joints"]) for s in doc["skins"]]
    assert all(not (a & b) for i, a in enumerate(joints) for b in joints[i + 1:])
    by_name = {n["name"]: i for i, n in enumerate(nodes)}
    for i, top in enumerate(("Centipede", "Centipede_01", "Centipede_02")):
        prefix = "" if i == 0 else f"c{i:02d}_"
        skin = doc["skins"][i]
        assert nodes[skin["skeleton"]]["name"] == prefix + "head"
        assert nodes[by_name[top]]["children"] == [skin["skeleton"]]
    # node names unique, also without regard to case
    names = [n["name"] for n in nodes]
    assert len({n.lower() for n in names}) == len(names)


def test_one_bake_animation_drives_every_creature(doc):
    assert [a["name"] for a in doc["animations"]] == ["bake"]
    targets = {c["target"]["node"] for c in doc["animations"][0]["channels"]}
    for skin in doc["skins"]:
        assert targets & set(skin["joints"])


def test_joints_read_back_from_glb_and_usd_agree(crowd):
    starts = []
    for i in range(N):
        g = read_glb(crowd.outputs["glb"], "bake", creature=i)
        u = read_usd(crowd.outputs["usd"], creature=i)
        assert g.names == u.names and g.names[0] == "head"
        assert g.n_frames == u.n_frames == 121
        assert np.abs(g.positions - u.positions).max() <= 1e-4
        # and the simulation's own spine, within the keyframe reduction's tolerance
        traj = crowd.trajectories[i]
        sim = traj.spine_positions + crowd.origin
        tol = crowd.report["creatures"][i]["animation"]["tolerance_m"]
        assert np.abs(g.positions[:, :traj.spine_positions.shape[1]] - sim).max() <= tol + 1e-5
        starts.append(g.positions[0, 0])
    assert min(np.linalg.norm(a - b) for k, a in enumerate(starts) for b in starts[k + 1:]) > 0.05


def test_spines_keep_two_body_radii_apart(crowd):
    rig = load_rig_config(DEFAULT_RIG)
    radius = max(rig.body.width_profile)
    sp = np.stack([t.spine_positions for t in crowd.trajectories])     # (n, F, S, 3)
    n, F, S, _ = sp.shape
    own = np.repeat(np.arange(n), S)
    other = own[:, None] != own[None, :]
    gap = min(float(cdist(sp[:, f].reshape(-1, 3), sp[:, f].reshape(-1, 3))[other].min())
              for f in range(F))
    c = crowd.report["crowd"]
    assert gap >= 2.0 * radius and c["spines_apart"]
    assert c["min_spine_gap_m"] == pytest.approx(gap, abs=1e-9)
    assert c["body_radius_m"] == radius and c["creatures"] == N
    assert c["leg_bones_in_other_bodies"] == sum(c["leg_bones_in_other_bodies_by_creature"])


def test_the_report_lists_every_creature(crowd):
    rep = json.loads(crowd.outputs["json"].read_text())
    cs = rep["creatures"]
    assert [c["name"] for c in cs] == ["Centipede", "Centipede_01", "Centipede_02"]
    assert [c["index"] for c in cs] == [0, 1, 2]
    for c, traj in zip(cs, crowd.trajectories):
        assert c["timeline"] and c["timeline"][0]["start"] == 0.0
        assert c["metrics"]["frames"] == 121 and c["metrics"]["nan_count"] == 0
        assert c["metrics"]["legs"]["enabled"]
        assert len(c["timeline"]) == len(traj.events)
    # the top level stays creature 0's, as a lone creature's report
    assert rep["metrics"] == cs[0]["metrics"] and rep["timeline"] == cs[0]["timeline"]
    assert rep["crowd"]["creatures"] == N


def test_the_files_carry_every_creatures_timeline_and_contacts(doc, stage, crowd):
    extras = doc["scenes"][0]["extras"]
    cs = extras["creatures"]
    assert [c["joint_prefix"] for c in cs] == ["", "c01_", "c02_"]
    assert cs[0]["foot_contacts"] == extras["foot_contacts"]
    assert all(len(c["foot_contacts"]) == 40 for c in cs)
    custom = stage.GetPrimAtPath("/World").GetCustomData()
    assert json.loads(custom["creatures"]) == cs
    for i, path in enumerate(("/World/Centipede", "/World/Centipede_01", "/World/Centipede_02")):
        assert stage.GetPrimAtPath(path).IsA(UsdSkel.Root)
        anim = stage.GetPrimAtPath(f"{path}/Animation")
        assert anim.GetCustomData()["frames"] == 121


def test_usd_meshes_are_stored_once_and_bound_to_their_own_skeleton(stage):
    for name in ("body", "legs"):
        src = stage.GetPrimAtPath(f"/World/Centipede/{name}")
        for i in (1, 2):
            prim = stage.GetPrimAtPath(f"/World/Centipede_{i:02d}/{name}_{i:02d}")
            assert prim.IsValid() and prim.HasAuthoredReferences()
            target = UsdSkel.BindingAPI(prim).GetSkeletonRel().GetTargets()
            assert [str(t) for t in target] == [f"/World/Centipede_{i:02d}/Skeleton"]
            assert (len(prim.GetAttribute("points").Get())
                    == len(src.GetAttribute("points").Get()))
    cache = UsdSkel.Cache()
    for i in (1, 2):
        root = UsdSkel.Root(stage.GetPrimAtPath(f"/World/Centipede_{i:02d}"))
        cache.Populate(root, Usd.PrimDefaultPredicate)
        bindings = cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate)
        assert len(bindings) == 1 and len(bindings[0].GetSkinningTargets()) == 2


def test_every_creature_is_judged(crowd):
    results = judge_creatures(crowd.outputs["glb"], crowd.outputs["usd"])
    assert len(results) == N
    for r in results:
        assert r["metrics"]["frames"] == 121
        assert r["metrics"]["glb_usd_max_m"] <= 1e-4
        assert r["metrics"]["spine_inside_geometry"] == 0


def test_one_worker_writes_the_same_bytes_as_two(crowd, tmp_path, nav_cache_dir):
    """The crowd's per-creature stages on one process and on two forked ones (the fixture's
    bake, baker.parallel.fork_map; serial where fork is not used) give the same files."""
    res = bake(crowd_config(tmp_path / "one", nav_cache_dir, 1))
    for fmt in ("glb", "usd"):
        assert res.outputs[fmt].read_bytes() == crowd.outputs[fmt].read_bytes(), fmt
    strip = ("timings_s", "outputs", "navmesh_cache_hit")
    assert ({k: v for k, v in res.report.items() if k not in strip}
            == {k: v for k, v in crowd.report.items() if k not in strip})


def test_a_crowd_with_clips_and_in_place_root_motion(tmp_path, nav_cache_dir):
    cfg = BakeConfig(seconds=2.0, seed=1, creatures=2, rig=load_rig_config(DEFAULT_RIG),
                     environment=FLOOR_ENVIRONMENT, prey=0,
                     out=tmp_path / "c2", nav_cache_dir=nav_cache_dir, clips=True,
                     root_motion="in-place")
    res = bake(cfg)
    issues = gltf_validate(res.outputs["glb"])["issues"]
    assert issues["numErrors"] == 0, issues["messages"][:5]
    d = Glb(res.outputs["glb"].read_bytes()).doc
    names = [a["name"] for a in d["animations"]]
    assert names[0] == "bake" and names[-1] == "root_motion" and len(names) >= 3
    nodes = d["nodes"]
    roots = {nodes[c["target"]["node"]]["name"] for c in d["animations"][-1]["channels"]}
    assert roots == {"root", "c01_root"}
    # the per-behaviour clips are creature 0's
    c0 = set(d["skins"][0]["joints"])
    for a in d["animations"][1:-1]:
        assert {c["target"]["node"] for c in a["channels"]} <= c0 | {
            i for i, n in enumerate(nodes) if n["name"] == "Sun"}
    stage = Usd.Stage.Open(str(res.outputs["usd"]))
    assert usd_validate(stage) == []
    assert stage.GetPrimAtPath("/World/Centipede_01/Clips/root_motion").IsValid()
    assert not stage.GetPrimAtPath("/World/Centipede_01/Clips/" + names[1]).IsValid()


@pytest.mark.parametrize("value, words", [("0", ["--creatures", "[1, 1000]"]),
                                          ("1001", ["--creatures", "[1, 1000]"]),
                                          ("x", ["--creatures", "integer"])])
def test_creatures_option_errors(value, words, capsys, tmp_path):
    check_option_error(["--creatures", value], words, capsys, tmp_path)


@pytest.mark.parametrize("value, words", [("0", ["--workers", "[1, 1024]"]),
                                          ("1025", ["--workers", "[1, 1024]"]),
                                          ("two", ["--workers", "integer"])])
def test_workers_option_errors(value, words, capsys, tmp_path):
    check_option_error(["--workers", value, "--creatures", "2"], words, capsys, tmp_path)


def check_option_error(args, words, capsys, tmp_path):
    """One line, exit 2, no traceback, nothing written."""
    code = main(["bake", *args, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "Traceback" not in err
    for w in words:
        assert w in lines[0], lines[0]
    assert not list(tmp_path.iterdir())


def test_a_jobs_file_takes_creatures(tmp_path):
    (tmp_path / "j.toml").write_text('[[job]]\nname = "crowd"\ncreatures = 4\n'
                                     '[[job]]\nname = "bad"\ncreatures = 0\n')
    with pytest.raises(Exception) as e:
        batch.load_plan(tmp_path / "j.toml", tmp_path / "out")
    assert "job 'bad': creatures = 0: expected an integer in [1, 1000]" in str(e.value)
    (tmp_path / "j.toml").write_text('[[job]]\nname = "crowd"\ncreatures = 4\n'
                                     '[[job]]\nname = "one"\n')
    plan = batch.load_plan(tmp_path / "j.toml", tmp_path / "out")
    assert [j.cfg.creatures for j in plan.jobs] == [4, 1]
    assert plan.jobs[0].key != plan.jobs[1].key


def test_an_unreduced_crowd_with_a_root_joint(tmp_path, nav_cache_dir):
    """--tolerance 0 writes every key of every creature; --root-motion root gives each its
    own `root` joint (`c01_root`)."""
    cfg = BakeConfig(seconds=1.0, seed=2, creatures=2, rig=load_rig_config(DEFAULT_RIG),
                     environment=FLOOR_ENVIRONMENT, prey=0,
                     out=tmp_path / "t0", nav_cache_dir=nav_cache_dir, tolerance=0.0,
                     root_motion="root", formats=("glb",))
    res = bake(cfg)
    assert gltf_validate(res.outputs["glb"])["issues"]["numErrors"] == 0
    d = Glb(res.outputs["glb"].read_bytes()).doc
    assert [d["nodes"][s["skeleton"]]["name"] for s in d["skins"]] == ["root", "c01_root"]
    anim = d["animations"][0]
    assert len(anim["channels"]) == 2 * 2 * len(d["skins"][0]["joints"])   # T and R, all
    for i, traj in enumerate(res.trajectories):
        g = read_glb(res.outputs["glb"], "bake", creature=i)
        head = g.positions[:, g.index("head")]
        assert np.abs(head - (traj.spine_positions[:, 0] + res.origin)).max() < 1e-5
