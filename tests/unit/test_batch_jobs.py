"""`baker batch` without baking: the jobs file (matrix, names, every error listed in one line),
job keys, the coordinator's isolation and retries (on a scripted pool), progress output, and a
local pool process that dies."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import click
import pytest

from baker import batch
from baker.cli import main
from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, BakeConfig, load_rig_config
from baker.errors import ConfigError, JobsFileError
from batch_jobs import NAMES_12, write_jobs, write_small_level


def run_cli(args, capsys):
    code = main(["batch", *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


# ----------------------------------------------------------------------------- jobs file
def test_matrix_expands_to_named_jobs(tmp_path):
    plan = batch.load_plan(write_jobs(tmp_path), tmp_path / "out")
    assert [j.name for j in plan.jobs] == NAMES_12
    by_name = {j.name: j.cfg for j in plan.jobs}
    cfg = by_name["small-seed2-hunt"]
    assert (cfg.seed, cfg.behaviour, cfg.seconds) == (2, "hunt", 1.0)
    assert cfg.environment == (tmp_path / "small.obj").resolve()
    assert cfg.out == (tmp_path / "out" / "small-seed2-hunt").resolve()
    assert by_name["forest-seed0-wander"].environment == FLOOR_ENVIRONMENT
    # one navigation group per environment (same rig and agent)
    assert len(plan.nav_groups) == 2
    assert {j.nav for j in plan.jobs if j.name.startswith("small")} == {1}
    # all keys differ (seed, behaviour or environment)
    assert len({j.key for j in plan.jobs}) == 12


def test_name_templates_and_unnamed_entries(tmp_path):
    write_small_level(tmp_path / "small.obj")
    (tmp_path / "j.toml").write_text("""
[[job]]
name = "{environment}_s{seed}_{behaviour}"
environment = "small.obj"
behaviour = "shade"
[job.matrix]
seed = [4, 5]

[[job]]
environment = "small.obj"
format = "glb"
usda = true
sun = "0.3,1,0.2"
""")
    plan = batch.load_plan(tmp_path / "j.toml", tmp_path / "o")
    assert [j.name for j in plan.jobs] == ["small_s4_shade", "small_s5_shade", "job2"]
    cfg = plan.jobs[2].cfg
    assert cfg.formats == ("glb",) and cfg.sun_direction == (0.3, 1.0, 0.2)


def test_every_error_is_listed_in_one_line(tmp_path, capsys):
    write_small_level(tmp_path / "small.obj")
    (tmp_path / "bad.toml").write_text("""
[defaults]
seconds = 1
out = "somewhere"

[[job]]
name = "a"
environment = "small.obj"
seed = -1
fps = 7

[[job]]
name = "b"
environment = "missing.glb"
sed = 3

[[job]]
name = "c"
environment = "small.obj"
[job.matrix]
behaviour = ["wander", "sleep"]
max_slope = [30, 95]

[[job]]
name = "d"
environment = "small.obj"

