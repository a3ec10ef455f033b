"""benchmarks/quality_sweep.py's --level: a level of the user's own swept beside the bundled
scenes (its own scene name, the rig's scale), registered in the worker processes too."""

from __future__ import annotations

import pytest

import sweep

qs = sweep.quality_sweep


def test_a_level_is_a_scene_named_by_its_file_and_scale(tmp_path):
    level = tmp_path / "my level.obj"
    level.write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 3 2\n")
    name, entry = qs.level_scene(f"{level}@8", 45.0, 2)
    assert name == "my level@8"
    assert entry == dict(env=str(level.resolve()), scale=8.0, seconds=45.0, prey=2)
    assert qs.level_scene(str(level), 60.0, 0)[0] == "my level"
    assert qs.level_scene(str(level), 60.0, 0)[1]["scale"] is None
    saved = dict(qs.SCENES)
    try:
        qs.register_scenes(dict([(name, entry)]))
        assert qs.scene_environment(name, tmp_path) == level.resolve()
        cfg = qs.make_config(level.resolve(), name, 3, 1.0, tmp_path / "o", tmp_path / "c")
        assert cfg.prey == 2 and cfg.environment == level.resolve()
    finally:
        qs.SCENES.clear()
        qs.SCENES.update(saved)


@pytest.mark.parametrize("spec", ["missing.obj", "{level}@big"])
def test_a_bad_level_is_a_one_line_exit(tmp_path, spec):
    level = tmp_path / "l.obj"
    level.write_text("v 0 0 0\n")
    with pytest.raises(SystemExit, match="--level"):
        qs.level_scene(spec.format(level=level), 60.0, 0)
