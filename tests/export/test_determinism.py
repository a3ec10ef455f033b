"""Same inputs -> byte-identical GLB, .usda and .usd (crate), across separate processes."""

import hashlib
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import sys, hashlib
from pathlib import Path
sys.path.insert(0, {tests!r}); sys.path.insert(0, {tools!r})
import numpy as np
import conftest
from baker.config import DEFAULT_RIG, load_rig_config
from baker.rig import build_rig
from baker.clip import build_clip
from baker.environment.model import Environment, Sun
from baker.export.gltf import build_glb
from baker.export.usd import write_usd
rig = build_rig(load_rig_config(DEFAULT_RIG))
clip = build_clip(conftest.sine_trajectory(rig.spacing, len(rig.spine)), rig)
env = Environment(meshes=(conftest.flat_ground(),
                          conftest.box_mesh("rock", (0.3, 0.05, 0.4), (0.05, 0.05, 0.08), (0.2, 0.2, 0.2, 1))),
                  sun=Sun(direction=np.array([0.0, 1.0, 0.0])))
extras = {{"seed": 3, "tags": {{"b": 1, "a": [1, 2]}}, "events": [{{"state": "wander"}}]}}
out = Path(sys.argv[1])
(out / "c.glb").write_bytes(build_glb(env, rig, clip, extras=extras))
write_usd(out / "c.usd", env, rig, clip, fps=30, extras=extras)
write_usd(out / "c.usda", env, rig, clip, fps=30, extras=extras)
"""


def _run(out: Path, hashseed: str) -> dict[str, str]:
    out.mkdir()
    code = SCRIPT.format(tests=str(ROOT / "tests"), tools=str(ROOT / "tests" / "tools"))
    env = {**os.environ, "PYTHONHASHSEED": hashseed,
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    subprocess.run([sys.executable, "-c", code, str(out)], check=True, env=env, timeout=300)
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(out.iterdir())}


def test_outputs_identical_across_processes(tmp_path):
    a = _run(tmp_path / "a", "1")
    b = _run(tmp_path / "b", "2")
    assert set(a) == {"c.glb", "c.usd", "c.usda"}
    assert a == b


def test_bundled_rig_recorded_relative_to_the_project(tmp_path):
    """The files record the bundled rig as rigs/scolopendra.toml, not where the project is
    checked out: a bake gives the same bytes from any clone (CI runners' paths differ). A rig
    outside the project keeps its path as given."""
    import json
    import shutil

    from baker.config import DEFAULT_RIG, REPO_ROOT, load_rig_config
    from baker.export.report import rig_summary

    rig = load_rig_config(DEFAULT_RIG)
    assert rig.source == "rigs/scolopendra.toml"
    assert str(REPO_ROOT) not in json.dumps(rig_summary(rig))
    mine = tmp_path / "mine.toml"
    shutil.copy(DEFAULT_RIG, mine)
    assert load_rig_config(mine).source == str(mine)
