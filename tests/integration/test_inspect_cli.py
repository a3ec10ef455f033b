"""`baker inspect FILE [--json]` on real bake outputs (GLB, USD, USDA, the JSON report) and on a
corpus of broken files built here: every one of those exits with 2 and one line, no traceback."""

from __future__ import annotations

import importlib.util
import json
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from baker.cli import main
from baker.config import FLOOR_ENVIRONMENT
from baker.inspect_file import LOOP_RULE, inspect_file, khronos_validate, loops_by_name
import bad_inputs
from glb_read import Glb

SECONDS = 3


@pytest.fixture(scope="module")
def bakes(tmp_path_factory, nav_cache_dir):
    """On the bundled rainforest floor: a bake with prey and per-behaviour clips (GLB + USD + JSON) and one written as USDA,
    every frame keyed (--tolerance 0: the tests below edit and count keys; reduced files are
    inspected in test_a_reduced_bake_is_inspected)."""
    d = tmp_path_factory.mktemp("inspect_cli")
    for name, extra in (("c", ["--prey", "1", "--clips"]),
                        ("t", ["--prey", "0", "--usda", "--format", "usd"])):
        code = main(["bake", str(FLOOR_ENVIRONMENT), "--seconds", str(SECONDS), "--seed", "2", "--out", str(d / name),
                     "--cache-dir", str(nav_cache_dir), "--tolerance", "0", *extra])
        assert code == 0
    return d


