"""Bad input: exit code 2, one line naming the problem, no traceback, no partial outputs, and a
previous good output survives."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from baker.cli import main


def run_cli(args, capsys):
    code = main(["bake", *map(str, args)])
    err = capsys.readouterr().err
    return code, err


def listing(folder: Path):
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def assert_user_error(code, err, *words):
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w.lower() in lines[0].lower(), lines[0]


def steep_plane(path: Path):
    a = np.radians(70)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, np.tan(a), 1], [0, np.tan(a), 1]], float)
    trimesh.Trimesh(v, [[0, 2, 1], [0, 3, 2]], process=False).export(path)


def put(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def steep(path: Path) -> Path:
    steep_plane(path)
    return path


CASES = {
    "missing": (lambda d: d / "nope.glb", ["not found"]),
    "extension": (lambda d: put(d / "scene.xyz", b"1 2 3"), ["xyz"]),
    "corrupt_glb": (lambda d: put(d / "bad.glb", b"glTF\x02\x00\x00\x00garbage"), ["bad.glb"]),
    "corrupt_obj": (lambda d: put(d / "bad.obj", b"\x00\xff\xfe v 1 2\nf 9 9 9\n\x00"), ["bad.obj"]),
    "no_faces": (lambda d: put(d / "pts.obj", b"v 0 0 0\nv 1 0 0\nv 0 0 1\n"), ["face"]),
    "no_walkable": (lambda d: steep(d / "steep.stl"), ["walkable"]),
    # a directory (an empty argument is the current one) is named as one, whatever its name
    "folder": (lambda d: d, ["directory"]),
    "folder_named_glb": (lambda d: (d / "level.glb").mkdir() or d / "level.glb", ["directory"]),
    "empty_argument": (lambda d: "", ["directory", "environment"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_environment_is_a_clean_user_error(case, tmp_path, capsys):
    make, words = CASES[case]
    env = make(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    code, err = run_cli([env, "--out", out / "c", "--seconds", 1, "--no-cache"], capsys)
    assert_user_error(code, err, *words)
    assert listing(out) == []


@pytest.mark.parametrize("args,word", [
    (["--seconds", 0], "--seconds"),
    (["--seconds", -3], "--seconds"),
    (["--fps", 0], "--fps"),
    (["--fps", -30], "--fps"),
    (["--fps", 100000], "--fps"),
    (["--fps", 7], "--fps"),
    (["--sun", "1,2"], "--sun"),
    (["--format", "fbx"], "format"),
])
def test_bad_options_are_clean_user_errors(args, word, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    code, err = run_cli(["--out", out / "c", *args], capsys)
    assert_user_error(code, err, word)
    assert listing(out) == []


def test_unwritable_output_folder(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code, err = run_cli(["--out", blocker / "sub" / "c", "--seconds", 1, "--no-cache"], capsys)
    assert_user_error(code, err, "output")


def test_running_out_of_memory_is_one_line(tmp_path, capsys, monkeypatch, nav_cache_dir):
    """An allocation that fails part way (a rig or level asking for more than the process may
    use) is one line naming memory and what to change, exit 2, and no output."""
    import baker.pipeline

    def too_big(*args, **kw):
        raise MemoryError("Unable to allocate 1.78 GiB for an array with shape (309031, 258, 3)")

    monkeypatch.setattr(baker.pipeline, "simulate_creatures", too_big)
    code, err = run_cli(["--out", tmp_path / "c", "--seconds", 1, "--cache-dir",
                         nav_cache_dir], capsys)
    assert_user_error(code, err, "out of memory", "1.78 GiB", "--cell-size", "(memory)")
    assert listing(tmp_path) == []

    def bare(*args, **kw):
        raise MemoryError()

    monkeypatch.setattr(baker.pipeline, "simulate_creatures", bare)
    code, err = run_cli(["--out", tmp_path / "c", "--seconds", 1, "--cache-dir",
                         nav_cache_dir], capsys)
    assert_user_error(code, err, "out of memory (an allocation failed)")


@pytest.mark.slow
def test_failed_bake_keeps_previous_output(tmp_path, capsys, nav_cache_dir):
    out = tmp_path / "c"
    code, _ = run_cli(["--out", out, "--seconds", 1, "--cache-dir", nav_cache_dir], capsys)
    assert code == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert set(before) == {"c.glb", "c.usd", "c.json"}
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF-broken")
    before["bad.glb"] = bad.read_bytes()
    code, err = run_cli([bad, "--out", out, "--seconds", 1, "--no-cache"], capsys)
    assert code == 2
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == before


def test_console_script_error_has_no_traceback(tmp_path):
    r = subprocess.run([sys.executable, "-m", "baker.cli", "bake", str(tmp_path / "missing.obj")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args", [["--help"], ["inspect", "--help"], ["bake", "--seconds", "1"]],
                         ids=["help", "inspect_help", "bake"])
def test_standard_output_on_a_full_disk_is_one_line(args, tmp_path, nav_cache_dir):
    """stdout on a full disk (/dev/full): one line on stderr and exit 2, not a traceback; a
    bake's files are committed before its summary is printed, and stay."""
    out = tmp_path / "o" / "c"
    extra = ["--out", str(out), "--cache-dir", str(nav_cache_dir)] if args[0] == "bake" else []
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "baker", *args, *extra], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr[-3000:]
    assert len(lines) == 1 and lines[0].startswith("Error: cannot write to standard output"), lines
    if args[0] == "bake":
        assert out.with_suffix(".glb").stat().st_size > 0 and out.with_suffix(".json").exists()


@pytest.mark.parametrize("value", ["0", "-2", "abc", ""])
def test_a_bad_numba_thread_count_is_one_line(value, tmp_path):
    """NUMBA_NUM_THREADS, read by numba as baker's kernels are imported: 0 was a ValueError
    traceback, a word a warning of many lines (numba's traceback in it) before the bake went on.
    Refused before any work, nothing written."""
    import os

    r = subprocess.run([sys.executable, "-m", "baker", "bake", "--seconds", "1", "--out",
                        str(tmp_path / "o" / "c"), "--no-cache"], capture_output=True, text=True,
                       env={**os.environ, "NUMBA_NUM_THREADS": value}, timeout=600)
    assert_user_error(r.returncode, r.stderr, "NUMBA_NUM_THREADS")
    assert listing(tmp_path) == []
