"""SIGINT, SIGTERM and SIGHUP at several points of a real bake, SIGQUIT, SIGALRM, SIGUSR2 and
SIGXCPU at some: exit 128 + the signal number (130 / 143 / 129 ...), one line on
stderr, no traceback, no temporary files, the previous outputs byte-identical.

The phases are hit with the test hook in baker/signals.py: BAKER_TEST_PAUSE_AT=<phase> holds
the bake at that checkpoint (so the signal lands there for sure), BAKER_TEST_MARKS=1 only
announces each phase (so the signal lands in the real work that follows: the imports, the
navigation build, the simulation)."""

from __future__ import annotations

import re
import shutil
import signal

import pytest

from bakeproc import Bake, snapshot

PEAK_MB = 2048
LINE = re.compile(r"^Error: interrupted by (SIGINT|SIGTERM|SIGHUP|SIGQUIT|SIGALRM|SIGUSR2|SIGXCPU)"
                  r" \(during [a-z:]+\)$")
CODES = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129, signal.SIGQUIT: 131,
         signal.SIGALRM: 142, signal.SIGUSR2: 140, signal.SIGXCPU: 152}
#: signals whose default action ends the process where it stands (temporaries left)
OTHERS = (signal.SIGQUIT, signal.SIGALRM, signal.SIGUSR2, signal.SIGXCPU)

#: (id, how, phase, extra bake args, seconds to wait after the marker)
#: how = "pause": held at the checkpoint; "mark": the signal follows the announcement.
POINTS = [
    ("start", "pause", "start", (), 0.0),
    ("imports", "mark", "start", (), 0.0),               # numpy, scipy, trimesh, pxr loading
    ("navmesh-build", "mark", "navmesh", ("--no-cache",), 0.3),   # the build takes seconds
    ("simulate", "mark", "simulate", ("--seconds", "4"), 0.0),
    ("write-usd", "pause", "write:usd", (), 0.0),        # the GLB's temporary exists
    ("commit", "pause", "commit", (), 0.0),              # every temporary exists
]
CASES = [(p, s) for p in POINTS for s in (signal.SIGINT, signal.SIGTERM)] + [
    (p, signal.SIGHUP) for p in POINTS if p[0] in ("simulate", "write-usd", "commit")] + [
    (p, s) for p in POINTS if p[0] == "write-usd" for s in OTHERS] + [
    (p, signal.SIGQUIT) for p in POINTS if p[0] == "simulate"]


@pytest.fixture(scope="module")
def good(tmp_path_factory, nav_cache_dir):
    from bakeproc import run

    folder = tmp_path_factory.mktemp("good_sig")
    done = run(["bake", "--seconds", "1", "--seed", "1", "--out", folder / "centipede",
                "--cache-dir", nav_cache_dir])
    assert done.code == 0, done.stderr
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("point,sig", CASES,
                         ids=[f"{p[0]}-{signal.Signals(s).name}" for p, s in CASES])
def test_signal_keeps_previous_outputs(point, sig, good, tmp_path, nav_cache_dir):
    _, how, phase, extra, delay = point
    out = tmp_path / "out"
    shutil.copytree(good, out)
    before = snapshot(out)
    args = ["bake", "--seconds", "1", "--seed", "9", "--out", out / "centipede",
            "--cache-dir", nav_cache_dir, *extra]
    b = Bake(args, pause_at=phase if how == "pause" else None, marks=how == "mark")
    assert b.wait_marker(phase), "the bake ended before the phase"
    if delay:
        import time
        time.sleep(delay)
    b.signal(sig)
    done = b.wait()
    assert done.code == CODES[sig], (done.code, done.stderr)
    assert "Traceback" not in done.stderr
    assert len(done.err_lines) == 1, done.stderr
    assert LINE.match(done.err_lines[0]), done.err_lines[0]
    assert signal.Signals(sig).name in done.err_lines[0]
    assert snapshot(out) == before          # byte-identical, and no hidden temporaries
    assert done.peak_mb < PEAK_MB


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.25])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_navmesh_command_stops_cleanly_during_imports(sig, delay, tmp_path):
    """`baker navmesh` imports numpy, scipy and trimesh lazily: a signal among them (some
    libraries catch BaseException around optional imports) still gives one line and 130/143."""
    from pathlib import Path

    level = Path(__file__).resolve().parents[2] / "environments" / "multistorey.glb"
    b = Bake(["navmesh", level, "--scale", "8", "--cache-dir", tmp_path / "c"], marks=True)
    assert b.wait_marker("start")
    if delay:
        import time
        time.sleep(delay)
    b.signal(sig)
    done = b.wait()
    assert done.code == CODES[sig], (done.code, done.stderr)
    assert len(done.err_lines) == 1 and LINE.match(done.err_lines[0]), done.stderr
    assert not list(tmp_path.glob("c/.*"))                # no temporary cache entry