def run(args, capsys) -> tuple[int, str, str]:
    code = main(["inspect", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


def as_json(path, capsys) -> dict:
    code, out, err = run([path, "--json"], capsys)
    assert code == 0, err
    return json.loads(out)


def test_glb_report_matches_the_file(bakes, capsys, rig):
    from validator import ensure_node

    ensure_node()                                  # the validator is installed for the tests
    path = bakes / "c.glb"
    r = as_json(path, capsys)
    g = Glb(path.read_bytes())
    doc = g.doc
    sk = r["skeleton"]
    assert sk["joints"] == rig.skeleton.n_joints and sk["roots"] == ["head"]
    assert sk["end_joints"] == sum(1 for j in range(rig.skeleton.n_joints)
                                   if not rig.skeleton.children(j))
    assert sk["groups"]["trunk"] == 20 and sk["groups"]["head"] == 1
    names = [a["name"] for a in doc["animations"]]
    assert [c["name"] for c in r["clips"]] == names and names[0] == "bake"
    frames = SECONDS * 30 + 1
    bake = r["clips"][0]
    assert bake["duration_s"] == pytest.approx(SECONDS) and bake["frames"] == frames
    anim = doc["animations"][0]
    # a reduced bake (the default): each channel has its own key count, static ones are gone
    assert bake["keys"] == sum(doc["accessors"][anim["samplers"][c["sampler"]]["input"]]["count"]
                               for c in anim["channels"])
    joints = set(doc["skins"][0]["joints"])
    for p in ("translation", "rotation"):
        assert bake["joint_channels"][p] == sum(
            c["target"]["node"] in joints and c["target"]["path"] == p for c in anim["channels"])
    assert 0 < bake["joint_channels"]["rotation"] <= sk["joints"]
    prey = doc["nodes"].index(next(n for n in doc["nodes"] if n["name"] == "prey_01"))
    # the channels of nodes that are not joints: the prey's, and the sun's when it turns
    assert bake["node_channels"] == sum(c["target"]["node"] not in joints for c in anim["channels"])
    assert sum(c["target"]["node"] == prey for c in anim["channels"]) >= 2
    assert not any(c["loop"] for c in r["clips"])
    # sizes: exact, they add up to the file, and the animation share is its accessors' views
    s = r["sizes"]
    assert sum(v for k, v in s.items() if k != "metadata_bytes") == path.stat().st_size
    anim_views = {doc["accessors"][smp[k]]["bufferView"] for a in doc["animations"]
                  for smp in a["samplers"] for k in ("input", "output")}
    assert s["animation"] == sum(doc["bufferViews"][v]["byteLength"] for v in anim_views)
    assert s["environment"] > 0 and s["mesh"] > 0 and 0 <= s["other"] < 64
    assert s["metadata_bytes"] == len(json.dumps(doc["scenes"][0]["extras"],
                                                 separators=(",", ":")))
    v = r["validator"]
    assert v["available"] and v["errors"] == 0 and v["warnings"] == 0
    assert v["tool"].startswith("Khronos glTF-Validator 2.")
    m = r["metadata"]
    assert m["seed"] == 2 and m["fps"] == 30 and m["rig"] == "scolopendra"
    assert sum(m["timeline"]["state_seconds"].values()) == pytest.approx(SECONDS)
    assert m["foot_contacts"]["feet"] == 40


def test_glb_text_report(bakes, capsys):
    code, out, err = run([bakes / "c.glb"], capsys)
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].startswith(f"{bakes / 'c.glb'}: GLB, ")
    assert lines[1].startswith("skeleton: 159 joints, root head")
    assert any(ln.split()[:5] == ["bake", f"{SECONDS:.3f}", "s", str(SECONDS * 30 + 1), "frames"]
               for ln in lines), out
    assert any(ln.startswith("size: mesh ") and "animation" in ln and "environment" in ln
               for ln in lines)
    assert any(ln.startswith("validator: Khronos glTF-Validator") and "0 errors, 0 warnings" in ln
               for ln in lines) or "not available" in out
    assert any(ln.startswith("metadata: generator baker") and "seed 2" in ln for ln in lines)


def test_a_reduced_bake_is_inspected(tmp_path, nav_cache_dir, capsys):
    """The default (reduced) bake: per-channel key counts and dropped static channels."""
    assert main(["bake", "--seconds", "2", "--seed", "3", "--out", str(tmp_path / "r"),
                 "--cache-dir", str(nav_cache_dir)]) == 0
    capsys.readouterr()
    for name in ("r.glb", "r.usd"):
        r = as_json(tmp_path / name, capsys)
        assert r["clips"] and r["clips"][0]["duration_s"] == pytest.approx(2.0)
    doc = Glb((tmp_path / "r.glb").read_bytes()).doc
    anim = doc["animations"][0]
    r = as_json(tmp_path / "r.glb", capsys)
    assert r["clips"][0]["keys"] == sum(
        doc["accessors"][anim["samplers"][c["sampler"]]["input"]]["count"]
        for c in anim["channels"]) < 61 * len(anim["channels"])


@pytest.mark.parametrize("name", ["c.usd", "t.usda"])
def test_usd_reports(bakes, capsys, name, rig):
    path = bakes / name
    r = as_json(path, capsys)
    assert r["format"] == name.rsplit(".", 1)[1]
    assert r["skeleton"]["joints"] == rig.skeleton.n_joints
    bound = [c for c in r["clips"] if c["bound"]]
    assert len(bound) == 1 and bound[0]["prim"] == "/World/Centipede/Animation"
    assert bound[0]["duration_s"] == pytest.approx(SECONDS)
    assert bound[0]["samples"] == {"translation": 91, "rotation": 91, "scale": 91}
    assert bound[0]["keys"] == 91 * 3 * rig.skeleton.n_joints
    if name == "c.usd":                        # with --clips: one SkelAnimation per behaviour
        glb = as_json(bakes / "c.glb", capsys)
        assert [c["name"] for c in r["clips"][1:]] == [c["name"] for c in glb["clips"][1:]]
    assert r["validator"] == {"tool": "UsdValidation", "available": True, "errors": 0,
                              "warnings": 0, "infos": 0, "messages": []}
    assert not r["sizes_exact"] and r["sizes"]["animation"] > r["sizes"]["mesh"] > 0
    assert r["metadata"]["seed"] == 2 and r["metadata"]["foot_contacts"]["feet"] == 40
    code, out, _ = run([path], capsys)
    assert code == 0 and "validator: UsdValidation: 0 errors, 0 warnings" in out


def test_json_report(bakes, capsys):
    r = as_json(bakes / "c.json", capsys)
    rep = r["report"]
    assert rep["seed"] == 2 and rep["fps"] == 30 and rep["seconds"] == SECONDS
    assert set(rep["outputs"]) == {"glb", "usd", "json"}
    assert r["metrics"]["frames"] == SECONDS * 30 + 1
    assert r["metrics"]["legs.legs"] == 40
    code, out, _ = run([bakes / "c.json"], capsys)
    assert code == 0 and "metrics:" in out and "frames 91" in out


def test_no_validate_and_a_missing_validator(bakes, capsys, monkeypatch):
    code, out, _ = run([bakes / "c.glb", "--no-validate"], capsys)
    assert code == 0 and "validator: skipped" in out
    monkeypatch.setattr("shutil.which", lambda name: None)
    v = khronos_validate(bakes / "c.glb")
    assert v == {"tool": "Khronos glTF-Validator", "available": False,
                 "reason": "node is not on PATH"}
    code, out, _ = run([bakes / "c.glb"], capsys)
    assert code == 0 and "Khronos glTF-Validator not available: node is not on PATH" in out


@pytest.mark.parametrize("name", ["c.glb", "c.usd", "c.json"])
def test_a_file_that_vanishes_once_checked_is_one_line(name, bakes, tmp_path, capsys,
                                                       monkeypatch):
    """The file removed between inspect's checks (there, a file) and its read: one line, exit
    2 (FileNotFoundError was a traceback)."""
    import shutil

    import baker.inspect_file as inspect_file_mod

    path = tmp_path / name
    shutil.copy(bakes / name, path)
    real = inspect_file_mod.Path.stat
    calls = []

    def stat_then_gone(self, *a, **k):     # exists, is_file, the size: then the file is gone
        st = real(self, *a, **k)
        if self == path:
            calls.append(1)
            if len(calls) == 3:
                path.unlink()
        return st

    monkeypatch.setattr(inspect_file_mod.Path, "stat", stat_then_gone)
    code, out, err = run([path], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith("Error: ") and path.name in err, err


def test_a_validator_folder_too_long_for_the_file_system_is_no_validator(bakes, capsys,
                                                                           monkeypatch):
    """$BAKER_GLTF_VALIDATOR naming a path the file system refuses as too long: the report
    (the validator found elsewhere, or not available), not 'Error: path is too long'."""
    monkeypatch.setenv("BAKER_GLTF_VALIDATOR", str(bakes / ("v" * 5000)))
    code, out, err = run([bakes / "c.glb"], capsys)
    assert code == 0 and "validator: " in out, err

@pytest.mark.parametrize("name,loops", [
    ("walk_loop", True), ("Walk-Cycle", True), ("walk_loop_2", True), ("turn_left_walk_loop", True),
    ("walk$loop", True), ("RUN_CYCLE", True), ("walkloop", False), ("loop_walk", False),
    ("bake", False), ("wander_00", False), ("cobra_rear", False)])
def test_loop_convention(name, loops):
    assert loops_by_name(name) is loops
    assert LOOP_RULE.pattern


def test_loop_flags_from_names_and_extras(bakes, tmp_path):
    """A clip loops by its name (Godot's rule) or by its extras' `loop`."""
    data = (bakes / "c.glb").read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    anims = doc["animations"]
    anims[0]["name"] = "walk_loop"
    anims[1]["extras"] = {"loop": True, "events": [{"t": 0.0, "type": "loop_start"}]}
    path = tmp_path / "loops.glb"
    path.write_bytes(_glb(doc, data[20 + jlen:]))
    clips = inspect_file(path, validate=False)["clips"]
    assert (clips[0]["loop"], clips[0]["loop_by"]) == (True, "name")
    assert (clips[1]["loop"], clips[1]["loop_by"], clips[1]["events"]) == (True, "extras", 1)


def test_reduced_channels_are_counted_per_channel(bakes, tmp_path):
    """Channels with their own key times (after reduction) and missing static channels."""
    data = (bakes / "c.glb").read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    a = doc["animations"][0]
    # a two-key input for the first channel, and the second channel dropped
    acc = dict(doc["accessors"][a["samplers"][a["channels"][0]["sampler"]]["input"]], count=2)
    doc["accessors"].append(acc)
    a["samplers"][a["channels"][0]["sampler"]] = dict(
        a["samplers"][a["channels"][0]["sampler"]], input=len(doc["accessors"]) - 1)
    dropped = a["channels"].pop(1)
    path = tmp_path / "reduced.glb"
    path.write_bytes(_glb(doc, data[20 + jlen:]))
    c = inspect_file(path, validate=False)["clips"][0]
    frames = SECONDS * 30 + 1
    assert c["keys_per_channel"] == [2, frames]
    assert c["keys"] == 2 + frames * (len(a["channels"]) - 1)
    assert c["static_joint_channels"][dropped["target"]["path"]] == 1


# ------------------------------------------------------------------ files it cannot read


def _glb(doc: dict, rest: bytes) -> bytes:
    j = json.dumps(doc).encode()
    j += b" " * ((-len(j)) % 4)
    return b"glTF" + struct.pack("<II", 2, 12 + 8 + len(j) + len(rest)) + \
        struct.pack("<I", len(j)) + b"JSON" + j + rest


PNG = b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\rIHDR" + bytes(17)


def _env_only_glb(d: Path) -> Path:
    from baker.environment.model import Environment, Sun
    from baker.export.gltf import build_glb
    from conftest import flat_ground

    p = d / "level.glb"
    p.write_bytes(build_glb(Environment(meshes=(flat_ground(),), sun=Sun(direction=np.array(
        [0.0, 1.0, 0.0]))), None, None, extras={}))
    return p


def _env_only_usd(d: Path) -> Path:
    from pxr import Usd, UsdGeom

    p = d / "level.usda"
    stage = Usd.Stage.CreateNew(str(p))
    UsdGeom.Xform.Define(stage, "/World")
    stage.GetRootLayer().Save()
    return p


def _bad_skin_glb(d: Path, bakes: Path) -> Path:
    data = (bakes / "c.glb").read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + jlen])
    doc["skins"][0]["joints"] = [10 ** 6]
    p = d / "badskin.glb"
    p.write_bytes(_glb(doc, data[20 + jlen:]))
    return p