[[job]]
name = "d"
""")
    code, out, err = run_cli([tmp_path / "bad.toml", "--out", tmp_path / "o"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    line = lines[0]
    assert line.startswith("Error: jobs file has 8 errors: (1) ")
    for part in ["[defaults]: out is one per batch: use `baker batch --out`",
                 "job 'a': seed = -1: expected an integer",
                 "job 'a': fps 7 is not supported",
                 "job 'b': environment: file not found:",
                 "job 'b': unknown key 'sed'; did you mean 'seed'?",
                 'job \'c\': matrix.behaviour[1]: behaviour = "sleep": expected one of auto, '
                 "wander, shade, hunt",
                 "job 'c': matrix.max_slope[1]: max_slope = 95.0: expected a finite number in "
                 "(0, 90) [deg]",
                 "job 'd': name 'd' is used twice (also by job 'd')"]:
        assert part in line, part
    assert line.endswith(f"({tmp_path / 'bad.toml'})")
    assert not (tmp_path / "o").exists()        # nothing was started


@pytest.mark.parametrize("text,words", [
    ("[[job]]\nseed = ", "not valid TOML"),
    ("[[job]]\nseed = " + "[" * 5000 + "]" * 5000 + "\n", "nest too deeply"),
    ("[defaults]\nseed = 1\n", "no [[job]] entries"),
    ("[job]\nseed = 1\n", "write [[job]], not [job]"),
    ("[[jobs]]\nseed = 1\n", "unknown table 'jobs'; did you mean 'job'?"),
    ("[[job]]\nname = 'manifest'\n", "taken by the batch's manifest.json"),
    ("[[job]]\nname = 'x y/z'\n[job.matrix]\nseed = []\n", "matrix.seed = []: expected a "
                                                          "non-empty list"),
    ("[[job]]\nname = '{seeed}'\n", "name template: 'seeed' is not a job key"),
    ("[[job]]\nseed = 1\nname = '{seed:>3000000000}'\n",       # would pad the name to 3 GB
     "'{seed:>3000000000}' is not a plain {key} field"),
    ("[[job]]\nname = '{seed.__class__.__mro__}'\n", "'{seed.__class__.__mro__}' is not a plain"),
    ("[[job]]\nname = '{environment!r}'\n", "'{environment!r}' is not a plain {key} field"),
    ("[[job]]\nrig = 'nope.toml'\n", "job #1: rig: file not found"),
    ("[[job]]\nenvironment = 'jobs.toml'\n", "environment: unsupported format '.toml'"),
])
def test_jobs_file_errors(tmp_path, capsys, text, words):
    (tmp_path / "jobs.toml").write_text(text)
    code, _, err = run_cli([tmp_path / "jobs.toml", "--out", tmp_path / "o"], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert words in err, err


def test_a_long_name_is_shown_short(tmp_path, capsys):
    """A name of a million characters: the error line names it cut (it was 20 kB long)."""
    (tmp_path / "jobs.toml").write_text("[[job]]\nname = '" + "x" * 1_000_000 + "'\n")
    code, _, err = run_cli([tmp_path / "jobs.toml", "--out", tmp_path / "o"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err[:500]
    assert "1,000,000 characters" in err and len(err) < 1000, err[:500]


def test_a_byte_order_mark_is_passed_over(tmp_path):
    """A jobs file and a rig file saved with a UTF-8 byte order mark (Windows Notepad) load
    (they were 'not valid TOML: Invalid statement (at line 1, column 1)')."""
    rig = tmp_path / "rig.toml"
    rig.write_bytes(b"\xef\xbb\xbf" + DEFAULT_RIG.read_bytes())
    assert replace(load_rig_config(rig), source=None) == \
        replace(load_rig_config(DEFAULT_RIG), source=None)
    (tmp_path / "jobs.toml").write_bytes(
        b"\xef\xbb\xbf[[job]]\nname = 'a'\nrig = 'rig.toml'\nseconds = 1\n")
    plan = batch.load_plan(tmp_path / "jobs.toml", tmp_path / "o")
    assert [j.name for j in plan.jobs] == ["a"]


def test_command_line_errors(tmp_path, capsys):
    jobs = write_jobs(tmp_path)
    code, _, err = run_cli([jobs, "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], capsys)
    assert code == 2 and err.startswith("Error: --workers sizes the local pool"), err
    code, _, err = run_cli([jobs, "--retries", "-1"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    code, _, err = run_cli([tmp_path / "none.toml"], capsys)
    assert code == 2 and "jobs file not found" in err
    for args, words in ((["--job-timeout", "nan"], "--job-timeout must be"),
                        (["--scheduler", ""], "--scheduler needs"),
                        (["--scheduler", "  "], "--scheduler needs")):
        code, out, err = run_cli([jobs, *args, "--out", tmp_path / "o"], capsys)
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "o").exists()          # refused before anything is written


def test_unreachable_scheduler_is_a_user_error():
    pytest.importorskip("distributed")
    with pytest.raises(ConfigError, match="cannot reach the Dask scheduler"):
        batch.DaskPool("tcp://127.0.0.1:9", connect_timeout=1)


# ----------------------------------------------------------------------------- keys
def test_key_covers_environment_bytes_rig_and_options(tmp_path):
    level = write_small_level(tmp_path / "small.obj")
    d = batch.environment_digest(level)
    cfg = batch.job_config({"environment": level, "seed": 1}, tmp_path / "a")
    key = batch.job_key(cfg, d)
    # where the files go and the cache change nothing
    assert batch.job_key(replace(cfg, out=tmp_path / "b", nav_cache_dir=tmp_path), d) == key
    assert batch.job_key(batch.job_config({"environment": level, "seed": 2}, tmp_path / "a"),
                         d) != key
    assert batch.job_key(batch.job_config({"environment": level, "seed": 1, "scale": 2.0},
                                          tmp_path / "a"), d) != key
    assert batch.job_key(batch.job_config({"environment": level, "seed": 1, "format": "glb"},
                                          tmp_path / "a"), d) != key
    write_small_level(level, shift=0.01)
    assert batch.environment_digest(level) != d
    # an OBJ's material library is part of its bytes
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\n")
    level.write_text("mtllib m.mtl\n" + level.read_text())
    d1 = batch.environment_digest(level)
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 0.1 0.5 0.5\n")
    assert batch.environment_digest(level) != d1


def test_key_covers_the_code(tmp_path, monkeypatch):
    """A change to baker's source (released or not) gives every job a new key."""
    level = write_small_level(tmp_path / "small.obj")
    cfg = batch.job_config({"environment": level, "seed": 1}, tmp_path / "a")
    d = batch.environment_digest(level)
    key = batch.job_key(cfg, d)
    assert len(batch.code_digest()) == 64
    monkeypatch.setattr(batch, "code_digest", lambda: "0" * 64)
    assert batch.job_key(cfg, d) != key