@pytest.mark.slow
def test_second_signal_during_cleanup_changes_nothing(good, tmp_path, nav_cache_dir):
    """Ctrl-C, then a SIGTERM once the bake has taken it: the first stops the bake, the
    second is ignored while the temporaries are removed. (Sent back to back, which of the two
    is first is the kernel's choice: it hands each to one of the process's threads.)"""
    out = tmp_path / "out"
    shutil.copytree(good, out)
    before = snapshot(out)
    b = Bake(["bake", "--seconds", "1", "--seed", "9", "--out", out / "centipede",
              "--cache-dir", nav_cache_dir], pause_at="commit")
    assert b.wait_marker("commit")
    b.signal(signal.SIGINT)
    b.wait_marker("interrupted")
    b.signal(signal.SIGTERM)
    done = b.wait()
    assert done.code == 130 and len(done.err_lines) == 1, done.stderr
    assert snapshot(out) == before


def test_console_entry_point_installs_the_handlers_first():
    """`baker` runs baker.entry:main, which imports only the standard library and
    baker.signals before installing the handlers."""
    import ast
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    scripts = tomllib.loads((root / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["baker"] == "baker.entry:main"
    for mod in ("entry.py", "signals.py", "__init__.py"):
        tree = ast.parse((root / "baker" / mod).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            else:
                continue
            for n in names:
                top = n.split(".")[0]
                assert top in ("__future__", "os", "signal", "sys", "time", "contextlib",
                               "threading", "select", "baker"), (mod, n)
                if top == "baker":
                    assert n in ("baker", "baker.signals", "baker.cli"), (mod, n)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_after_the_command_returned_changes_nothing(tmp_path, signum):
    """Once the command has returned (a bake's files committed, its success line printed), a
    Ctrl-C or SIGTERM as the interpreter ends leaves exit code 0 and nothing on stderr (it
    killed the process with 130 and no message: Python restores the default handlers as it
    ends). The signal is sent from an atexit hook, after baker's main has returned."""
    import subprocess
    import sys

    code = ("import atexit, os, sys\n"
            f"atexit.register(lambda: os.kill(os.getpid(), {int(signum)}))\n"
            "from baker.entry import main\n"
            "sys.exit(main(['--version']))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == "" and "version" in r.stdout


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_while_a_usd_level_is_read_on_its_thread(sig, good, tmp_path):
    """A USD level is read on a thread of its own (parallel.on_own_stack), in native code no
    signal stops. A signal then stops the bake as any other (the line, 130/143, the previous
    outputs as they were) and the process ends at once: the interpreter's finalization ran
    beside the still-reading thread, which aborted the process (signal 6, "terminate called
    without an active exception") after the line. The signal is sent once the thread has
    announced the read (the test hook's "read:usd"); the read of 20,000 nested prims goes on
    for a second or more after it, and the test checks that it had not ended."""
    import bad_inputs

    level = tmp_path / "deep.usda"
    level.write_text(bad_inputs.deep_usd_text(20_000))
    out = tmp_path / "out"
    shutil.copytree(good, out)
    before = snapshot(out)
    b = Bake(["bake", level, "--seconds", "1", "--seed", "9", "--out", out / "centipede",
              "--no-cache"], marks=True)
    assert b.wait_marker("read:usd"), "the bake ended before the USD read"
    b.signal(sig)
    done = b.wait()
    marks = [ln.strip() for ln in done.stdout.splitlines() if ln.startswith("baker-test:")]
    assert "baker-test: at interrupted" in marks, done.stdout
    assert "baker-test: at read:usd:done" not in marks[:marks.index("baker-test: at interrupted")]
    assert done.code == CODES[sig], (done.code, done.stderr)
    assert "Traceback" not in done.stderr
    assert done.err_lines == [f"Error: interrupted by {signal.Signals(sig).name} (during load)"], \
        done.stderr
    assert snapshot(out) == before
