"""The bad-input corpus (tests/tools/bad_inputs.py): every case is refused with exit code 2 and
exactly one stderr line `Error: <what> (<where>)`, leaves the out folder as it was (the previous
good outputs byte-identical, no temporary files), within 2 GB (no wall-clock limit: the
machines are shared).

Most cases run in-process through `baker.cli.main` (peak memory from tracemalloc, which sees
numpy's allocations); SUBPROCESS cases run as real processes running `baker.cli` as __main__
(through tests/tools/peak_rss.py, which reports the child's own peak RSS: ru_maxrss from
wait4 would carry pytest's). Files in other encodings that were refused before (Latin-1 OBJ, STL,
PLY) must load and bake.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

import bad_inputs
from baker.cli import main
from baker.config import FLOOR_ENVIRONMENT

CASES = {c.id: c for c in bad_inputs.all_cases()}
PEAK_RSS = Path(__file__).resolve().parents[1] / "tools" / "peak_rss.py"
ERROR_LINE = re.compile(r"^Error: \S.*$")
MAX_BYTES = 2 * 1024**3

#: cases run as real processes (the hostile sizes among them), the rest in-process
SUBPROCESS = [
    "glb_count_2e9_no_view", "glb_count_2e9", "glb_count_huge_indices", "glb_sparse_2e9_no_view",
    "glb_view_length_huge", "glb_buffer_length_huge", "glb_chunk_length_huge", "glb_json_deep",
    "glb_index_minus_5", "glb_node_translation_1e12", "stl_count_2e9", "stl_binary_nan",
    "ply_binary_vertex_2e9", "ply_ascii_vertex_2e9", "obj_nan_vertex", "gltf_bin_outside",
    "usd_sublayer_missing", "usd_reference_outside", "usd_syntax_error", "usd_face_index_past",
    "usd_reference_bad_prim", "usd_variant_reference_outside",
    "usd_crate_section_start", "usd_prims_60000_deep",
    "rig_legs_none", "rig_empty", "opt_sun_0_1e308,0,0",
    "opt_navmesh_from_nan", "opt_seconds_0_nan",
]


def bake_args(case, folder: Path, out: Path) -> list[str]:
    extra = [str(a) for a in case.make(folder)]
    if extra and extra[0] == "navmesh":
        return ["navmesh", str(FLOOR_ENVIRONMENT), "--no-cache", *extra[1:]]
    if extra and extra[0] == "batch":   # a jobs file; a refused one makes no output folder
        return ["batch", extra[1], "--out", str(out / "batch"), "--workers", "1",
                "--cache-dir", str(folder / "cache"), *extra[2:]]
    env = []
    if extra and not extra[0].startswith("--"):
        env, extra = [extra[0]], extra[1:]
    return ["bake", *env, "--out", str(out / "c"), "--seconds", "1", "--no-cache", *extra]


@pytest.fixture(scope="module")
def previous(tmp_path_factory) -> dict[str, bytes]:
    """A good bake's files (the small corpus scene), to pre-create in every case's out folder."""
    d = tmp_path_factory.mktemp("good")
    scene = d / "scene.glb"
    scene.write_bytes(bad_inputs.good_glb())
    code = main(["bake", str(scene), "--out", str(d / "out" / "c"), "--seconds", "1",
                 "--no-cache"])
    assert code == 0
    files = {p.name: p.read_bytes() for p in (d / "out").iterdir()}
    assert set(files) == {"c.glb", "c.usd", "c.json"}
    return files


def setup_case(tmp_path: Path, previous: dict[str, bytes]):
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    out.mkdir()
    for name, data in previous.items():
        (out / name).write_bytes(data)
    return folder, out


def check_refusal(code: int, err: str, out: Path, previous: dict[str, bytes]):
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert ERROR_LINE.match(lines[0]), lines[0]
    assert "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == previous  # nothing added or lost


IN_PROCESS = sorted(set(CASES) - set(SUBPROCESS))


def test_corpus_size():
    assert len(CASES) >= 200
    classes = {c.split("_")[0] for c in CASES}
    assert classes >= {"glb", "gltf", "obj", "stl", "ply", "usd", "rig", "opt"}
    assert set(SUBPROCESS) <= set(CASES)


@pytest.mark.parametrize("cid", IN_PROCESS)
def test_bad_input_in_process(cid, tmp_path, previous, capsys):
    folder, out = setup_case(tmp_path, previous)
    argv = bake_args(CASES[cid], folder, out)
    capsys.readouterr()
    tracemalloc.start()
    try:
        code = main(argv)
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    captured = capsys.readouterr()
    check_refusal(code, captured.err, out, previous)
    assert captured.out == ""
    assert peak < MAX_BYTES


@pytest.mark.parametrize("cid", SUBPROCESS)
def test_bad_input_subprocess(cid, tmp_path, previous):
    folder, out = setup_case(tmp_path, previous)
    argv = bake_args(CASES[cid], folder, out)
    errf, peakf = tmp_path / "stderr.txt", tmp_path / "peak.txt"
    with open(errf, "wb") as err_fh:
        r = subprocess.run([sys.executable, str(PEAK_RSS), "baker.cli", *argv],
                           stdout=subprocess.DEVNULL, stderr=err_fh, stdin=subprocess.DEVNULL,
                           cwd=tmp_path, env={**os.environ, "PEAK_RSS_FILE": str(peakf)})
    check_refusal(r.returncode, errf.read_text(), out, previous)
    peak = int(peakf.read_text())  # the child's own VmHWM (see tests/tools/peak_rss.py)
    assert 0 < peak < MAX_BYTES
    # nothing written in the working folder either (the case's own files aside)
    assert not [x for x in tmp_path.iterdir() if x.name.startswith(".") or "tmp" in x.name]


@pytest.mark.parametrize("cid", sorted(bad_inputs.GLB_EXPECT))
def test_node_hierarchy_messages_say_what_is_wrong(cid, tmp_path):
    """A scene listing a node twice said 'node 0 has two parents'."""
    from baker.environment import load_environment
    from baker.errors import EnvironmentLoadError

    (tmp_path / "in").mkdir()
    (path,) = CASES[f"glb_{cid}"].make(tmp_path / "in")
    with pytest.raises(EnvironmentLoadError) as e:
        load_environment(path)
    assert bad_inputs.GLB_EXPECT[cid] in str(e.value), str(e.value)
    assert "two parents" not in str(e.value)


@pytest.mark.parametrize("name", sorted(bad_inputs.GOOD_LATIN1))
def test_files_in_other_encodings_load(name, tmp_path):
    from baker.environment import load_environment

    p = tmp_path / name
    p.write_bytes(bad_inputs.GOOD_LATIN1[name])
    env = load_environment(p)
    assert sum(len(m.faces) for m in env.meshes) == 2


@pytest.mark.parametrize("name", sorted(bad_inputs.GOOD_UNUSUAL))
def test_unusual_but_valid_files_load(name, tmp_path):
    """Tabs between fields, indented lines, CRLF: the same floor as GOOD_OBJ."""
    from baker.environment import load_environment

    p = tmp_path / name
    p.write_bytes(bad_inputs.GOOD_UNUSUAL[name])
    plain = tmp_path / "plain.obj"
    plain.write_text(bad_inputs.GOOD_OBJ)
    env, ref = load_environment(p), load_environment(plain)
    assert np.array_equal(env.mesh.vertices, ref.mesh.vertices)
    assert np.array_equal(env.mesh.faces, ref.mesh.faces)


@pytest.mark.parametrize("name", sorted(bad_inputs.GOOD_UNUSUAL_GLTF))
def test_unusual_but_valid_gltf_load(name, tmp_path):
    """A byte order mark before the JSON, a data: URI's base64 in lines or unpadded: the same
    scene as the corpus's good GLB."""
    from baker.environment import load_environment

    p = tmp_path / name
    p.write_bytes(bad_inputs.GOOD_UNUSUAL_GLTF[name])
    plain = tmp_path / "plain.glb"
    plain.write_bytes(bad_inputs.good_glb())
    env, ref = load_environment(p), load_environment(plain)
    assert len(env.meshes) == len(ref.meshes)
    for a, b in zip(env.meshes, ref.meshes):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


