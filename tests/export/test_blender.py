"""Optional: Blender 5 (bpy) imports the GLB and the USD with the animation in place.

bpy needs numpy<2, so it is not a project dependency. Point BAKER_BLENDER_PYTHON at a Python
that has it (e.g. `python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install bpy`); the test skips
otherwise.
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from baker.atomic import atomic_write_bytes
from baker.export.gltf import build_glb
from baker.export.usd import write_usd

PROBE = Path(__file__).resolve().parents[1] / "tools" / "blender_probe.py"


def _blender_python() -> str:
    exe = os.environ.get("BAKER_BLENDER_PYTHON", "")
    if not exe or not shutil.which(exe):
        pytest.skip("set BAKER_BLENDER_PYTHON to a Python with bpy to run the Blender import check")
    return exe


def _probe(exe: str, path: Path, fps: int, frames: list[int]) -> dict:
    r = subprocess.run([exe, str(PROBE), str(path), str(fps), ",".join(map(str, frames))],
                       capture_output=True, text=True, timeout=600)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("PROBE_JSON ")]
    assert lines, f"Blender probe failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return json.loads(lines[-1][len("PROBE_JSON "):])


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".glb", ".usd"])
def test_blender_imports_the_animation(tmp_path, suffix, small_env, rig, clip, trajectory, bake_extras):
    exe = _blender_python()
    path = tmp_path / f"centipede{suffix}"
    if suffix == ".glb":
        atomic_write_bytes(path, build_glb(small_env, rig, clip, extras=bake_extras))
    else:
        write_usd(path, small_env, rig, clip, fps=clip.fps, extras=bake_extras)
    last = clip.n_frames - 1
    frames = [0, last // 2, last]
    d = _probe(exe, path, clip.fps, frames)
    assert len(d["armatures"]) == 1
    assert sorted(d["bones"]) == sorted(rig.skeleton.names)      # Blender orders bones by hierarchy
    assert d["action_range"] == [0.0, float(last)]
    assert d["lights"] and d["skinned_meshes"]
    assert d["skinned_vertices"] == len(rig.mesh.vertices)
    world, _ = clip.world(rig.skeleton.parents)                 # every joint, legs included
    np.testing.assert_allclose(world[:, rig.spine], trajectory.spine_positions, atol=1e-5)
    for f in frames:
        got = np.array([d["positions"][str(f)][n] for n in rig.skeleton.names])
        p = world[f]
        want = np.stack([p[:, 0], -p[:, 2], p[:, 1]], -1)          # +Y up -> Blender's +Z up
        assert np.abs(got - want).max() < 1e-5


@pytest.mark.slow
def test_blender_imports_each_behaviour_clip_as_an_action(tmp_path, nav_cache_dir):
    """`--clips`: every per-behaviour glTF animation arrives in Blender as its own action."""
    exe = _blender_python()
    from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
    from baker.pipeline import bake
    from glb_read import Glb

    r = bake(BakeConfig(seconds=20, seed=0, rig=load_rig_config(DEFAULT_RIG), prey=2, clips=True,
                        out=tmp_path / "clips", formats=("glb",), nav_cache_dir=nav_cache_dir))
    names = [a["name"] for a in Glb(r.outputs["glb"].read_bytes()).doc["animations"]]
    assert len(names) >= 3 and names[0] == "bake"
    d = _probe(exe, r.outputs["glb"], 30, [0])
    for name in names:
        assert name in d["actions"], (name, sorted(d["actions"]))
    for i, e in enumerate(r.report["timeline"]):
        name = f"{e['state']}_{i:02d}"
        if name in names:
            f0, f1 = round(e["start"] * 30), round(e["end"] * 30)
            assert d["actions"][name] == [0.0, float(f1 - f0)]


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".glb", ".usd"])
def test_blender_places_the_creature_at_the_placement(tmp_path, suffix, small_env, rig, trajectory):
    """An environment origin and a placement away from the world origin (the Centipede node's /
    SkelRoot's translation): Blender puts every bone where the simulation has it. (40 m out, so
    Blender's own float32 object matrices stay well under 1e-5 m; at 10 km they are ~1 mm, a
    constant offset of the whole armature, not a jitter.)"""
    exe = _blender_python()
    from baker.clip import build_clip
    from baker.environment.model import Environment

    origin = np.array([40.0, 2.0, -30.0])
    env = Environment(meshes=small_env.meshes, sun=small_env.sun, origin=origin)
    clip = build_clip(trajectory, rig, origin=origin)
    assert np.all(clip.placement != 0)
    path = tmp_path / f"placed{suffix}"
    if suffix == ".glb":
        atomic_write_bytes(path, build_glb(env, rig, clip, extras={}))
    else:
        write_usd(path, env, rig, clip, fps=clip.fps, extras={})
    last = clip.n_frames - 1
    d = _probe(exe, path, clip.fps, [0, last])
    world, _ = clip.world(rig.skeleton.parents)
    np.testing.assert_allclose(world[:, rig.spine], trajectory.spine_positions + origin, atol=1e-5)
    for f in (0, last):
        got = np.array([d["positions"][str(f)][n] for n in rig.skeleton.names])
        p = world[f]
        assert np.abs(got - np.stack([p[:, 0], -p[:, 2], p[:, 1]], -1)).max() < 1e-5