def test_job_options_are_bakes_options():
    """Every `bake` option is a job key (or one per batch), with the same choices and defaults."""
    from baker.cli import bake

    names = {"environment": "environment", "rig_path": "rig", "fmt": "format",
             "max_slope_deg": "max_slope"}
    params = {names.get(p.name, p.name): p for p in bake.params}
    missing = set(params) - set(batch.OPTIONS) - set(batch.BATCH_LEVEL)
    assert not missing, (f"`bake` options {sorted(missing)} are not job keys: add them to "
                         "baker.batch.OPTIONS and job_config")
    assert set(params) == set(batch.OPTIONS) | set(batch.BATCH_LEVEL)
    for key, kind in batch.OPTIONS.items():
        p = params[key]
        if isinstance(kind, tuple):
            assert isinstance(p.type, click.Choice) and tuple(p.type.choices) == kind, key
        elif kind == "bool":
            assert p.is_flag, key
    cfg = batch.job_config({}, Path("/tmp/x"))
    # a job bakes on one process (workers=1): the batch's own workers share the cores
    assert cfg == replace(BakeConfig(rig=load_rig_config(DEFAULT_RIG), out=Path("/tmp/x")),
                          rig=cfg.rig, workers=1)
    assert cfg.rig == load_rig_config(DEFAULT_RIG)
    for p in bake.params:
        field = {"fmt": None, "rig_path": None, "usda": None, "sun": None, "out": None,
                 "environment": None, "max_memory": "max_memory_mb"}.get(p.name, p.name)
        if field in BakeConfig.__dataclass_fields__ and not getattr(p, "is_flag", False) \
                and p.default is not None:
            assert getattr(cfg, field) == p.default, p.name


# ----------------------------------------------------------------------------- coordinator
class ScriptedPool:
    """A pool that answers each task from a script: label -> list of Outcomes (one per attempt),
    or None: it never answers."""

    kind = "test"

    def __init__(self, script, slots=2):
        self.script = {k: (None if v is None else list(v)) for k, v in script.items()}
        self.size = slots
        self.running = {}
        self.abandoned = []
        self.submitted = []
        self._n = 0

    def describe(self):
        return "scripted"

    def slots(self):
        return self.size - len(self.running)

    def submit(self, task):
        self._n += 1
        self.running[self._n] = task
        self.submitted.append(task.label)
        return self._n

    def wait(self, timeout):
        done = []
        for h, task in list(self.running.items()):
            answers = self.script.get(task.label, [])
            if answers is None:
                continue
            out = answers.pop(0) if answers else batch.Outcome(ok=True, worker="w")
            del self.running[h]
            done.append((h, out))
        return done

    def abandon(self, handle):
        self.abandoned.append(self.running.pop(handle).label)

    def close(self, interrupted=False):
        pass


def _plan(tmp_path):
    write_small_level(tmp_path / "a.obj")
    write_small_level(tmp_path / "b.obj", shift=0.1)
    (tmp_path / "j.toml").write_text("""
[[job]]
name = "a"
environment = "a.obj"
[job.matrix]
seed = [0, 1, 2, 3]
[[job]]
name = "b"
environment = "b.obj"
[job.matrix]
seed = [0, 1]
""")
    plan = batch.load_plan(tmp_path / "j.toml", tmp_path / "out", cache=tmp_path / "cache")
    (tmp_path / "out").mkdir()
    return plan


