"""--up z: a level whose file is +Z up (OBJ, PLY, STL from 3ds Max, Unreal or CAD; a glTF or
USD that says otherwise) is turned +Y up, (x, y, z) -> (x, z, -y), its sun with it; --units: a
level in centimetres (Unreal), millimetres, inches, ... is put in metres."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bad_inputs import good_gltf, pack_glb, usd_text
from baker.cli import main
from baker.environment.load import load_environment

#: the corpus floor and box, +Y up, and the same turned +Z up (x, y, z) -> (x, -z, y)
Y_UP = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2], [0.8, 0, -0.2], [1.2, 0, -0.2],
                 [1.2, 0.4, -0.2], [0.8, 0.4, -0.2]], float)
FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]])


def _obj(v: np.ndarray) -> str:
    return "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in v) + "".join(
        f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in FACES)


def z_up(v: np.ndarray) -> np.ndarray:
    return np.c_[v[:, 0], -v[:, 2], v[:, 1]]


def world(env) -> np.ndarray:
    return env.mesh.vertices.astype(np.float64) + env.origin


def test_obj_z_up_is_turned_y_up(tmp_path):
    (tmp_path / "y.obj").write_text(_obj(Y_UP))
    (tmp_path / "z.obj").write_text(_obj(z_up(Y_UP)))
    ref = load_environment(tmp_path / "y.obj")
    env = load_environment(tmp_path / "z.obj", up_axis="z")
    assert np.allclose(world(env), world(ref), atol=1e-6)
    assert np.array_equal(env.mesh.faces, ref.mesh.faces)      # a rotation keeps windings
    # read as +Y up, the floor would stand on its edge
    assert np.ptp(world(load_environment(tmp_path / "z.obj"))[:, 1]) == pytest.approx(4.0)


def test_gltf_sun_turns_with_the_level(tmp_path):
    doc, blob = good_gltf()
    (tmp_path / "scene.glb").write_bytes(pack_glb(doc, blob))
    plain = load_environment(tmp_path / "scene.glb")
    turned = load_environment(tmp_path / "scene.glb", up_axis="z")
    def y_up(v):        # the turn --up z applies: (x, y, z) -> (x, z, -y)
        return np.c_[v[:, 0], v[:, 2], -v[:, 1]]

    assert np.allclose(turned.sun.direction, y_up(plain.sun.direction[None])[0])
    assert np.allclose(world(turned), y_up(world(plain)), atol=1e-6)


def test_usd_up_overrides_the_stage(tmp_path):
    """A stage that says upAxis Y but holds +Z-up points: --up z reads it right."""
    text = usd_text(points="[" + ", ".join(f"({x:g}, {y:g}, {z:g})" for x, y, z in z_up(
        Y_UP[:4])) + "]")
    (tmp_path / "level.usda").write_text(text)
    env = load_environment(tmp_path / "level.usda", up_axis="z")
    assert np.ptp(world(env)[:, 1]) == pytest.approx(0.0, abs=1e-6)
    assert np.ptp(world(load_environment(tmp_path / "level.usda"))[:, 1]) == pytest.approx(4.0)


def test_bake_with_up_z(tmp_path):
    level = tmp_path / "z.obj"
    level.write_text(_obj(z_up(Y_UP)))
    out = tmp_path / "out" / "c"
    assert main(["bake", str(level), "--up", "z", "--seconds", "1", "--no-cache", "--out",
                 str(out)]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["environment"]["up_axis"] == "z"
    assert report["environment"]["bounds"][1][1] == pytest.approx(0.4, abs=1e-5)


def test_navmesh_hints_at_up_z(tmp_path, capsys):
    """Read +Y up, a +Z-up floor stands on its edge: the refusal says to pass --up z, which
    then finds the floor."""
    level = tmp_path / "z.obj"
    level.write_text(_obj(z_up(Y_UP[:4])).replace("f 5 6 7\nf 5 7 8\n", ""))
    assert main(["navmesh", str(level), "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "pass --up z" in err and len(err.strip().splitlines()) == 1
    assert main(["navmesh", str(level), "--no-cache", "--up", "z"]) == 0
    assert "walkable" in capsys.readouterr().out


@pytest.mark.parametrize("units, metres", [("cm", 0.01), ("mm", 0.001), ("ft", 0.3048)])
def test_units_put_the_level_in_metres(tmp_path, units, metres):
    """An Unreal-style level (+Z up, centimetres) and others: --up z --units cm gives the
    metre level back; USD's metersPerUnit is overridden the same way."""
    (tmp_path / "y.obj").write_text(_obj(Y_UP))
    (tmp_path / "z.obj").write_text(_obj(z_up(Y_UP) / metres))
    ref = load_environment(tmp_path / "y.obj")
    env = load_environment(tmp_path / "z.obj", up_axis="z", units=units)
    assert np.allclose(world(env), world(ref), atol=1e-5)
    text = usd_text(mpu="1").replace("(2, 0, 2)", f"({2 / metres:g}, 0, {2 / metres:g})")
    (tmp_path / "level.usda").write_text(text)
    usd = load_environment(tmp_path / "level.usda", units=units)
    assert world(usd).max(axis=0)[0] == pytest.approx(2.0, rel=1e-6)


def test_bake_with_units(tmp_path):
    level = tmp_path / "cm.obj"
    level.write_text(_obj(z_up(Y_UP) * 100))
    out = tmp_path / "out" / "c"
    assert main(["bake", str(level), "--up", "z", "--units", "cm", "--seconds", "1",
                 "--no-cache", "--out", str(out)]) == 0
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["environment"]["units"] == "cm"
    assert report["environment"]["bounds"][1][1] == pytest.approx(0.4, abs=1e-5)
