"""`baker cycles`: every loop closes (seam error <= 1e-4 m, velocities at the first and last
frame within 2%), one-shots start and end in the idle pose, no joint turns 30 degrees in a frame,
idle feet stay planted, both validators are clean, the bytes are deterministic and bad options
are one-line errors. Loops and one-shots are judged from the written GLB (and USD), not from the
arrays in memory; only the velocity reference (the simulation's frames just outside each
window, which no file holds) comes from the run."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from baker.cli import main
from baker.config import DEFAULT_RIG, load_rig_config
from baker.cycles import CyclesConfig, bake_cycles
from glb_read import Glb
from validator import gltf_validate, usd_issues

LOOPS = ("walk_loop", "run_loop", "turn_left_walk_loop", "turn_right_walk_loop", "idle_loop")
SHOTS = ("cobra_rear", "warning", "strike")


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    out = tmp_path_factory.mktemp("cycles")
    result = bake_cycles(CyclesConfig(rig=load_rig_config(DEFAULT_RIG), out=out))
    return result, Glb(result.outputs["glb"].read_bytes())


def clip_world(glb: Glb, name: str, joints) -> tuple[np.ndarray, np.ndarray]:
    """(F, J, 3) world positions and (F, J, 3, 3) world rotations of `joints` (the root first)
    over the keys of animation `name`, composed from the file's node matrices."""
    names = [a["name"] for a in glb.doc["animations"]]
    nodes, world = glb.world_matrices(names.index(name))
    idx = [nodes.index(j) for j in joints]
    w = world[:, idx]
    return w[..., :3, 3], w[..., :3, :3]