def _run(plan, pool, timeout=None, retries=1):
    manifest = batch.Manifest(plan)
    todo = batch.skip_up_to_date(plan, manifest)
    stream = io.StringIO()
    batch._Run(plan, manifest, pool, batch.Progress(len(todo), 0, stream), todo,
               timeout, retries).loop()
    return manifest, stream.getvalue()


def test_failures_stay_with_their_job_and_only_lost_workers_are_retried(tmp_path):
    plan = _plan(tmp_path)
    died = batch.Outcome(ok=False, infra=True, error="worker process 7 died (exit code -9)")
    pool = ScriptedPool({
        "a-seed0": [died, batch.Outcome(ok=True, worker="w2")],            # retried once
        "a-seed1": [batch.Outcome(ok=False, error="EnvironmentLoadError: bad")],  # not retried
        "a-seed2": [died, died],                                          # out of retries
        "navigation b.obj": [batch.Outcome(ok=False, error="nothing walkable (b.obj)")],
    })
    manifest, text = _run(plan, pool)
    jobs = manifest.jobs
    assert pool.submitted[:2] == ["navigation a.obj", "navigation b.obj"]   # surfaces first
    assert (jobs["a-seed0"]["status"], jobs["a-seed0"]["attempts"]) == ("baked", 2)
    assert (jobs["a-seed1"]["status"], jobs["a-seed1"]["attempts"]) == ("failed", 1)
    assert jobs["a-seed1"]["error"] == "EnvironmentLoadError: bad"
    assert (jobs["a-seed2"]["status"], jobs["a-seed2"]["attempts"]) == ("failed", 2)
    assert "died" in jobs["a-seed2"]["error"]
    assert jobs["a-seed3"]["status"] == "baked"
    for name in ("b-seed0", "b-seed1"):       # their surface failed: never submitted
        assert jobs[name]["status"] == "failed"
        assert jobs[name]["error"] == "navigation surface: nothing walkable (b.obj)"
        assert name not in pool.submitted
    assert manifest.summary() == {"jobs": 6, "baked": 2, "skipped": 0, "failed": 4, "pending": 0}
    assert manifest.navigation[1]["status"] == "failed"
    on_disk = json.loads(manifest.path.read_text())
    assert on_disk["summary"]["failed"] == 4
    assert "retrying a-seed0" in text and "[6/6] " in text


def test_a_task_past_its_timeout_is_stopped(tmp_path, monkeypatch):
    plan = _plan(tmp_path)
    monkeypatch.setattr(batch._Run, "_grace", lambda self: 0.0)
    pool = ScriptedPool({"a-seed2": None})
    manifest, _ = _run(plan, pool, timeout=0.2)
    assert pool.abandoned == ["a-seed2"]
    e = manifest.jobs["a-seed2"]
    assert e["status"] == "failed" and "timed out after 0.2 s" in e["error"]
    assert manifest.summary()["baked"] == 5


def test_up_to_date_needs_the_same_key_and_unchanged_outputs(tmp_path):
    plan = _plan(tmp_path)
    job = plan.jobs[0]
    paths = job.cfg.output_paths()
    for path in paths.values():
        path.write_bytes(b"x" * 10)
    entry = {"key": job.key, "status": "baked",
             "outputs": {f: batch.file_record(path) for f, path in paths.items()}}
    (plan.out / "manifest.json").write_text(json.dumps({"jobs": {job.name: entry}}))
    m = batch.Manifest(plan)
    assert m.up_to_date(job) == entry
    os.utime(paths["glb"], ns=(1, 1))          # touched, same bytes: the sha256 says so
    assert m.up_to_date(job) == entry
    paths["glb"].write_bytes(b"y" * 10)         # same size, other bytes
    assert m.up_to_date(job) is None
    paths["glb"].write_bytes(b"x" * 10)
    assert m.up_to_date(job) == entry
    paths["usd"].unlink()
    assert m.up_to_date(job) is None
    paths["usd"].write_bytes(b"x" * 10)
    for changed in ({"key": "0" * 64}, {"status": "failed"}):
        m.previous = {job.name: {**entry, **changed}}
        assert m.up_to_date(job) is None
    m.previous = {}
    assert m.up_to_date(job) is None