@pytest.mark.parametrize("name", sorted(bad_inputs.GOOD_ASCII_STL))
def test_unusual_ascii_stl_load(name, tmp_path):
    """A solid named with STL's own words, lines ending in a lone CR: the floor once per
    solid, under its own name."""
    from baker.environment import load_environment

    data, names = bad_inputs.GOOD_ASCII_STL[name]
    p = tmp_path / name
    p.write_bytes(data)
    ref = tmp_path / "plain.stl"
    ref.write_bytes(bad_inputs.GOOD_LATIN1["latin1.stl"])
    env, plain = load_environment(p), load_environment(ref)
    assert [m.name for m in env.meshes] == names
    for m in env.meshes:
        assert np.array_equal(m.vertices, plain.mesh.vertices)
        assert np.array_equal(m.faces, plain.mesh.faces)


def test_latin1_obj_bakes(tmp_path, capsys):
    p = tmp_path / "latin1.obj"
    p.write_bytes(bad_inputs.GOOD_LATIN1["latin1.obj"])
    code = main(["bake", str(p), "--out", str(tmp_path / "o" / "c"), "--seconds", "1",
                 "--no-cache", "--format", "glb"])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "o" / "c.glb").stat().st_size > 0


def test_a_rig_whose_name_is_not_utf8_bakes(tmp_path, capsys):
    """A --rig path holding a byte that is not UTF-8 (Linux allows it): the USD's custom data
    keeps the path, and USD raised UnicodeEncodeError on it (a traceback after the bake). The
    byte is stored as its escape, as in the JSON report."""
    from baker.config import DEFAULT_RIG

    scene, rig = tmp_path / "scene.glb", tmp_path / os.fsdecode(b"r\xff.toml")
    scene.write_bytes(bad_inputs.good_glb())
    rig.write_bytes(DEFAULT_RIG.read_bytes())
    code = main(["bake", str(scene), "--rig", str(rig), "--out", str(tmp_path / "o" / "c"),
                 "--seconds", "1", "--no-cache"])
    assert code == 0, capsys.readouterr().err
    from pxr import Usd

    stage = Usd.Stage.Open(str(tmp_path / "o" / "c.usd"))
    source = stage.GetPrimAtPath("/World").GetCustomData()["rig"]["source"]
    assert source.endswith("r\\udcff.toml"), source