def from_root(pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(F, J, 3) positions seen from joint 0 (the root: translation and yaw)."""
    return (pos - pos[:, :1]) @ rot[:, 0]              # row vectors: R^T (x - x_root)


def ground_steps(pos: np.ndarray, rot: np.ndarray, frames) -> np.ndarray:
    """(k, J, 3) each joint's step from frame f to f + 1 seen from the root at f."""
    f = np.asarray(frames)
    return (pos[f + 1] - pos[f]) @ rot[f, 0]


def test_clip_list_and_loop_names(cycles):
    result, glb = cycles
    names = [a["name"] for a in glb.doc["animations"]]
    assert names == list(LOOPS + SHOTS)

    def godot_loops(name: str) -> bool:
        # editor/import/3d/resource_importer_scene.cpp, _teststr: trailing digits, spaces and
        # '_' dropped, then a "_loop"/"-loop"/"_cycle"/... suffix (any case) or "$loop"
        what = name.rstrip("0123456789 _")
        return any(what.lower().endswith(sep + s) or ("$" + s) in what.lower()
                   for s in ("loop_mode", "loop", "cycle") for sep in "_-")

    assert [n for n in names if godot_loops(n)] == list(LOOPS)
    from baker.export.events import ClipEvents

    for a in glb.doc["animations"]:
        ev = a["extras"]
        ClipEvents.model_validate(ev)                    # the project's clip events schema
        t = glb.accessor(a["samplers"][0]["input"])
        assert ev["loop"] is (a["name"] in LOOPS)
        assert ev["frames"] == len(t)
        marks = {e["name"]: e["frame"] for e in ev["events"] if e["type"] == "marker"}
        first = next(e for e in ev["events"] if e["type"] == "behaviour")
        assert first["frame"] == 0
        if ev["loop"]:
            assert marks == {"loop_start": 0, "loop_end": len(t) - 1}
            assert first["details"]["cycle"]["frames"] == len(t) - 1
        else:
            assert marks["start"] == 0 and marks["end"] == len(t) - 1
            assert first["details"]["one_shot"]["starts_and_ends_in"] == "idle_loop"
        if a["name"] != "idle_loop":
            assert len(ev["contacts"]) == 40


def test_loops_close_in_the_glb(cycles):
    """Seam error <= 1e-4 m; the velocities through the seam as played agree with the
    simulation's at the first and the last frame within 2% (baker.cycles.looping)."""
    result, glb = cycles
    joints = result.rig.skeleton.names
    summary = {c["name"]: c for c in result.summary["clips"]}
    for name in LOOPS:
        pos, rot = clip_world(glb, name, joints)
        p = from_root(pos, rot)
        seam = np.linalg.norm(p[-1] - p[0], axis=-1).max()
        assert seam <= 1e-4, (name, seam)
        ref = result.references[name]
        rt, rq = ref.world(result.rig.skeleton.parents)
        rr = Rotation.from_quat(rq.reshape(-1, 4)).as_matrix().reshape(rq.shape[:2] + (3, 3))
        n = len(p) - 1
        played = ground_steps(pos, rot, [n - 1, 0])
        sim = ground_steps(rt, rr, [0, n + 1])
        speed = max(np.linalg.norm(played, axis=-1).max(), np.linalg.norm(sim, axis=-1).max())
        mismatch = np.linalg.norm(played - sim, axis=-1).max() / speed
        assert mismatch <= 0.02, (name, mismatch)
        assert summary[name]["velocity_mismatch"] == pytest.approx(mismatch, abs=1e-3)
        # and the simulation itself was periodic: the residual distributed was tiny
        assert summary[name]["residual_m"] <= 1e-4, summary[name]
        cyc = summary[name]["cycle"]
        if name != "idle_loop":
            assert abs(cyc["slither_nudge"]) <= 0.01 and abs(cyc["stride_nudge"]) <= 0.01
            assert cyc["measured_gait_cycles"] == pytest.approx(cyc["gait_cycles"], abs=1e-6)


def test_loops_move_as_asked(cycles):
    """walk/run travel forward at their speeds (root along +Z), turns turn left and right."""
    result, glb = cycles
    bl = result.summary["body_length_m"]
    root = {}
    for name in LOOPS:
        pos, rot = clip_world(glb, name, ["root"])
        root[name] = (pos[:, 0], rot[:, 0])
        assert np.allclose(pos[0, 0], 0.0, atol=1e-6)            # starts at the origin
    fps = result.summary["fps"]
    for name, speed in (("walk_loop", 0.8), ("run_loop", 1.6)):
        p = root[name][0]
        v = (p[-1, 2] - p[0, 2]) * fps / (len(p) - 1) / bl
        assert v == pytest.approx(speed, rel=0.05), name
        assert abs(p[-1, 0] - p[0, 0]) < 0.01 * (p[-1, 2] - p[0, 2])   # along +Z
    for name, side in (("turn_left_walk_loop", 1.0), ("turn_right_walk_loop", -1.0)):
        fwd = root[name][1][:, :, 2]                               # the root's +Z in the world
        yaw = np.unwrap(np.arctan2(fwd[:, 0], fwd[:, 2]))
        assert side * (yaw[-1] - yaw[0]) > 0.5                     # turned by > 0.5 rad
    idle = root["idle_loop"][0]
    assert np.abs(idle - idle[0]).max() < 1e-6


def test_one_shots_start_and_end_in_the_idle_pose(cycles):
    result, glb = cycles
    joints = result.rig.skeleton.names
    pos, rot = clip_world(glb, "idle_loop", joints)
    idle = from_root(pos, rot)[0]
    for name in SHOTS:
        pos, rot = clip_world(glb, name, joints)
        p = from_root(pos, rot)
        assert np.linalg.norm(p[0] - idle, axis=-1).max() <= 1e-4, name
        assert np.linalg.norm(p[-1] - idle, axis=-1).max() <= 1e-4, name
        assert np.linalg.norm(p - idle, axis=-1).max() > 0.01, name   # and does something


def test_no_joint_turns_30_degrees_in_a_frame(cycles):
    """Every joint's local rotation, key to key (and across each loop's seam)."""
    _, glb = cycles
    for a in glb.doc["animations"]:
        for ch in a["channels"]:
            if ch["target"]["path"] != "rotation":
                continue
            q = glb.accessor(a["samplers"][ch["sampler"]]["output"]).astype(np.float64)
            root = glb.doc["nodes"][ch["target"]["node"]]["name"] == "root"
            if a["extras"]["loop"] and not root:     # the root's motion accumulates instead
                q = np.concatenate([q, q[1:2]])
            dot = np.abs(np.sum(q[1:] * q[:-1], axis=-1)).clip(0.0, 1.0)
            turn = np.degrees(2.0 * np.arccos(dot)).max()
            assert turn < 30.0, (a["name"], ch["target"]["node"], turn)


def test_idle_feet_stay_planted(cycles):
    result, glb = cycles
    feet = [n for n in result.rig.skeleton.names if n.startswith("leg_") and n.endswith("_foot")]
    assert len(feet) == 40
    pos, _ = clip_world(glb, "idle_loop", feet)
    assert np.linalg.norm(pos - pos[:1], axis=-1).max() <= 1e-5
    assert np.abs(pos[..., 1]).max() < 0.01                        # on the ground


def test_validators_are_clean(cycles):
    result, _ = cycles
    report = gltf_validate(result.outputs["glb"])
    assert report["issues"]["numErrors"] == 0
    assert report["issues"]["numWarnings"] == 0
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(result.outputs["usd"]))
    assert usd_issues(stage) == []
    bound = UsdSkel.Animation(stage.GetPrimAtPath("/World/Centipede/Animation"))
    assert bound.GetPrim().GetCustomData()["loop"] is True
    for name in LOOPS[1:] + SHOTS:
        prim = stage.GetPrimAtPath(f"/World/Centipede/Clips/{name}")
        assert prim.IsValid(), name
        assert prim.GetCustomData()["loop"] is (name in LOOPS)
    assert stage.GetPrimAtPath("/World/Centipede/Skeleton").IsValid()


