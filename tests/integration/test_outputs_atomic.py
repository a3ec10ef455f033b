"""A bake's outputs are all or nothing (baker/atomic.py OutputSet), checked with real bakes.

Each bad case asserts: the exit code, exactly one stderr line matching a pattern, no leftover or
temporary files, the previous good outputs byte-identical, and the child's peak memory.
Good outputs are baked once per session (`--seconds 1`) and copied for each case."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from bakeproc import Bake, run, seeds_of, snapshot

from baker.cli import main

PEAK_MB = 2048
ERROR = re.compile(r"^error: .+", re.IGNORECASE)
FILES = ["centipede.glb", "centipede.json", "centipede.usd"]


def bake_args(out, cache, seed=1, *extra):
    return ["bake", "--seconds", "1", "--seed", str(seed), "--out", str(out),
            "--cache-dir", str(cache), *extra]


@pytest.fixture(scope="session")
def good_outputs(tmp_path_factory, nav_cache_dir) -> Path:
    """A folder holding one good bake (seed 1), made with `--out <folder>/`."""
    folder = tmp_path_factory.mktemp("good")
    done = run(bake_args(f"{folder}{os.sep}", nav_cache_dir))
    assert done.code == 0, done.stderr
    assert sorted(p.name for p in folder.iterdir()) == FILES
    return folder


@pytest.fixture
def out_dir(tmp_path, good_outputs) -> Path:
    d = tmp_path / "out"
    shutil.copytree(good_outputs, d)
    return d


def assert_one_line(done, pattern=ERROR, code=2):
    assert done.code == code, (done.code, done.stderr)
    assert "Traceback" not in done.stderr
    assert len(done.err_lines) == 1, done.stderr
    assert pattern.search(done.err_lines[0]), done.err_lines[0]
    assert done.peak_mb < PEAK_MB


def test_out_folder_with_trailing_slash_writes_into_it(good_outputs):
    """The session's good bake used `--out <folder>/`: the files are inside, named centipede."""
    assert seeds_of(good_outputs / "centipede") == {"json": 1, "glb": 1, "usd": 1}
    for p in good_outputs.iterdir():
        assert p.stat().st_mode & 0o044, p     # not mkstemp's 0600


# ----------------------------------------------------------------------------- fail early
def _preflight_cases():
    """(id, setup(folder) -> --out value, words expected in the message). Generated over the
    three output names and several shapes of bad path."""
    cases = []
    for name in FILES:
        ext = name.split(".", 1)[1]

        def folder_in_the_way(d, name=name):
            (d / name).unlink()
            (d / name).mkdir()
            return d / "centipede"
        cases.append((f"{ext}-is-a-folder", folder_in_the_way, ["folder"]))
    for n in (256, 300, 1000):
        cases.append((f"name-{n}-chars", lambda d, n=n: d / ("x" * n), ["too long"]))
    cases.append(("name-fits-but-not-json", lambda d: d / ("y" * 252), ["too long"]))
    cases.append(("parent-is-a-file", lambda d: d / "centipede.json" / "x", ["folder"]))
    cases.append(("deep-under-a-file", lambda d: d / "centipede.glb" / "a" / "b" / "x", ["folder"]))
    cases.append(("empty", lambda d: "", ["--out"]))
    cases.append(("blank", lambda d: "   ", ["--out"]))
    return cases


PREFLIGHT = _preflight_cases()


@pytest.mark.parametrize("setup,words", [c[1:] for c in PREFLIGHT], ids=[c[0] for c in PREFLIGHT])
def test_unwritable_outputs_fail_before_any_work(out_dir, setup, words, capsys, monkeypatch,
                                                 nav_cache_dir):
    """Checked before the level is loaded: the pipeline is never entered."""
    import baker.pipeline

    out = setup(out_dir)
    before = snapshot(out_dir)

    def no_bake(*a, **k):
        raise AssertionError("the bake started although its outputs cannot be written")

    monkeypatch.setattr(baker.pipeline, "bake", no_bake)
    code = main(bake_args(out, nav_cache_dir))
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and ERROR.search(lines[0]), err
    for w in words:
        assert w in lines[0].lower(), lines[0]
    assert snapshot(out_dir) == before


# ----------------------------------------------------------------------------- fail late
@pytest.mark.slow
@pytest.mark.parametrize("victim,phase", [("centipede.usd", "write:usd"),
                                          ("centipede.json", "commit"),
                                          ("centipede.glb", "commit")])
def test_target_turned_folder_during_the_bake_keeps_every_old_file(out_dir, nav_cache_dir,
                                                                   victim, phase):
    """The issue's case: the USD path is a folder once the GLB is written. Nothing is
    renamed: the other old files stay byte-identical, no temporary is left."""
    before = snapshot(out_dir)
    b = Bake(bake_args(out_dir / "centipede", nav_cache_dir, 7), pause_at=phase)
    assert b.wait_marker(phase)
    (out_dir / victim).unlink()
    (out_dir / victim).mkdir()
    b.signal(signal.SIGUSR1)                    # resume
    done = b.wait()
    assert_one_line(done)
    assert "folder" in done.err_lines[0]
    after = snapshot(out_dir)
    assert after.pop(victim) == b"<dir>"
    before.pop(victim)
    assert after == before


@pytest.mark.slow
def test_concurrent_bakes_into_one_out_leave_files_of_one_run(out_dir, nav_cache_dir):
    """Two bakes with different seeds, held just before their commits and released together:
    the folder lock makes one commit wait for the other, so every file has the same seed."""
    bakes = [Bake(bake_args(out_dir / "centipede", nav_cache_dir, s), pause_at="commit")
             for s in (11, 12)]
    for b in bakes:
        assert b.wait_marker("commit")
    for b in bakes:
        b.signal(signal.SIGUSR1)
    dones = [b.wait() for b in bakes]
    for d in dones:
        assert d.code == 0, d.stderr
        assert d.peak_mb < PEAK_MB
    seeds = seeds_of(out_dir / "centipede")
    assert len(set(seeds.values())) == 1 and seeds["json"] in (11, 12), seeds
    assert sorted(p.name for p in out_dir.iterdir()) == FILES


@pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin",
                    reason="RLIMIT_FSIZE on Linux")
@pytest.mark.parametrize("fmt", ["usd", "both"])
def test_a_full_disk_is_one_line_and_keeps_the_previous_files(out_dir, nav_cache_dir, fmt):
    """An output's write fails part way (the file-size limit stands in for a full disk: Python
    ignores SIGXFSZ, so the write gets EFBIG; USD raised its own multi-line error): one line
    naming the file and the reason, exit 2, no temporary, and the previous files
    byte-identical."""
    import resource

    before = snapshot(out_dir)
    limit = len(before["centipede.usd"]) // 2

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    done = subprocess.run(
        [sys.executable, "-m", "baker", *bake_args(f"{out_dir}{os.sep}", nav_cache_dir, 2,
                                                   "--format", fmt)],
        capture_output=True, text=True, preexec_fn=small_files)
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    named = ["centipede.usd"] if fmt == "usd" else ["centipede.usd", "centipede.glb"]
    assert "File too large" in lines[0] and any(n in lines[0] for n in named), lines[0]
    assert snapshot(out_dir) == before
