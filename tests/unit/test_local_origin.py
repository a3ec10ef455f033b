"""The environment's local origin: chosen from the float64 world bounds (whole metres; 0 on axes
whose range holds the world origin), subtracted before the float32 rounding, for every format;
world inputs and outputs converted at the edges (pipeline config, navmesh report)."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from baker.config import BakeConfig
from baker.environment import load_environment
from baker.environment.load import choose_origin
from baker.environment.model import Environment

FAR = np.array([10000.0, 0.0, -20000.0])
# a 2 x 2 m floor 10 km out, with vertices that float32 world coordinates could not hold
# (their spacing is 1 mm there)
FLOOR = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0],
                  [0.123456789, 0.0, 0.3456789]]) + FAR
FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 0, 1]])


def test_choose_origin_rule():
    np.testing.assert_array_equal(choose_origin([-11.25, -0.4, -11.25], [11.25, 0.5, 11.25]), 0)
    # per axis: an axis whose range holds 0 keeps 0; others get the rounded centre
    np.testing.assert_array_equal(choose_origin([9990.2, -1.0, 20.0], [10010.9, 5.0, 40.6]),
                                  [10001.0, 0.0, 30.0])
    np.testing.assert_array_equal(choose_origin([-300.5, 100.0, -7.0], [-299.5, 102.0, -5.0]),
                                  [-300.0, 101.0, -6.0])
    o = choose_origin([1e7, 0.0, 0.0], [1e7 + 1.0, 1.0, 1.0])
    assert o[0] == 1e7 + 1.0 and o.dtype == np.float64   # a half rounds up


def _check_far(env: Environment, world: np.ndarray, atol: float = 1e-6):
    assert env.origin.tolist() == [10000.0, 0.0, -20000.0]
    v = np.concatenate([m.vertices for m in env.meshes])
    assert v.dtype == np.float32 and np.abs(v).max() <= 1.5
    got = np.unique(np.round(env.to_world(v), 5), axis=0)
    want = np.unique(np.round(world, 5), axis=0)
    np.testing.assert_allclose(got, want, atol=atol, rtol=0)
    # the odd vertex is kept to float32 precision of its small local value, not to 1 mm
    local = v[np.argmin(np.linalg.norm(v - (FLOOR[4] - FAR), axis=1))].astype(np.float64)
    assert np.abs(local - (FLOOR[4] - FAR)).max() < 1e-7
    np.testing.assert_allclose(env.bounds + env.origin, [world.min(0), world.max(0)], atol=1e-6)


def test_obj_far_away(tmp_path):
    obj = tmp_path / "far.obj"
    obj.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in FLOOR)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in FACES))
    _check_far(load_environment(obj), FLOOR)


@pytest.mark.parametrize("fmt", ["stl", "ply"])
def test_stl_ply_far_away_are_exact_for_their_float32_coordinates(tmp_path, fmt):
    # trimesh writes these formats with float32 world coordinates: whatever they hold,
    # local = world - origin exactly
    p = tmp_path / f"far.{fmt}"
    p.write_bytes(trimesh.Trimesh(FLOOR, FACES, process=False).export(file_type=fmt))
    stored = trimesh.load_mesh(p, process=False).vertices.astype(np.float64)
    env = load_environment(p)
    assert env.origin.tolist() == FAR.tolist()
    v = np.concatenate([m.vertices for m in env.meshes]).astype(np.float64)
    np.testing.assert_array_equal(np.unique(v + env.origin, axis=0), np.unique(stored, axis=0))


def test_glb_node_translation_far_away_keeps_the_float32_vertices_bit_for_bit(tmp_path):
    pos = (FLOOR - FAR).astype(np.float32)
    idx = FACES.astype(np.uint16).reshape(-1)
    blob = pos.tobytes() + idx.tobytes()
    blob += b"\0" * (-len(blob) % 4)
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"name": "far", "translation": FAR.tolist(), "children": [1]},
                     {"name": "floor", "mesh": 0, "rotation": [0.0, 0.0, 0.0, 1.0]}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
                          "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
                         {"bufferView": 1, "componentType": 5123, "count": len(idx),
                          "type": "SCALAR"}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
                           {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": idx.nbytes}],
           "buffers": [{"byteLength": len(blob)}]}
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    p = tmp_path / "far.glb"
    p.write_bytes(b"glTF" + struct.pack("<II", 2, 28 + len(js) + len(blob))
                  + struct.pack("<I", len(js)) + b"JSON" + js
                  + struct.pack("<I", len(blob)) + b"BIN\0" + blob)
    env = load_environment(p)
    assert env.origin.tolist() == FAR.tolist()
    np.testing.assert_array_equal(env.meshes[0].vertices, pos)


def test_usd_z_up_centimetres_far_away(tmp_path):
    from pxr import Gf, Usd, UsdGeom

    p = tmp_path / "far.usda"
    stage = Usd.Stage.CreateNew(str(p))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    xf = UsdGeom.Xform.Define(stage, "/Far")
    # baker (x, y, z) = 0.01 * (X, Z, -Y) in the Z-up centimetre stage
    xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(1e6, 2e6, 0.0))
    mesh = UsdGeom.Mesh.Define(stage, "/Far/floor")
    cm = (FLOOR - FAR) * 100.0
    mesh.CreatePointsAttr([Gf.Vec3f(float(x), float(-z), float(y)) for x, y, z in cm])
    mesh.CreateFaceVertexCountsAttr([3] * len(FACES))
    mesh.CreateFaceVertexIndicesAttr([int(i) for i in FACES.reshape(-1)])
    stage.GetRootLayer().Save()
    env = load_environment(p)
    # points are float32 centimetres: compare with what the file holds
    held = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64) * 0.01
    world = np.stack([held[:, 0], held[:, 2], -held[:, 1]], 1) + FAR
    assert env.origin.tolist() == FAR.tolist()
    np.testing.assert_allclose(np.unique(env.to_world(env.meshes[0].vertices), axis=0),
                               np.unique(world, axis=0), atol=1e-6, rtol=0)


def test_near_origin_levels_keep_their_coordinates(tmp_path):
    near = FLOOR - FAR
    obj = tmp_path / "near.obj"
    obj.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in near)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in FACES))
    env = load_environment(obj)
    assert env.origin.tolist() == [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(np.unique(env.meshes[0].vertices, axis=0),
                                  np.unique(near.astype(np.float32), axis=0))


def test_world_inputs_move_into_the_local_frame():
    from baker.pipeline import in_local_frame

    cfg = BakeConfig(start=(10000.5, 0.25, -19999.0), prey_positions=((10001.0, 0.0, -20000.5),))
    local = in_local_frame(cfg, FAR)
    assert local.start == (0.5, 0.25, 1.0)
    assert local.prey_positions == ((1.0, 0.0, -0.5),)
    assert in_local_frame(cfg, np.zeros(3)) is cfg


def test_navmesh_report_takes_and_gives_world_points(tmp_path):
    from baker.config import DEFAULT_RIG, load_rig_config
    from baker.navmesh.report import format_report, run

    floor = trimesh.Trimesh(np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float) + FAR,
                            [[0, 2, 1], [0, 3, 2]], process=False)
    path = tmp_path / "far_floor.obj"
    floor.export(path)
    agent = load_rig_config(DEFAULT_RIG).navigation
    a, b = FAR + [-0.75, 0.0, -0.75], FAR + [0.75, 0.0, 0.5]
    png = tmp_path / "map.png" if _has_matplotlib() else None
    rep = run(path, agent, None, png=png, path_from=a, path_to=b)
    pts = rep.path.points
    assert rep.path.complete
    np.testing.assert_allclose(pts[0], a, atol=0.02)
    np.testing.assert_allclose(pts[-1], b, atol=0.02)
    assert "(10000." in format_report(rep)
    if png is not None:
        assert png.read_bytes()[:4] == b"\x89PNG"


def _has_matplotlib() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def test_map_axes_are_world(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from baker.navmesh import debug
    from conftest import flat_ground

    from baker.config import DEFAULT_RIG, load_rig_config
    from baker.environment.model import Sun
    from baker.navmesh.build import build

    env = Environment(meshes=(flat_ground(),), sun=Sun(direction=np.array([0.0, 1.0, 0.0])),
                      origin=FAR)
    agent = load_rig_config(DEFAULT_RIG).navigation
    from dataclasses import replace

    surface = build(env, replace(agent, cell_size=0.05))
    seen = {}
    real_close = plt.close

    def keep(fig):
        seen["xlim"] = fig.axes[0].get_xlim()
        seen["ylim"] = fig.axes[0].get_ylim()
        real_close(fig)

    monkeypatch.setattr(plt, "close", keep)
    debug.draw_map(surface, tmp_path / "m.png", paths=[np.array([[0.0, 0, 0], [0.5, 0, 0.5]])],
                   origin=env.origin)
    assert 9998.0 < min(seen["xlim"]) < max(seen["xlim"]) < 10002.0
    assert -20002.0 < min(seen["ylim"]) < max(seen["ylim"]) < -19998.0
