"""Paths this user may not read, search or write: one line and exit 2 for every command, a cache
folder that cannot be searched is no cache (the bake goes on), and numba's compiled-kernel cache
falls back to the temporary folder when neither the install nor the home folder is writable.

The checks run as another user: as root, `setpriv` to nobody (root reads every folder); as any
other user, themselves. They skip when that user cannot run this checkout's Python."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FLOOR = ROOT / "environments" / "rainforest_floor.glb"


def _prefix() -> list[str]:
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: no other user to run as")
    return [setpriv, "--reuid", "65534", "--regid", "65534", "--clear-groups"]


@pytest.fixture(scope="module")
def other():
    """(run(args, cwd, **env) -> CompletedProcess as the other user, its work folder with a
    folder `d` it may not search holding a level, a rig, a jobs file and a bake)."""
    prefix = _prefix()
    work = Path(tempfile.mkdtemp(prefix="baker-perm-"))
    work.chmod(0o777)
    d = work / "d"
    d.mkdir()
    shutil.copy(FLOOR, d / "level.glb")
    shutil.copy(FLOOR, d / "bake.glb")
    (d / "rig.toml").write_text("[body]\nsegments = 21\n")
    (d / "jobs.toml").write_text('[[job]]\nenvironment = "level.glb"\nseconds = 1\n')
    (work / "o").mkdir()
    (work / "o").chmod(0o777)

    def run(args, **env):
        e = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "COV"))}
        e.update(env)
        return subprocess.run([*prefix, sys.executable, *args], cwd=work, env=e,
                              capture_output=True, text=True, timeout=300)

    probe = run(["-c", "import baker, numpy"])
    if probe.returncode != 0:
        shutil.rmtree(work)
        pytest.skip(f"the other user cannot run this checkout: {probe.stderr.strip()[-200:]}")
    d.chmod(0o600 if prefix else 0o000)     # no search (x) bit: nothing in it can be reached
    yield run, work
    d.chmod(0o755)
    shutil.rmtree(work)


@pytest.mark.parametrize("args,path", [
    (["bake", "d/level.glb", "--out", "o/c", "--seconds", "1"], "d/level.glb"),
    (["bake", "--rig", "d/rig.toml", "--out", "o/c", "--seconds", "1"], "d/rig.toml"),
    (["bake", "--out", "d/sub/c", "--seconds", "1"], "d/sub"),
    (["navmesh", "d/level.glb"], "d/level.glb"),
    (["batch", "d/jobs.toml", "--out", "o/batch"], "d/jobs.toml"),
    (["inspect", "d/bake.glb"], "d/bake.glb"),
    (["preview", "d/bake.glb", "--out", "o/p.png"], "d/bake.glb"),
], ids=lambda v: v[0] if isinstance(v, list) else None)
def test_a_path_it_may_not_reach_is_one_line_and_exit_2(other, args, path):
    run, work = other
    r = run(["-m", "baker", *args], HOME=str(work))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[0].startswith("Error: permission denied") and path in lines[0], lines[0]
    assert not list((work / "o").glob("c*"))


def test_a_cache_entry_it_may_not_reach_is_no_entry(other):
    run, work = other
    r = run(["-c", "from baker.navmesh import cache; print(cache.load('d/cache/entry.npz'))"],
            HOME=str(work))
    assert r.returncode == 0 and r.stdout.strip() == "None", r.stderr


def test_compiled_kernels_cached_in_the_temporary_folder_without_a_writable_home(other):
    """An install the user may not write, run with HOME=/ (a container's other user): numba
    cannot cache beside the sources or in ~/.cache, and the modules with cached kernels failed
    at import; they use a folder in the temporary folder instead."""
    run, work = other
    if os.access("/", os.W_OK) and os.geteuid() != 0:
        pytest.skip("this user can write /")
    if os.access(ROOT / "baker", os.W_OK) and os.geteuid() != 0:
        pytest.skip("this user can write the checkout")
    r = run(["-c", "import os, baker.navmesh.raster, baker.export.keyfit; "
                   "print(os.environ.get('NUMBA_CACHE_DIR', ''))"], HOME="/")
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip().startswith(tempfile.gettempdir()), r.stdout
