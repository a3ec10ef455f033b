"""End to end on the bundled rainforest floor: a 60 s bake, checked by the Khronos validator,
UsdValidation, the UsdSkel round trip and the motion metrics; determinism; the CLI's output."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdSkel

from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, BakeConfig, load_rig_config
from baker.geometry.transforms import trs_to_matrix
from baker.pipeline import bake
from glb_read import Glb
from validator import gltf_validate, issues_summary, usd_validate

pytestmark = pytest.mark.slow


def run(tmp: Path, cache: Path, name: str, seconds: float, seed: int = 0, **kw):
    cfg = BakeConfig(environment=FLOOR_ENVIRONMENT, prey=0, seconds=seconds, seed=seed,
                     rig=load_rig_config(DEFAULT_RIG),
                     out=tmp / name, nav_cache_dir=cache, **kw)
    return bake(cfg)


@pytest.fixture(scope="module")
def baked(tmp_path_factory, nav_cache_dir):
    tmp = tmp_path_factory.mktemp("bake60")
    return run(tmp, nav_cache_dir, "centipede", 60.0)


def test_outputs_exist(baked):
    assert set(baked.outputs) == {"glb", "usd", "json"}
    for p in baked.outputs.values():
        assert p.is_file() and p.stat().st_size > 0
    assert not [p for p in baked.outputs["glb"].parent.iterdir() if ".tmp" in p.name]


def test_motion_metrics_over_every_frame(baked):
    m = baked.report["metrics"]
    assert m["frames"] == 60 * 30 + 1
    assert m["nan_count"] == 0
    # every trunk joint between 0 and 2x clearance above the surface below it
    assert m["clearance_violations"] == 0
    assert 0.0 <= m["clearance_ratio_min"] and m["clearance_ratio_max"] <= 2.0
    # neighbouring spine joints within +-2% of the rig spacing
    assert m["spacing_error_max"] <= 0.02
    # the surface under the head is never steeper than 60 degrees
    assert m["head_slope_max_deg"] <= 60.0
    assert m["frames_on_unwalkable_slope"] == 0
    assert m["trunk_inside_geometry"] == 0  # no trunk joint inside a solid, any frame
    assert m["head_unsupported_frames"] == 0
    assert m["distance_walked_body_lengths"] > 10
    # the body moves with its head: no joint jumps along the trail (metrics.spine_jumps)
    assert m["spine_jump_frames"] == 0, m["spine_jump_max_spacings"]


def test_metrics_agree_with_the_trajectory(baked):
    """Recompute spacing from the trajectory itself, not from the report."""
    p = baked.trajectory.spine_positions
    spacing = 0.25 / 20
    gaps = np.linalg.norm(np.diff(p, axis=1), axis=2) / spacing - 1
    assert np.abs(gaps).max() == pytest.approx(baked.report["metrics"]["spacing_error_max"])
    assert np.all(np.isfinite(p))


def test_glb_passes_khronos_validator(baked):
    report = gltf_validate(baked.outputs["glb"])
    errors = issues_summary(report, 0)
    assert errors == [], errors
    assert report["issues"]["numErrors"] == 0


def test_usd_passes_usd_validation(baked):
    stage = Usd.Stage.Open(str(baked.outputs["usd"]))
    assert usd_validate(stage) == []
    assert UsdGeomUpAxis(stage) == "Y"
    assert stage.GetTimeCodesPerSecond() == 30
    assert stage.GetEndTimeCode() == 60 * 30


def UsdGeomUpAxis(stage):
    from pxr import UsdGeom

    return UsdGeom.GetStageUpAxis(stage)


def test_usd_anim_query_matches_glb_accessors(baked):
    """UsdSkel's joint-local transforms equal the GLB's channels at every frame: the GLB's
    reduced keys (16-bit rotations; a channel left out is the node's TRS) interpolated, LINEAR,
    between its key times."""
    from scipy.spatial.transform import Rotation, Slerp

    stage = Usd.Stage.Open(str(baked.outputs["usd"]))
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath("/World/Centipede"))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Centipede/Skeleton"))
    anim = cache.GetSkelQuery(skel).GetAnimQuery()
    names = [str(t).split("/")[-1] for t in anim.GetJointOrder()]
    glb = Glb(baked.outputs["glb"].read_bytes())
    tracks = glb.animation_tracks()
    times = (np.arange(1801) / 30).astype(np.float32).astype(np.float64)

    def played(name, path, default):
        if (name, path) not in tracks:
            node = glb.doc["nodes"][glb.node_index(name)]
            return np.tile(np.asarray(node.get(path, default), np.float64), (len(times), 1))
        k, v = tracks[(name, path)]
        v = v / 32767.0 if v.dtype == np.int16 else v.astype(np.float64)
        if len(k) == 1:
            return np.tile(v[0], (len(times), 1))
        if path == "rotation":
            return Slerp(k, Rotation.from_quat(v))(np.clip(times, k[0], k[-1])).as_quat()
        return np.stack([np.interp(times, k, v[:, c]) for c in range(3)], 1)

    t = np.stack([played(n, "translation", [0.0] * 3) for n in names], 1)
    q = np.stack([played(n, "rotation", [0.0, 0.0, 0.0, 1.0]) for n in names], 1)
    glb_m = trs_to_matrix(t, q)
    assert len(t) == 1801
    worst = 0.0
    for f in range(len(t)):
        usd_m = np.array(anim.ComputeJointLocalTransforms(Usd.TimeCode(f))).transpose(0, 2, 1)
        worst = max(worst, float(np.abs(usd_m - glb_m[f]).max()))
    assert worst < 1e-4, worst


def test_report_contents(baked):
    r = json.loads(baked.outputs["json"].read_text())
    assert r["seed"] == 0
    assert r["parameters"]["seconds"] == 60.0 and r["parameters"]["fps"] == 30
    assert r["parameters"]["rig"]["body"]["segments"] == 21
    for stage in ("load", "navmesh", "rig", "simulate", "pose", "export"):
        assert r["timings_s"][stage] >= 0
    for pkg in ("numpy", "trimesh", "pygltflib", "usd-core"):
        assert r["versions"][pkg]
    tl = r["timeline"]
    assert tl and tl[0]["start"] == 0.0 and tl[-1]["end"] == 60.0
    assert all(a["end"] == b["start"] for a, b in zip(tl, tl[1:]))
    doc = Glb(baked.outputs["glb"].read_bytes()).doc
    assert doc["scenes"][0]["extras"]["seed"] == 0
    assert doc["scenes"][0]["extras"]["timeline"] == tl
    # planted intervals per leg agree with the trajectory's contact flags
    contacts = doc["scenes"][0]["extras"]["foot_contacts"]
    assert len(contacts) == 40
    flags = np.zeros(baked.trajectory.n_frames, dtype=bool)
    for a, b in contacts["leg_R_07_foot"]:
        flags[a:b + 1] = True
    assert np.array_equal(flags, baked.trajectory.foot_contacts[:, 2 * 6 + 1])


def test_same_seed_same_bytes_different_seed_different_path(tmp_path, nav_cache_dir):
    a = run(tmp_path, nav_cache_dir, "a", 10.0, seed=3)
    b = run(tmp_path, nav_cache_dir, "b", 10.0, seed=3)
    c = run(tmp_path, nav_cache_dir, "c", 10.0, seed=4)
    for fmt in ("glb", "usd"):
        assert a.outputs[fmt].read_bytes() == b.outputs[fmt].read_bytes()
    pa, pc = a.trajectory.spine_positions[:, 0], c.trajectory.spine_positions[:, 0]
    assert np.abs(pa - pc).max() > 0.1


def test_cli_is_quiet_when_piped_and_prints_one_summary_line(tmp_path, nav_cache_dir):
    r = subprocess.run([sys.executable, "-m", "baker.cli", "bake", "--seconds", "2", "--out",
                        str(tmp_path / "c"), "--cache-dir", str(nav_cache_dir)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1
    assert "61 frames" in lines[0] and "c.glb" in lines[0] and "c.usd" in lines[0]
    assert " s" in lines[0]
