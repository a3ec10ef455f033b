"""Names in the written files: every GLB node, mesh and material name is unique also without
regard to case (across the three kinds together), and so is every object prim name of the USD,
on a bake with prey and the debug navmesh layer whose environment uses the names baker itself
needs (`Centipede`, `centipede_mesh`, `navmesh`, `prey_01`, `head`, ...) in other cases. The
bake's metadata is stored once."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.pipeline import bake
from glb_read import Glb
from validator import gltf_validate, issues_summary, usd_validate

#: environment node names that clash, without regard to case, with what baker writes
CLASHING = ("CENTIPEDE", "Centipede_Mesh", "centipede_skinned", "NavMesh_Mesh", "Prey_01", "HEAD",
            "Ground", "ground_MESH", "ground_mat", "sun", "environment", "Looks", "mesh")


def clashing_level(path: Path) -> Path:
    """A 6 m floor (named `Ground`) and small blocks named after baker's own names."""
    scene = trimesh.Scene()
    floor = trimesh.creation.box(extents=(6.0, 0.1, 6.0))
    floor.apply_translation((0, -0.05, 0))
    scene.add_geometry(floor, node_name="Ground", geom_name="Ground")
    for k, name in enumerate(n for n in CLASHING if n != "Ground"):
        box = trimesh.creation.box(extents=(0.08, 0.04, 0.08))
        box.apply_translation((-2.5 + 0.4 * k, 0.02, 2.6))
        scene.add_geometry(box, node_name=name, geom_name=name)
    scene.export(path)
    return path


@pytest.fixture(scope="module")
def baked(tmp_path_factory, nav_cache_dir):
    tmp = tmp_path_factory.mktemp("names")
    level = clashing_level(tmp / "level.glb")
    cfg = BakeConfig(environment=level, seconds=2, seed=3, rig=load_rig_config(DEFAULT_RIG),
                     out=tmp / "c", formats=("glb", "usda"), prey=2, debug_navmesh=True,
                     clips=True, nav_cache_dir=nav_cache_dir)
    return bake(cfg)


def clashes(names) -> dict[str, int]:
    return {k: v for k, v in Counter(n.lower() for n in names).items() if v > 1}


def test_glb_names_are_unique_without_regard_to_case(baked):
    doc = Glb(baked.outputs["glb"].read_bytes()).doc
    nodes = [n["name"] for n in doc["nodes"]]
    names = nodes + [m["name"] for m in doc["meshes"]] + [m["name"] for m in doc["materials"]]
    assert all(names), "every node, mesh and material has a name"
    assert clashes(names) == {}
    # the names baker needs are kept exactly; the environment's give way
    for fixed in ("Centipede", "centipede_mesh", "Environment", "Sun", "Prey", "prey_01",
                  "prey_02", "head", "navmesh"):
        assert fixed in nodes, fixed
    assert "centipede_skinned" in [m["name"] for m in doc["meshes"]]
    assert {"Ground", "Ground_mesh", "Ground_mat"} <= set(names)
    env = doc["nodes"][nodes.index("Environment")]["children"]
    env_names = [doc["nodes"][i]["name"] for i in env]
    assert len(env_names) == len(CLASHING)
    for raw in CLASHING:                      # each clashing part is still there, renamed
        assert sum(n.lower().startswith(raw.lower()) for n in env_names) >= 1, raw
    rig = load_rig_config(DEFAULT_RIG)
    from baker.rig import build_rig

    joints = build_rig(rig).skeleton.names
    skin = doc["skins"][0]["joints"]
    assert tuple(doc["nodes"][i]["name"] for i in skin) == joints   # joint names unchanged


def test_glb_metadata_is_stored_once(baked):
    doc = Glb(baked.outputs["glb"].read_bytes()).doc
    assert "extras" not in doc["asset"]
    ex = doc["scenes"][0]["extras"]
    assert ex["seed"] == 3 and ex["timeline"]
    # nowhere else: no node, mesh or material carries a copy
    for kind in ("nodes", "meshes", "materials"):
        assert not any("extras" in x for x in doc[kind]), kind
    report = gltf_validate(baked.outputs["glb"])
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []


def test_usd_prim_names_are_unique_without_regard_to_case(baked):
    from pxr import Usd, UsdShade

    stage = Usd.Stage.Open(str(baked.outputs["usda"]))
    prims = [p for p in stage.Traverse() if not p.IsA(UsdShade.Shader)]
    names = [p.GetName() for p in prims]
    assert clashes(names) == {}
    paths = {str(p.GetPath()) for p in prims}
    assert {"/World/Prey/prey_01/prey_01_mesh", "/World/Looks/prey_01_mat",
            "/World/Debug/navmesh", "/World/Looks/navmesh_mat", "/World/Environment/Ground",
            "/World/Looks/Ground_mat"} <= paths
    assert usd_validate(stage) == []
    ex = stage.GetPrimAtPath("/World").GetCustomData()
    assert ex["seed"] == 3
    assert np.isfinite(float(ex["seconds"]))
