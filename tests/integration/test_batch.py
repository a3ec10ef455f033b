"""`baker batch` end to end: a 12-job batch (3 seeds x 2 environments x 2 behaviours, 1 s
bakes: the bundled rainforest floor and a small level built in code) on the local pool; a
second run skips all 12; changing one option re-bakes only the jobs it touches; a broken job
fails while the other 11 bake; the same batch on a Dask scheduler with two workers (loopback)
gives byte-identical files; SIGTERM half way, then a run that completes it."""

from __future__ import annotations

import json
import os
import re
import selectors
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from baker.cli import main
from baker.config import FLOOR_ENVIRONMENT
from batch_jobs import NAMES_12, digests, manifest, stray_files, write_jobs

#: A line that never comes within this long means the batch is broken (not a time limit on
#: the bakes: each wait is for an event the batch announces).
EVENT_WAIT_S = 300.0


def run_cli(args, capsys):
    code = main(["batch", *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def stamps(out: Path) -> dict[str, int]:
    return {p.name: p.stat().st_mtime_ns for p in out.iterdir() if not p.name.startswith(".")
            and p.name != "manifest.json"}


def expected_files(names, formats=(".glb", ".usd", ".json")) -> set[str]:
    return {n + s for n in names for s in formats} | {"manifest.json"}


def run_captured(args) -> tuple[int, str, str]:
    """`baker` in this process with stdout and stderr captured (for module fixtures)."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def first(tmp_path_factory, nav_cache_dir):
    """The 12-job batch on 2 local workers: (folder, out, stdout, stderr, GLB/USD digests)."""
    folder = tmp_path_factory.mktemp("batch")
    code, out, err = run_captured(["batch", write_jobs(folder), "--out", folder / "out",
                                   "--workers", "2", "--cache-dir", nav_cache_dir])
    assert code == 0, err
    return folder, folder / "out", out, err, digests(folder / "out")


def test_first_run_bakes_every_job(first):
    folder, out, stdout, stderr, _ = first
    m = manifest(out)
    assert list(m["jobs"]) == NAMES_12
    assert m["summary"] == {"jobs": 12, "baked": 12, "skipped": 0, "failed": 0, "pending": 0}
    assert {p.name for p in out.iterdir()} == expected_files(NAMES_12)
    assert stray_files(out) == []
    for name, e in m["jobs"].items():
        assert e["status"] == "baked" and e["error"] is None and e["attempts"] == 1
        assert len(e["key"]) == 64 and e["worker"] and e["wall_s"] > 0
        # each output as the manifest records it
        for fmt, rec in e["outputs"].items():
            assert (out / rec["path"]).stat().st_size == rec["bytes"]
        assert e["metrics"]["frames"] == 31 and e["metrics"]["frames_on_unwalkable_slope"] == 0
        # navigation was built (or loaded) once per environment, before the jobs
        assert e["navmesh_cache_hit"] is True
        assert json.loads((out / f"{name}.json").read_text())["navmesh_cache_hit"] is True
    assert [n["status"] for n in m["navigation"]] == ["ready", "ready"]
    assert digests(out)["forest-seed0-wander.glb"] != digests(out)["forest-seed1-wander.glb"]
    # piped: plain lines, one per job, and one summary line on stdout
    assert sum(" baked " in ln for ln in stderr.splitlines()) == 12
    line, = stdout.strip().splitlines()
    assert re.fullmatch(r"batch: 12 jobs, 12 baked, 0 up to date, 0 failed in [0-9.]+ s -> "
                        + re.escape(str(out / "manifest.json")), line), line


def test_outputs_pass_the_validators(first):
    from pxr import Usd
    from validator import gltf_validate, issues_summary, usd_validate

    out = first[1]
    report = gltf_validate(out / "small-seed1-hunt.glb")
    assert issues_summary(report, 0) == [] and report["issues"]["numWarnings"] == 0
    assert usd_validate(Usd.Stage.Open(str(out / "forest-seed2-wander.usd"))) == []


def test_second_run_skips_all_then_one_option_rebakes_only_its_jobs(first, capsys,
                                                                      nav_cache_dir):
    folder, out, *_ = first
    before = stamps(out)
    code, stdout, _ = run_cli([folder / "jobs.toml", "--out", out, "--cache-dir", nav_cache_dir],
                              capsys)
    assert code == 0
    assert "12 jobs, 0 baked, 12 up to date, 0 failed" in stdout
    m = manifest(out)
    assert {e["status"] for e in m["jobs"].values()} == {"skipped"}
    assert stamps(out) == before                        # not one file rewritten
    # the small level's jobs get 1.5 s instead of 1 s
    changed = write_jobs(folder, "jobs2.toml", small_seconds=1.5)
    code, stdout, _ = run_cli([changed, "--out", out, "--workers", "2",
                               "--cache-dir", nav_cache_dir], capsys)
    assert code == 0
    assert "12 jobs, 6 baked, 6 up to date, 0 failed" in stdout
    m = manifest(out)
    after = stamps(out)
    for name, e in m["jobs"].items():
        small = name.startswith("small")
        assert e["status"] == ("baked" if small else "skipped"), name
        for suffix in (".glb", ".usd", ".json"):
            assert (after[name + suffix] != before[name + suffix]) == small, name + suffix
        if small:
            assert e["metrics"]["frames"] == 46


@pytest.mark.slow
def test_a_broken_job_fails_and_the_other_11_bake(tmp_path, capsys, nav_cache_dir):
    write_jobs(tmp_path)        # small.obj
    jobs = tmp_path / "broken.toml"
    jobs.write_text(f"""
[defaults]
seconds = 1
prey = 0

[[job]]
name = "forest"
environment = "{FLOOR_ENVIRONMENT.as_posix()}"
[job.matrix]
seed = [0, 1, 2]
behaviour = ["wander", "hunt"]

[[job]]
name = "small-seed{{seed}}-{{behaviour}}"
environment = "small.obj"
[job.matrix]
seed = [0, 1, 2]
behaviour = ["wander"]

[[job]]
name = "small-seed{{seed}}-{{behaviour}}"
environment = "small.obj"
behaviour = "hunt"
[job.matrix]
seed = [0, 1]

[[job]]
name = "small-seed2-hunt"
environment = "broken.glb"
behaviour = "hunt"
seed = 2
""")
    (tmp_path / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00" + b"\x00" * 40)
    out = tmp_path / "out"
    code, stdout, stderr = run_cli([jobs, "--out", out, "--workers", "2",
                                    "--cache-dir", nav_cache_dir], capsys)
    assert code == 1, stderr
    assert "12 jobs, 11 baked, 0 up to date, 1 failed" in stdout
    m = manifest(out)
    assert sorted(m["jobs"]) == sorted(NAMES_12)
    bad = m["jobs"]["small-seed2-hunt"]
    assert bad["status"] == "failed" and bad["outputs"] == {}
    assert bad["error"].startswith("navigation surface: ") and "broken.glb" in bad["error"]
    assert m["summary"] == {"jobs": 12, "baked": 11, "skipped": 0, "failed": 1, "pending": 0}
    assert {p.name for p in out.iterdir()} == \
        expected_files(set(NAMES_12) - {"small-seed2-hunt"})
    assert stray_files(out) == []
    assert "failed small-seed2-hunt: navigation surface: " in stderr
    # again: the 11 are up to date, the broken one fails again
    code, stdout, _ = run_cli([jobs, "--out", out, "--cache-dir", nav_cache_dir], capsys)
    assert code == 1 and "0 baked, 11 up to date, 1 failed" in stdout


def test_job_timeout(tmp_path, capsys, nav_cache_dir):
    from batch_jobs import write_small_level

    write_small_level(tmp_path / "small.obj")
    (tmp_path / "j.toml").write_text('[[job]]\nname = "long"\nenvironment = "small.obj"\n'
                                     "seconds = 120\n")
    code, stdout, _ = run_cli([tmp_path / "j.toml", "--out", tmp_path / "o", "--job-timeout", 1,
                               "--cache-dir", nav_cache_dir], capsys)
    assert code == 1
    e = manifest(tmp_path / "o")["jobs"]["long"]
    assert e["status"] == "failed" and e["error"].startswith("timed out after 1 s (--job-timeout)")
    assert e["attempts"] == 1
    assert {p.name for p in (tmp_path / "o").iterdir()} == {"manifest.json"}   # no lock left


# ----------------------------------------------------------------------------- Dask
def _start(args, log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=log.open("wb"),
                            stderr=subprocess.STDOUT, start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)


@pytest.mark.slow
def test_dask_scheduler_and_two_workers_give_the_same_bytes(first, tmp_path, nav_cache_dir):
    pytest.importorskip("distributed")
    folder, _, _, _, local = first
    info = tmp_path / "scheduler.json"
    procs = [_start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                     "--scheduler-file", str(info)], tmp_path / "scheduler.log")]
    try:
        end = time.monotonic() + EVENT_WAIT_S
        while not info.exists() and time.monotonic() < end and procs[0].poll() is None:
            time.sleep(0.1)
        assert info.exists(), (tmp_path / "scheduler.log").read_text()
        procs.append(_start(["worker", "--scheduler-file", str(info), "--nworkers", "2",
                             "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1",
                             "--memory-limit", "0", "--death-timeout", "60",
                             "--local-directory", str(tmp_path / "dask")],
                            tmp_path / "worker.log"))
        address = json.loads(info.read_text())["address"]
        out = tmp_path / "out"
        r = subprocess.run([sys.executable, "-m", "baker", "batch", folder / "jobs.toml",
                            "--out", out, "--scheduler", address, "--cache-dir", nav_cache_dir],
                           capture_output=True, text=True, timeout=EVENT_WAIT_S)
        assert r.returncode == 0, r.stderr
        assert "12 baked" in r.stdout
        assert f"on Dask scheduler {address}" in r.stderr
        m = manifest(out)
        workers = {e["worker"] for e in m["jobs"].values()}
        assert all(w.startswith("tcp://127.0.0.1:") for w in workers)
        assert digests(out) == local                       # byte-identical GLB and USD
        assert stray_files(out) == []
    finally:
        for p in reversed(procs):
            _stop(p)


# ----------------------------------------------------------------------------- SIGTERM
def _read_until(proc, want: int, lines: list[str]) -> None:
    """Read the batch's stderr until `want` jobs are baked."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stderr, selectors.EVENT_READ)
    end = time.monotonic() + EVENT_WAIT_S
    while sum(" baked " in ln for ln in lines) < want:
        assert time.monotonic() < end and proc.poll() is None, "".join(lines)
        if sel.select(timeout=0.5):
            lines.append(proc.stderr.readline().decode())


@pytest.mark.slow
def test_sigterm_half_way_then_run_again(first, tmp_path, nav_cache_dir):
    """The small level's 6 jobs (of the 12), stopped once 2 are baked. One worker, so the jobs
    run one after another and the signal comes with four still to do. With two workers it
    failed once in a fresh clone's third full run (not reproduced in 8 runs alone, 5 of them
    beside 3 busy processes); the likely cause: the 1 s bakes of two workers can finish the
    batch while a loaded machine delays the test's reading of the progress lines."""
    folder, _, _, _, local = first
    text = (folder / "jobs.toml").read_text()
    jobs = folder / "small.toml"
    jobs.write_text(text[:text.index("[[job]]")] + text[text.index('[[job]]\nname = "small"'):])
    names = [n for n in NAMES_12 if n.startswith("small")]
    out = tmp_path / "out"
    args = [sys.executable, "-m", "baker", "batch", jobs, "--out", out, "--workers", "1",
            "--cache-dir", nav_cache_dir]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    lines: list[str] = []
    _read_until(proc, 2, lines)
    proc.send_signal(signal.SIGTERM)
    rest = proc.stderr.read().decode()
    proc.wait(EVENT_WAIT_S)
    assert proc.returncode == 143, rest
    assert rest.strip().splitlines()[-1] == "Error: interrupted by SIGTERM (during batch)"
    assert "Traceback" not in rest
    assert stray_files(out) == []
    m = manifest(out)
    assert list(m["jobs"]) == names
    done = {n for n, e in m["jobs"].items() if e["status"] == "baked"}
    assert 2 <= len(done) < 6
    assert {e["status"] for n, e in m["jobs"].items() if n not in done} == {"pending"}
    # each job's files are all there or none (a job whose commit finished as the signal came
    # may be on disk but not yet in the manifest: it is baked again, whole)
    files = {p.name for p in out.iterdir()} - {"manifest.json"}
    for name in names:
        have = {s for s in (".glb", ".usd", ".json") if name + s in files}
        assert have in (set(), {".glb", ".usd", ".json"}), (name, have)
        if name in done:
            assert have
    r = subprocess.run(args, capture_output=True, text=True, timeout=EVENT_WAIT_S)
    assert r.returncode == 0, r.stderr
    m = manifest(out)
    assert {n for n, e in m["jobs"].items() if e["status"] == "skipped"} == done
    assert {n for n, e in m["jobs"].items() if e["status"] == "baked"} == set(names) - done
    assert {p.name for p in out.iterdir()} == expected_files(names)
    assert stray_files(out) == []
    assert digests(out) == {k: v for k, v in local.items() if k.startswith("small")}