def test_summary(cycles):
    result, _ = cycles
    doc = json.loads(result.outputs["json"].read_text())
    assert doc["root_motion"] == "root"
    assert doc["speeds_bl_per_s"] == {"walk": 0.8, "run": 1.6}
    assert [c["name"] for c in doc["clips"]] == list(LOOPS + SHOTS)
    for c in doc["clips"]:
        assert c["max_joint_turn_deg"] < 30.0
        if c["loop"]:
            assert c["seam_error_m"] <= 1e-4 and c["velocity_mismatch"] <= 0.02


@pytest.mark.slow
def test_same_options_same_bytes(cycles, tmp_path):
    result, _ = cycles
    again = bake_cycles(CyclesConfig(rig=load_rig_config(DEFAULT_RIG), out=tmp_path))
    for k, p in result.outputs.items():
        assert p.read_bytes() == again.outputs[k].read_bytes(), k


@pytest.mark.parametrize("args, word", [
    (["--speeds", "1"], "--speeds"),
    (["--speeds", "fast,faster"], "--speeds"),
    (["--speeds", "0.1,1.6"], "walk speed"),
    (["--speeds", "0.8,9"], "run speed"),
    (["--speeds", "nan,1"], "walk speed"),
    (["--speeds", "2,0.5"], "faster than the run"),
    (["--fps", "7"], "--fps"),
    (["--rig", "no_such_rig.toml"], "rig file not found"),
])
def test_bad_options_are_one_line_errors(args, word, tmp_path, capsys):
    code = main(["cycles", "--out", str(tmp_path / "c"), *args])
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert word.lower() in lines[0].lower()
    assert not (tmp_path / "c").exists()


def test_out_over_the_rig_read_is_an_error(tmp_path, capsys):
    """A rig file named cycles.json (or .usd) in the --out folder: the library was written
    over the rig it read."""
    from baker.config import DEFAULT_RIG

    for name in ("cycles.json", "cycles.usd"):
        rig = tmp_path / name
        rig.write_bytes(DEFAULT_RIG.read_bytes())
        assert main(["cycles", "--out", str(tmp_path), "--rig", str(rig)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is the rig file" in err, err
        assert rig.read_bytes() == DEFAULT_RIG.read_bytes()
        rig.unlink()
    assert not list(tmp_path.iterdir())


def test_out_naming_a_file_is_an_error(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["cycles", "--out", str(f)]) == 2
    assert "--out" in capsys.readouterr().err
    assert f.read_text() == "x"


def test_the_seam_is_as_smooth_as_the_loop_from_the_file_alone(cycles):
    """Read from the GLB only: played in a loop, the step into the seam and the step out of it
    (key N-1 -> N == 0 and key 0 -> 1, seen from the root) change about as much as consecutive
    steps inside the loop: the seam has no velocity jump of its own. (A touch-down or lift-off
    can fall on the seam, and the gait's period is not a whole number of frames, so the seam's
    change may be up to 10% over the largest inside the loop; a jump would be far larger.)"""
    result, glb = cycles
    joints = result.rig.skeleton.names
    for name in LOOPS:
        pos, rot = clip_world(glb, name, joints)
        n = len(pos) - 1
        steps = ground_steps(pos, rot, range(n))                  # (N, J, 3), step f -> f + 1
        change = np.linalg.norm(np.diff(steps, axis=0), axis=-1)  # inside: step f+1 vs step f
        seam = np.linalg.norm(steps[0] - steps[-1], axis=-1)      # out of the seam vs into it
        assert np.all(seam <= 1.1 * change.max(axis=0) + 1e-7), (
            name, float((seam - change.max(axis=0)).max()))


def test_an_empty_out_is_an_error(tmp_path, capsys, monkeypatch):
    """`--out ""` named the current folder and wrote the clips there."""
    monkeypatch.chdir(tmp_path)
    assert main(["cycles", "--out", ""]) == 2
    err = capsys.readouterr().err
    assert err.startswith("Error: --out is empty") and err.count("\n") == 1
    assert not list(tmp_path.iterdir())