def test_deadline_check():
    assert batch._deadline(None) is None
    check = batch._deadline(0.0)
    with pytest.raises(batch.JobTimeout, match=r"timed out after 0 s \(--job-timeout\), in load"):
        check("load", 0.0)


def test_progress_bar_on_a_terminal_plain_lines_when_piped():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    p = batch.Progress(2, 3, tty)
    assert p.bar is not None
    p.job("x", {"status": "baked", "wall_s": 1.0, "worker": "w", "error": None})
    p.job("y", {"status": "failed", "wall_s": 1.0, "worker": "w", "error": "bad file"})
    p.close()
    text = tty.getvalue()
    assert "skipped 3" in text and "failed 1" in text and "failed y: bad file" in text
    piped = io.StringIO()
    p = batch.Progress(2, 0, piped)
    assert p.bar is None
    p.job("x", {"status": "baked", "wall_s": 1.25, "worker": "h:1", "error": None})
    p.job("y", {"status": "failed", "wall_s": 1.0, "worker": "w", "error": "bad file"})
    assert piped.getvalue().splitlines() == ["[1/2] baked x: 1.25 s on h:1",
                                             "[2/2] failed y: bad file"]


class _Exit:
    """A task whose unpickling ends the worker process: a crash as far as the pool can tell."""

    def __reduce__(self):
        return (os._exit, (3,))


def test_local_pool_reports_a_dead_worker_and_replaces_it():
    pool = batch.LocalPool(1)
    try:
        h = pool.submit(_Exit())
        first = pool.procs[0].proc.pid
        done = []
        while not done:
            done = pool.wait(1.0)
        (handle, out), = done
        assert handle == h and out.infra and not out.ok
        assert out.error == f"worker process {first} died (exit code 3)"
        assert pool.slots() == 1 and pool.procs == []
        pool.submit(_Exit())                    # a fresh process takes the next task
        assert [p.proc.pid != first for p in pool.procs] == [True]
    finally:
        pool.close()


def test_jobs_file_error_is_not_cut():
    e = JobsFileError("x" * 5000, where="j.toml")
    from baker.errors import format_error

    assert len(format_error(e)) > 5000
    assert len(format_error(ConfigError("x" * 5000))) <= 410


