"""Optional: levels exported by Blender's own exporters load as Blender has them.

tests/tools/blender_levels.py, run by a Python with Blender's bpy (BAKER_BLENDER_PYTHON, as in
tests/export/test_blender.py; bpy needs numpy<2, so it is not a project dependency), builds a
level (parenting, unapplied and negative scales, linked duplicates, Array/Mirror/Solidify
modifiers, collection instances, hidden objects, an n-gon, curves) in a metre scene and a
centimetre one, and exports it as glTF (GLB, .gltf + .bin, +Z up, Draco, GPU instancing,
lights), OBJ, PLY and STL (ASCII and binary, both up axes) and USD (.usda/.usdc/.usdz,
instancing, matrices, triangulated), writing beside each file Blender's evaluated world
triangles of what that exporter writes. Every file is loaded with load_environment (told the
--up / --units a user must give, listed in the manifest) and compared with them
(tests/tools/blender_compare.py): the same surface within 1e-5 of the level's size, facing the
same way, and the same sun. The test skips when no Blender Python is given.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from baker.environment import load_environment

TOOLS = Path(__file__).resolve().parents[1] / "tools"
LEVELS = TOOLS / "blender_levels.py"

#: every kind of export the script writes (a name's tail after "m_" / "cm_")
KINDS = {"gltf_glb", "gltf_glb_apply", "gltf_sep", "gltf_zup", "gltf_visible", "gltf_lights",
         "gltf_draco", "gltf_gpu_inst", "obj", "obj_raw", "obj_zup", "obj_tri", "ply_bin",
         "ply_ascii", "ply_yup", "stl_bin", "stl_ascii", "usd_usda", "usd_usdc", "usd_usdz",
         "usd_inst", "usd_matrix", "usd_viewport", "usd_yup", "usd_tri"}


def _blender_python() -> str:
    exe = os.environ.get("BAKER_BLENDER_PYTHON", "")
    if not exe or not shutil.which(exe):
        pytest.skip("set BAKER_BLENDER_PYTHON to a Python with bpy to run the Blender export check")
    return exe


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    exe = _blender_python()
    out = tmp_path_factory.mktemp("blender_levels")
    r = subprocess.run([exe, str(LEVELS), str(out)], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0 and (out / "manifest.json").exists(), \
        f"blender_levels.py failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return out


@pytest.mark.slow
def test_every_blender_export_loads_as_blender_has_it(exported):
    from blender_compare import check_entry

    manifest = json.loads((exported / "manifest.json").read_text())
    names = {e["name"] for e in manifest}
    for scene in ("m_", "cm_"):
        assert {scene + k for k in KINDS} <= names, sorted({scene + k for k in KINDS} - names)
    assert {"m_usd_cm", "cm_stl_units"} <= names
    fails = []
    for e in manifest:
        env = load_environment(exported / e["file"], up_axis=e["up"], units=e["units"])
        r = check_entry(exported, e, env)
        if r["fails"]:
            fails.append(f"{e['name']} ({e['file']}, up {e['up']}, units {e['units']}): "
                         + "; ".join(r["fails"]))
    assert not fails, "\n".join(fails)


@pytest.mark.slow
def test_blender_ply_and_stl_read_plus_y_up_stand_the_floor_on_its_edge(exported):
    """Blender's PLY and STL exports are +Z up: read without --up z, the 16 m floor stands
    vertical (what the README's level-input section tells the user to pass)."""
    for name in ("m_level_bin.ply", "m_level_bin.stl"):
        env = load_environment(exported / name)
        lo = min(m.vertices.min(0)[1] for m in env.meshes) + env.origin[1]
        hi = max(m.vertices.max(0)[1] for m in env.meshes) + env.origin[1]
        assert hi - lo == pytest.approx(16.0, abs=1e-4), name
        env = load_environment(exported / name, up_axis="z")
        lo = min(m.vertices.min(0)[1] for m in env.meshes) + env.origin[1]
        hi = max(m.vertices.max(0)[1] for m in env.meshes) + env.origin[1]
        assert -0.2 < lo < 0 and 3 < hi < 3.1, (name, lo, hi)   # below: the solidified wall