def test_one_key_sun_path_is_a_fixed_sun(tmp_path):
    """A --sun-path of one key is a fixed sun: used by the creature and written to both files
    like --sun."""
    from baker.config import BakeConfig, validate_bake
    from baker.geometry.transforms import direction_from_angles

    import numpy as np

    cfg = validate_bake(BakeConfig(sun_path="90,30"))
    assert cfg.sun_path is None
    expect = direction_from_angles(np.radians([90.0]), np.radians([30.0]))[0]
    np.testing.assert_allclose(cfg.sun_direction, expect)
    same = validate_bake(BakeConfig(sun_direction=tuple(expect)))
    assert same == cfg



def test_one_key_sun_path_bakes_like_sun(tmp_path, capsys):
    """Both files of a one-key --sun-path bake are byte-identical to those of the same fixed
    --sun (which the writers export as the scene's light)."""
    from baker.geometry.transforms import direction_from_angles

    import numpy as np

    scene = tmp_path / "scene.glb"
    scene.write_bytes(bad_inputs.good_glb())
    d = direction_from_angles(np.radians([90.0]), np.radians([30.0]))[0]
    common = ["bake", str(scene), "--seconds", "1", "--no-cache"]
    assert main([*common, "--out", str(tmp_path / "a" / "c"), "--sun-path", "90,30"]) == 0
    assert main([*common, "--out", str(tmp_path / "b" / "c"),
                 "--sun", ",".join(repr(float(x)) for x in d)]) == 0
    for ext in ("glb", "usd"):
        assert (tmp_path / "a" / f"c.{ext}").read_bytes() == \
            (tmp_path / "b" / f"c.{ext}").read_bytes()


OBJ_QUAD = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nusemtl m\nf 1 3 2\nf 1 4 3\n"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("side", ["mtllib", "map_Kd"])
def test_an_obj_side_file_that_is_a_fifo_is_missing_not_waited_for(side, tmp_path):
    """An OBJ's material library or texture naming a FIFO in its folder: opening a FIFO blocks
    until a writer comes, and the load hung; it is a missing side file (the mesh loads)."""
    os.mkfifo(tmp_path / "pipe")
    if side == "mtllib":
        (tmp_path / "level.obj").write_text("mtllib pipe\n" + OBJ_QUAD)
    else:
        (tmp_path / "m.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nmap_Kd pipe\n")
        (tmp_path / "level.obj").write_text("mtllib m.mtl\n" + OBJ_QUAD)
    code = ("from baker.environment.load import load_environment; "
            f"env = load_environment({str(tmp_path / 'level.obj')!r}); "
            "print(sum(len(m.faces) for m in env.meshes))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "2"
