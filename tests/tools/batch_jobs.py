"""Jobs files and a small level for the batch tests (tests/unit/test_batch_jobs.py,
tests/integration/test_batch.py), built in code."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from baker.config import FLOOR_ENVIRONMENT

#: the 12-job batch: 3 seeds x 2 environments (the bundled rainforest floor and a small level)
#: x 2 behaviours, 1 s bakes without prey
JOBS_12 = """\
[defaults]
seconds = 1
prey = 0

[[job]]
name = "forest"
environment = "{forest}"
[job.matrix]
seed = [0, 1, 2]
behaviour = ["wander", "hunt"]

[[job]]
name = "small"
environment = "small.obj"
seconds = {small_seconds}
[job.matrix]
seed = [0, 1, 2]
behaviour = ["wander", "hunt"]
"""

NAMES_12 = [f"{env}-seed{s}-{b}" for env in ("forest", "small") for s in (0, 1, 2)
            for b in ("wander", "hunt")]


def write_small_level(path: Path, shift: float = 0.0) -> Path:
    """A 3 x 3 m floor with a rock and a log, as OBJ (`shift` moves the rock, in metres, for a
    level with other bytes)."""
    import trimesh
    from conftest import box_mesh, flat_ground

    parts = (flat_ground(3.0, 6),
             box_mesh("rock", (0.4 + shift, 0.05, 0.3), (0.08, 0.05, 0.1), (0.2, 0.2, 0.2, 1.0)),
             box_mesh("log", (-0.5, 0.03, -0.4), (0.3, 0.03, 0.06), (0.1, 0.05, 0.02, 1.0)))
    mesh = trimesh.util.concatenate([trimesh.Trimesh(m.vertices, m.faces, process=False)
                                     for m in parts])
    mesh.export(path)
    return path


def write_jobs(folder: Path, name: str = "jobs.toml", small_seconds: float = 1,
               extra: str = "") -> Path:
    """The 12-job file in `folder` (with small.obj beside it), plus `extra` TOML."""
    if not (folder / "small.obj").exists():
        write_small_level(folder / "small.obj")
    path = folder / name
    path.write_text(JOBS_12.format(forest=FLOOR_ENVIRONMENT.as_posix(),
                                   small_seconds=small_seconds) + extra)
    return path


def manifest(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())


def digests(out: Path, suffixes=(".glb", ".usd")) -> dict[str, str]:
    """sha256 of every output with one of `suffixes` in `out`."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(out.iterdir())
            if p.suffix in suffixes}


def stray_files(out: Path) -> list[str]:
    """Temporaries, backups and locks left in `out` (hidden files)."""
    return sorted(p.name for p in out.iterdir() if p.name.startswith("."))
