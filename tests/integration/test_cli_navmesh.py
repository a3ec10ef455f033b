"""`baker navmesh ENV`: the report, the on-disk cache shared with `bake`, the map PNG with a path,
the agent overrides and --scale (also on `bake`), and clean user errors."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from baker.cli import main
from baker.config import DEFAULT_RIG, load_rig_config

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    """A 2 x 2 m floor with a 0.5 x 0.5 m block 3 cm high in one corner (a riser between the
    default rig's step height and 5 cm)."""
    d = tmp_path_factory.mktemp("navscene")
    floor = trimesh.Trimesh([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]],
                            [[0, 2, 1], [0, 3, 2]], process=False)
    block = trimesh.creation.box(extents=(0.5, 0.03, 0.5))
    block.apply_translation((0.5, 0.015, 0.5))
    path = d / "scene.obj"
    trimesh.util.concatenate([floor, block]).export(path)
    return path


def run(args, capsys):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def value(out: str, pattern: str) -> float:
    m = re.search(pattern, out)
    assert m, (pattern, out)
    return float(m.group(1).replace(",", ""))


def test_report_cache_miss_then_hit_and_bake_reuses_it(scene, tmp_path, capsys):
    cache = tmp_path / "cache"
    code, out, err = run(["navmesh", scene, "--cache-dir", cache], capsys)
    assert code == 0, err
    assert "(cache miss)" in out and str(cache) in out
    assert value(out, r"([\d,]+) walkable samples") > 1000
    assert 2.0 < value(out, r"([\d.]+) m\^2 walkable") < 4.0
    assert value(out, r"(\d+) components") == 2  # floor and block top (3 cm > step)
    assert 50.0 < value(out, r"largest ([\d.]+) %") < 100.0
    files = list(cache.glob("navsurface-*.npz"))
    assert len(files) == 1 and files[0].name in out
    code, out2, _ = run(["navmesh", scene, "--cache-dir", cache], capsys)
    assert code == 0 and "(cache hit)" in out2 and files[0].name in out2
    # `bake` looks for the same file: its build is skipped
    code, _, err = run(["bake", scene, "--seconds", 1, "--format", "glb", "--out",
                        tmp_path / "c", "--cache-dir", cache], capsys)
    assert code == 0, err
    rep = json.loads((tmp_path / "c.json").read_text())
    assert rep["navmesh_cache_hit"] is True
    assert list(cache.glob("navsurface-*.npz")) == files


def test_no_cache_writes_nothing(scene, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    code, out, _ = run(["navmesh", scene, "--no-cache"], capsys)
    assert code == 0 and "(cache off)" in out
    assert not (tmp_path / "xdg").exists()


def test_default_cache_dir_is_the_bake_default(scene, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    code, out, _ = run(["navmesh", scene], capsys)
    assert code == 0
    assert len(list((tmp_path / "xdg" / "baker" / "navmesh").glob("navsurface-*.npz"))) == 1


def test_png_map_with_path(scene, tmp_path, capsys):
    png = tmp_path / "maps" / "map.png"
    code, out, err = run(["navmesh", scene, "--no-cache", "--png", png,
                          "--from", "-0.8,0,-0.8", "--to", "0.8,0,-0.6"], capsys)
    assert code == 0, err
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert [p.name for p in png.parent.iterdir()] == ["map.png"]  # no temporary left over
    assert "map -> " in out and "complete" in out
    assert 1.5 < value(out, r": ([\d.]+) m, \d+ points") < 1.8
    # a goal on the block top is on another component: a flagged partial path
    code, out, _ = run(["navmesh", scene, "--no-cache", "--from", "-0.8,0,-0.8",
                        "--to", "0.5,0.03,0.5"], capsys)
    assert code == 0 and "PARTIAL" in out


def test_agent_overrides_and_scale(scene, capsys):
    code, out, _ = run(["navmesh", scene, "--no-cache", "--step-height", "0.05",
                        "--agent-radius", "0.03", "--agent-height", "0.1", "--max-slope", "45",
                        "--cell-size", "0.02"], capsys)
    assert code == 0
    assert value(out, r"(\d+) components") == 1  # the 3 cm block is climbed now
    assert value(out, r"agent radius ([\d.]+) m") == pytest.approx(0.03)
    assert value(out, r"height ([\d.]+) m") == pytest.approx(0.1)
    assert value(out, r"step ([\d.]+) m") == pytest.approx(0.05)
    assert value(out, r"max slope ([\d.]+) deg") == pytest.approx(45.0)
    assert value(out, r"columns of ([\d.]+) m") == pytest.approx(0.02)
    code, out, _ = run(["navmesh", scene, "--no-cache", "--scale", "3"], capsys)
    assert code == 0
    base = load_rig_config(DEFAULT_RIG).navigation  # tripled
    assert value(out, r"agent radius ([\d.]+) m") == pytest.approx(3 * base.radius, rel=1e-3)
    assert value(out, r"columns of ([\d.]+) m") == pytest.approx(3 * base.cell_size, rel=1e-3)
    assert value(out, r"step ([\d.]+) m") == pytest.approx(3 * base.step_height, rel=1e-3)
    assert value(out, r"height ([\d.]+) m") == pytest.approx(3 * base.height, rel=1e-3)


def test_bake_takes_scale_and_overrides(scene, tmp_path, capsys):
    code, _, err = run(["bake", scene, "--seconds", 1, "--format", "glb", "--no-cache",
                        "--out", tmp_path / "g", "--scale", 2, "--max-slope", 50], capsys)
    assert code == 0, err
    rep = json.loads((tmp_path / "g.json").read_text())
    assert rep["parameters"]["rig"]["body"]["length"] == pytest.approx(0.5)
    assert rep["navmesh"]["agent"]["max_slope"] == pytest.approx(np.radians(50.0))
    base = load_rig_config(DEFAULT_RIG).navigation
    assert rep["navmesh"]["cell_size"] == pytest.approx(2 * base.cell_size)


@pytest.mark.parametrize("args,word", [
    (["--agent-radius", "0"], "--agent-radius"),
    (["--agent-radius", "nan"], "--agent-radius"),
    (["--agent-height", "-1"], "--agent-height"),
    (["--step-height", "-0.1"], "--step-height"),
    (["--max-slope", "90"], "--max-slope"),
    (["--max-slope", "0"], "--max-slope"),
    (["--cell-size", "0"], "--cell-size"),
    (["--scale", "0"], "--scale"),
    (["--scale", "1e6"], "--scale"),
    (["--scale", "big"], "--scale"),
    (["--from", "0,0,0"], "--to"),
    (["--from", "0,0", "--to", "1,0,0"], "--from"),
    (["--png", "map.jpg"], ".png"),
    (["--cell-size", "1e-5"], "cell size"),
])
def test_bad_options_exit_2_with_one_line(scene, tmp_path, capsys, args, word):
    code, out, err = run(["navmesh", scene, "--no-cache", *args], capsys)
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert word.lower() in lines[0].lower(), lines[0]
    assert not list(tmp_path.iterdir())


def test_bad_bake_override_and_missing_environment(tmp_path, capsys):
    code, _, err = run(["bake", "--max-slope", "100", "--out", tmp_path / "c"], capsys)
    assert code == 2 and "--max-slope" in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())
    code, _, err = run(["navmesh", tmp_path / "missing.obj"], capsys)
    assert code == 2 and "not found" in err and len(err.strip().splitlines()) == 1