def _put(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


BROKEN = {
    "missing": (lambda d, b: d / "nope.glb", "not found"),
    "folder": (lambda d, b: d, "not a file"),
    "empty_glb": (lambda d, b: _put(d / "e.glb", b""), "empty"),
    "empty_usd": (lambda d, b: _put(d / "e.usd", b""), "empty"),
    "truncated_glb": (lambda d, b: _put(d / "t.glb", (b / "c.glb").read_bytes()[:5000]),
                      "truncated"),
    "truncated_header": (lambda d, b: _put(d / "h.glb", b"glTF\x02\x00"), "not a GLB"),
    "garbage_glb": (lambda d, b: _put(d / "g.glb", bytes(range(256)) * 4), "not a GLB"),
    "png": (lambda d, b: _put(d / "pic.png", PNG), "'.png'"),
    "png_as_glb": (lambda d, b: _put(d / "pic.glb", PNG), "not a GLB"),
    "wrong_extension": (lambda d, b: _put(d / "c.txt", (b / "c.glb").read_bytes()), "'.txt'"),
    "no_extension": (lambda d, b: _put(d / "c", (b / "c.glb").read_bytes()), "suffix-less"),
    "glb_as_usd": (lambda d, b: _put(d / "c2.usd", (b / "c.glb").read_bytes()), "USD"),
    "no_skin": (lambda d, b: _env_only_glb(d), "without a skin"),
    "bad_json_chunk": (lambda d, b: _put(d / "j.glb", _glb_raw(b"{not json ", b"")), "not JSON"),
    "json_chunk_overflow": (lambda d, b: _put(d / "o.glb", _glb_overflow()), "JSON chunk"),
    "bad_skin": (lambda d, b: _bad_skin_glb(d, b), "malformed glTF"),
    "garbage_usd": (lambda d, b: _put(d / "g.usd", b"garbage\x00\x01" * 50), "USD"),
    "truncated_usd": (lambda d, b: _put(d / "t.usd", (b / "c.usd").read_bytes()[:4000]), "USD"),
    "garbage_usda": (lambda d, b: _put(d / "g.usda", b"#usda 1.0\n(\n garbage"), "USD"),
    "crate_section_start": (lambda d, b: _put(d / "s.usdc", bad_inputs.crate_section_flipped()),
                            "USD"),
    "no_skeleton_usd": (lambda d, b: _env_only_usd(d), "no UsdSkel Skeleton"),
    # a prim named in Latin-1: pxr's error could not be turned into text (UnicodeDecodeError)
    "latin1_usda": (lambda d, b: _put(d / "l.usda", b'#usda 1.0\ndef Xform "fl\xe9"\n{\n}\n'),
                    "not UTF-8 text"),
    "garbage_json": (lambda d, b: _put(d / "g.json", b"\xff\xfe{"), "not JSON"),
    "other_json": (lambda d, b: _put(d / "o.json", b'{"a": 1}'), "not a baker report"),
    "deep_json": (lambda d, b: _put(d / "deep.json", b"[" * 100_000 + b"]" * 100_000),
                  "nested too deeply"),
    # a fuzz round's (each was a traceback, a hang, a crash or a report of no bake)
    "skin_no_animation": (lambda d, b: _put(d / "s.glb", _skinned_glb()), "no animation"),
    "glb_json_deep": (lambda d, b: _put(d / "deep.glb", _glb_raw(b"[" * 100_000 + b"]" * 100_000,
                                                                 b"")), "nested too deeply"),
    "animation_name_number": (lambda d, b: _put(d / "n.glb", _glb_with(
        b / "c.glb", lambda doc: doc["animations"][0].update(name=5))), "not a string"),
    "report_outputs_number": (lambda d, b: _put(d / "r.json", json.dumps(
        {**json.loads((b / "c.json").read_text()), "outputs": 5}).encode()), "outputs"),
    "usd_no_animation": (lambda d, b: _put(d / "n.usda", _usda_of(b, lambda t: t.replace(
        'def SkelAnimation "', 'def Xform "'))), "no UsdSkel SkelAnimation"),
    "usd_skeleton_no_joints": (lambda d, b: _put(d / "n.usda", _usda_of(b, lambda t: re.sub(
        r'(def Skeleton ".*?uniform token\[\] joints = )\[[^\]]*\]', r"\1[]", t, count=1,
        flags=re.S))), "no joints"),
    **{f"usd_time_codes_{v}": (lambda d, b, v=v: _put(d / "n.usda", _usda_of(b, lambda t: re.sub(
        r"timeCodesPerSecond = \S+", f"timeCodesPerSecond = {v}", t, count=1))),
        "timeCodesPerSecond") for v in ("0", "-30", "nan", "inf")},
    "usd_layer_fifo": (lambda d, b: _fifo_layer(d), "not a file"),
    "usd_layer_device": (lambda d, b: _put(d / "z.usda", b"#usda 1.0\n(\n    subLayers = "
                                                     b"[@/dev/zero@]\n)\n"), "not a file"),
    "usda_200000_deep": (lambda d, b: _put(d / "deep.usda", bad_inputs.deep_usd_text(
        200_000).encode()), "levels deep"),
}


def _skinned_glb() -> bytes:
    """A skinned glTF (bad_inputs.skinned_gltf) with no animation."""
    doc, blob = bad_inputs.skinned_gltf()
    return bad_inputs.pack_glb(doc, bytes(blob))


def _usda_of(bakes: Path, edit) -> bytes:
    """The bake's USD as text, edited by edit(text)."""
    from pxr import Sdf

    return edit(Sdf.Layer.FindOrOpen(str(bakes / "c.usd")).ExportToString()).encode()


def _fifo_layer(d: Path) -> Path:
    """A USDA whose sublayer is a FIFO: USD's read of it waited for ever for a writer."""
    import os

    os.mkfifo(d / "pipe.usda")
    return _put(d / "f.usda", b"#usda 1.0\n(\n    subLayers = [@pipe.usda@]\n)\n")


def _glb_raw(json_bytes: bytes, rest: bytes) -> bytes:
    j = json_bytes + b" " * ((-len(json_bytes)) % 4)
    return b"glTF" + struct.pack("<II", 2, 20 + len(j) + len(rest)) + \
        struct.pack("<I", len(j)) + b"JSON" + j + rest


def _glb_overflow() -> bytes:
    data = bytearray(_glb_raw(b'{"asset": {"version": "2.0"}}', b""))
    data[12:16] = struct.pack("<I", 10 ** 6)
    return bytes(data)


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_unreadable_file_is_one_line_and_exit_2(case, bakes, tmp_path, capsys):
    make, word = BROKEN[case]
    path = make(tmp_path, bakes)
    for args in ([path], [path, "--json"]):
        code, out, err = run(args, capsys)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2, (case, out, err)
        assert len(lines) == 1 and "Traceback" not in err, err
        assert lines[0].startswith("Error: ") and word.lower() in lines[0].lower(), lines[0]
        assert out == ""


@pytest.mark.parametrize("case", ["truncated_usd", "garbage_usda", "bad_skin", "png",
                                  "crate_section_start"])
def test_unreadable_file_in_a_subprocess(case, bakes, tmp_path):
    """The console entry point: nothing of USD's or Python's own reaches stderr (a crate whose
    section starts past the file: USD's C++ code printed 'failed call to posix_madvise')."""
    path = BROKEN[case][0](tmp_path, bakes)
    r = subprocess.run([sys.executable, "-m", "baker", "inspect", str(path)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stdout == ""


def _glb_with(path: Path, edit) -> bytes:
    """The GLB at `path` with its JSON chunk edited by edit(doc) (the binary chunk as it was)."""
    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    edit(doc)
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    rest = data[20 + n:]
    return (struct.pack("<4sII", b"glTF", 2, 20 + len(js) + len(rest))
            + struct.pack("<I4s", len(js), b"JSON") + js + rest)


def test_judge_reads_the_motion_against_the_limits(bakes, capsys, tmp_path):
    """`inspect --judge` judges every creature of a GLB from the files alone (the USD beside it
    compared too) and exits 1 when a limit fails: here the same bake with its environment
    lifted 3 cm, the feet then deep in the ground."""
    code, out, err = run([bakes / "c.glb", "--judge", "--no-validate"], capsys)
    assert code == 0, err
    assert "1/1 creature(s) within every limit" in out and "glb_usd_max_m" in out
    code, out, _ = run([bakes / "c.glb", "--judge", "--no-validate", "--json"], capsys)
    (judged,) = json.loads(out)["judged"]
    assert code == 0 and judged["failures"] == []
    assert judged["values"]["rotation_max_deg"] < 30.0 and judged["values"]["glb_usd_max_m"] < 1e-4

    def lift(doc):
        env = next(n for n in doc["nodes"] if n.get("name") == "Environment")
        t = env.get("translation", [0.0, 0.0, 0.0])
        env["translation"] = [t[0], t[1] + 0.03, t[2]]

    sunk = tmp_path / "sunk.glb"
    sunk.write_bytes(_glb_with(bakes / "c.glb", lift))
    code, out, _ = run([sunk, "--judge", "--no-validate"], capsys)
    assert code == 1
    assert "foot_penetration_max_pct_bl" in out and "FAILS" in out
    assert "0/1 creature(s) within every limit; failing: 0" in out


def test_judge_needs_a_glb(bakes, capsys):
    code, out, err = run([bakes / "t.usda", "--judge"], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "--judge reads a GLB" in err


def _set_extras_fps(doc):
    doc["scenes"][doc.get("scene", 0)].setdefault("extras", {})["fps"] = "thirty"
    doc.setdefault("extras", {})["fps"] = "thirty"


def _environment_node_its_own_child(doc):
    env = next(i for i, n in enumerate(doc["nodes"]) if n.get("name") == "Environment")
    doc["nodes"][env]["children"] = [env]


@pytest.mark.parametrize("edit", [
    _set_extras_fps,
    lambda doc: doc["skins"][0].update(joints=[]),
    # the walk of the node hierarchy went on for ever (--judge and preview hung)
    _environment_node_its_own_child,
    lambda doc: doc["nodes"][doc["scenes"][0]["nodes"][0]].update(children=[True]),
], ids=["fps_not_a_number", "skin_without_joints", "node_its_own_child", "child_true"])
def test_judge_of_a_glb_it_cannot_play_is_one_line(edit, bakes, capsys, tmp_path):
    """A GLB plain inspect reads, whose motion --judge cannot play: one line, exit 2 (and
    `baker preview`'s the same)."""
    bad = tmp_path / "bad.glb"
    bad.write_bytes(_glb_with(bakes / "c.glb", edit))
    code, out, err = run([bad, "--judge", "--no-validate"], capsys)
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    if importlib.util.find_spec("matplotlib") and edit is not _set_extras_fps:
        code = main(["preview", str(bad), "--out", str(tmp_path / "p")])
        err = capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert not list(tmp_path.glob("p*"))


def _timeline_start_text(doc):
    doc["scenes"][doc.get("scene", 0)]["extras"]["timeline"][0]["start"] = "x"


def test_hand_edited_metadata_is_summarized(bakes, capsys, tmp_path):
    """A timeline event whose start is not a number (an edited file) counts no seconds; it
    raised ValueError (a traceback)."""
    p = tmp_path / "edited.glb"
    p.write_bytes(_glb_with(bakes / "c.glb", _timeline_start_text))
    code, out, err = run([p, "--no-validate"], capsys)
    assert code == 0 and "timeline" in out, err


def test_glb_json_with_nan_is_not_json(bakes, capsys, tmp_path):
    """NaN in a GLB's JSON chunk (Python's reader takes it; it is not JSON): one line, exit 2,
    for inspect, --json (it raised ValueError printing the report) and --judge."""
    p = tmp_path / "nan.glb"
    p.write_bytes(_glb_with(bakes / "c.glb", lambda d: d.setdefault("extras", {}).update(
        seed=float("nan"))))
    for extra in ([], ["--json"], ["--judge"]):
        code, out, err = run([p, "--no-validate", *extra], capsys)
        assert code == 2 and out == "", err
        assert len(err.splitlines()) == 1 and "not JSON" in err, err


def test_usd_custom_data_nan_prints_as_json(bakes, capsys, tmp_path):
    """A USD's customData may hold NaN: --json writes it as the string "nan" (json.dumps
    refused it: a traceback)."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(bakes / "c.usd"))
    world = stage.GetPrimAtPath("/World")
    world.SetCustomDataByKey("seed", float("nan"))
    p = tmp_path / "nan.usda"
    stage.GetRootLayer().Export(str(p))
    code, out, err = run([p, "--no-validate", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["metadata"]["seed"] == "nan"


def test_judge_with_a_corrupt_usd_beside_is_one_line(bakes, capsys, tmp_path):
    """--judge compares the GLB with the bake's USD beside it: a USD that does not open is one
    line naming it (pxr's Tf.ErrorException was a traceback)."""
    (tmp_path / "c.glb").write_bytes((bakes / "c.glb").read_bytes())
    (tmp_path / "c.usd").write_bytes(b"garbage\x00\x01" * 50)
    code, out, err = run([tmp_path / "c.glb", "--judge", "--no-validate"], capsys)
    assert code == 2 and out == "", err
    assert len(err.splitlines()) == 1 and "c.usd" in err and "Traceback" not in err, err