@pytest.mark.parametrize("address, word", [
    ("not a url", "not a Dask scheduler address"), ("localhost", "not a Dask scheduler address"),
    ("tcp://host:abc", "not a Dask scheduler address"), (":8786", "not a Dask scheduler address"),
    ("inproc://x", "not a Dask scheduler address"),     # inproc: this process's own
    # a host label over 63 characters, an empty one, a name over 253 (the Client raised
    # UnicodeError from the idna codec half made)
    ("tcp://" + "a" * 70 + ":8786", "not a host name"), ("tcp://a..b:8786", "not a host name"),
    ("tcp://" + ("a" * 60 + ".") * 5 + "a:8786", "at most 253"),
    # a transport this installation cannot use (TypeError inside the Client)
    ("ucx://127.0.0.1:8786", "cannot be used here"), ("tls://127.0.0.1:8786", "TLS configuration"),
])
def test_a_scheduler_address_dask_cannot_parse_is_one_line(address, word, tmp_path):
    """Refused before a Dask Client is made: one that failed on its address left a half-made
    object whose clean-up stalled 40 s and printed a traceback after the error line."""
    pytest.importorskip("distributed")
    jobs = write_jobs(tmp_path)
    r = subprocess.run([sys.executable, "-m", "baker", "batch", str(jobs), "--out",
                        str(tmp_path / "o"), "--scheduler", address],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines() == [r.stderr.strip()], r.stderr
    assert word in r.stderr and "(--scheduler)" in r.stderr
    assert not (tmp_path / "o").exists()          # refused before the output folder is made


def test_batch_lock_is_exclusive_and_leaves_no_file(tmp_path):
    """One batch per output folder: a second is refused while the first holds the lock, and
    the lock file is gone once the first ends (the next batch locks afresh)."""
    from baker.errors import ConfigError

    with batch._batch_lock(tmp_path):
        assert (tmp_path / batch.LOCK_FILE).exists()
        with pytest.raises(ConfigError, match="another `baker batch` is writing"):
            with batch._batch_lock(tmp_path):
                pass
    assert not (tmp_path / batch.LOCK_FILE).exists()
    with batch._batch_lock(tmp_path):
        pass
    assert list(tmp_path.iterdir()) == []


def test_batch_lock_retakes_a_file_unlinked_under_it(tmp_path, monkeypatch):
    """A batch that locks the file another batch unlinked as it ended opens the path again:
    it holds the file the path names, so a third batch sees its lock."""
    import fcntl

    from baker.errors import ConfigError

    path = tmp_path / batch.LOCK_FILE
    real_flock, calls = fcntl.flock, []

    def flock(fd, op):          # the first lock lands on a file unlinked just before
        calls.append(fd)
        if len(calls) == 1:
            path.unlink()
        return real_flock(fd, op)

    monkeypatch.setattr(fcntl, "flock", flock)
    with batch._batch_lock(tmp_path):
        monkeypatch.setattr(fcntl, "flock", real_flock)
        assert len(calls) == 2 and path.exists()
        with pytest.raises(ConfigError):
            with batch._batch_lock(tmp_path):
                pass


def test_up_and_units_split_navigation_groups(tmp_path):
    """Jobs reading the same level with another --up or --units navigate another surface."""
    write_small_level(tmp_path / "small.obj")
    (tmp_path / "j.toml").write_text('[defaults]\nenvironment = "small.obj"\nseconds = 1\n'
                                     '[[job]]\nname = "a"\nup = "z"\n'
                                     '[[job]]\nname = "b"\n'
                                     '[[job]]\nname = "c"\nunits = "mm"\n'
                                     '[[job]]\nname = "d"\nup = "y"\nunits = "m"\n')
    plan = batch.load_plan(tmp_path / "j.toml", tmp_path / "o")
    assert [j.nav for j in plan.jobs] == [0, 1, 2, 3]
    assert [(c.up_axis, c.units) for c in plan.nav_groups] == [
        ("z", None), (None, None), (None, "mm"), ("y", "m")]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_manifest_that_is_a_fifo_is_no_previous_run(tmp_path):
    """A FIFO where the previous manifest would be: reading it waited for a writer for ever
    (the batch hung before its first job); it holds no previous run."""
    (tmp_path / "jobs.toml").write_text("[[job]]\nname = 'a'\nseconds = 1\n")
    plan = batch.load_plan(tmp_path / "jobs.toml", tmp_path / "o")
    plan.out.mkdir()
    os.mkfifo(plan.out / batch.MANIFEST)
    assert batch.Manifest(plan).previous == {}


@pytest.mark.parametrize("text", [b"[" * 100_000 + b"]" * 100_000,
                                  b'{"jobs": ' + b'{"a": ' * 100_000 + b"1" + b"}" * 100_001])
def test_a_manifest_nested_too_deeply_is_no_previous_run(tmp_path, text):
    """A previous manifest.json of JSON nested 100,000 deep (a RecursionError traceback before
    the first job): it holds no previous run, and the batch bakes every job."""
    (tmp_path / "jobs.toml").write_text("[[job]]\nname = 'a'\nseconds = 1\n")
    plan = batch.load_plan(tmp_path / "jobs.toml", tmp_path / "o")
    plan.out.mkdir()
    (plan.out / batch.MANIFEST).write_bytes(text)
    assert batch.Manifest(plan).previous == {}


def test_environment_digest_reads_in_chunks(tmp_path):
    """A .gltf naming a 3 GB buffer (a sparse file here): the job key's digest read it whole
    into memory; it is hashed in chunks now, with the same digest as the whole bytes'."""
    import hashlib
    import tracemalloc

    big = tmp_path / "big.bin"
    with open(big, "wb") as f:
        f.truncate(3 << 30)
    gltf = tmp_path / "level.gltf"
    gltf.write_text('{"asset": {"version": "2.0"}, "buffers": [{"uri": "big.bin"}]}')
    tracemalloc.start()
    try:
        digest = batch.environment_digest(gltf)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 200 << 20
    h = hashlib.sha256()
    text = gltf.read_bytes()
    h.update(len(text).to_bytes(8, "little") + text + b"big.bin\0"
             + (3 << 30).to_bytes(8, "little"))
    zeros = bytes(1 << 24)
    for _ in range((3 << 30) >> 24):
        h.update(zeros)
    assert digest == h.hexdigest()
