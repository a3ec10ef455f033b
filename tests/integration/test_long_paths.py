"""Paths the file system refuses as too long (ENAMETOOLONG: the whole path over PATH_MAX, or one
name over NAME_MAX), given to any command or option: exit 2 with one line naming the path, no
traceback, nothing written. A cache folder too long to use is a warning: the bake goes on
without the cache, as with any cache folder that cannot be written."""

from __future__ import annotations

import os

import pytest

from baker.cli import main


def long_folder(tmp_path, parts=25):
    """A path over PATH_MAX (4096 on Linux) made of names that each fit NAME_MAX."""
    folder = os.path.join(str(tmp_path), *(["d" * 200] * parts))
    assert len(os.fsencode(folder)) > os.pathconf(str(tmp_path), "PC_PATH_MAX")
    return folder


def one_error(code, err):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2, err
    assert "Traceback" not in err
    assert len(lines) == 1, err
    assert "path is too long" in lines[0], lines[0]
    assert len(lines[0]) < 200, lines[0]
    return lines[0]


COMMANDS = {
    "bake-environment": lambda L, out: ["bake", f"{L}/level.glb", "--out", out],
    "bake-out": lambda L, out: ["bake", "--out", f"{L}/centipede"],
    "bake-out-folder": lambda L, out: ["bake", "--out", f"{L}/"],
    "bake-rig": lambda L, out: ["bake", "--rig", f"{L}/rig.toml", "--out", out],
    "bake-long-name": lambda L, out: ["bake", "x" * 300 + ".glb", "--out", out],
    "navmesh": lambda L, out: ["navmesh", f"{L}/level.glb"],
    "preview": lambda L, out: ["preview", f"{L}/bake.glb"],
    "inspect": lambda L, out: ["inspect", f"{L}/bake.glb"],
    "batch": lambda L, out: ["batch", f"{L}/jobs.toml"],
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_too_long_path_is_one_line(name, tmp_path, capsys):
    out = tmp_path / "out" / "centipede"
    args = COMMANDS[name](long_folder(tmp_path), str(out))
    line = one_error(main([*args, "--seconds", "1"] if args[0] == "bake" else args),
                     capsys.readouterr().err)
    assert "..." in line or "x" * 20 in line      # the path, shortened to keep one line
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_too_long_cache_folder_bakes_without_cache(tmp_path, capsys, caplog):
    out = tmp_path / "out" / "centipede"
    code = main(["bake", "--seconds", "1", "--out", str(out),
                 "--cache-dir", long_folder(tmp_path)])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "Traceback" not in err
    assert out.with_suffix(".glb").exists() and out.with_suffix(".usd").exists()
    warned = [r.getMessage() for r in caplog.records if "cannot be written" in r.getMessage()]
    assert warned and all(len(w) < 200 for w in warned), warned     # the folder shortened
