"""The navigation cache from the command line: `--cache-max` on `bake` and `navmesh`, a
damaged entry and an unwritable cache folder each cost one warning line and the bake goes on."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bakeproc import run

ROOT = Path(__file__).resolve().parents[2]
LEVEL = ROOT / "environments" / "multistorey.glb"       # builds in a fraction of a second
LEVEL_ARGS = [str(LEVEL), "--scale", "8"]
WARNING = re.compile(r"^WARNING .*navigation cache", re.IGNORECASE)


def bake(tmp_path, cache_args, seed=0):
    return run(["bake", *LEVEL_ARGS, "--seconds", "1", "--seed", str(seed),
                "--out", tmp_path / "out" / "c", *cache_args])


def entries(folder: Path):
    return sorted(folder.glob("navsurface-*.npz"))


@pytest.mark.slow
def test_unwritable_cache_folder_bakes_with_one_warning(tmp_path):
    """A folder under a regular file can be neither created nor written, even by root (a
    cache folder that is itself a file is refused by the option's own check)."""
    blocker = tmp_path / "file"
    blocker.write_bytes(b"x")
    folder = blocker / "cache"
    done = bake(tmp_path, ["--cache-dir", folder])
    assert done.code == 0, done.stderr
    assert len(done.err_lines) == 1 and WARNING.search(done.err_lines[0]), done.stderr
    assert "without the cache" in done.err_lines[0]
    assert (tmp_path / "out" / "c.glb").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["empty", "truncated"])
def test_damaged_entry_is_rebuilt_with_one_warning(tmp_path, damage):
    folder = tmp_path / "cache"
    first = run(["navmesh", *LEVEL_ARGS, "--cache-dir", folder])
    assert first.code == 0 and not first.err_lines, first.stderr
    [entry] = entries(folder)
    data = entry.read_bytes()
    entry.write_bytes(b"" if damage == "empty" else data[: len(data) // 2])
    done = bake(tmp_path, ["--cache-dir", folder])
    assert done.code == 0, done.stderr
    assert len(done.err_lines) == 1 and "damaged" in done.err_lines[0], done.stderr
    assert entry.read_bytes() == data                    # rebuilt and rewritten, identical
    again = run(["navmesh", *LEVEL_ARGS, "--cache-dir", folder])
    assert again.code == 0 and not again.err_lines and "cache hit" in again.stdout


@pytest.mark.slow
def test_cache_max_on_both_commands(tmp_path):
    folder = tmp_path / "cache"
    done = run(["navmesh", *LEVEL_ARGS, "--cache-dir", folder, "--cache-max", "0"])
    assert done.code == 0 and entries(folder) == [], done.stderr
    done = bake(tmp_path, ["--cache-dir", folder, "--cache-max", "0"])
    assert done.code == 0 and entries(folder) == [], done.stderr
    done = bake(tmp_path, ["--cache-dir", folder, "--cache-max", "100"])
    assert done.code == 0 and len(entries(folder)) == 1, done.stderr
    # a second agent size: a second entry; with room for one, the older one goes
    size = entries(folder)[0].stat().st_size
    done = run(["navmesh", *LEVEL_ARGS, "--agent-radius", "0.2", "--cache-dir", folder,
                "--cache-max", str(1.5 * size / 2 ** 20)])
    assert done.code == 0, done.stderr
    assert len(entries(folder)) == 1
