"""The package's dependencies point one way (DESIGN.md): geometry <- environment <- navmesh <-
behaviour/locomotion <- run <- solve <- sim <- clip <- export, with the pipeline and CLI on
top. Only environment/ reads scene files and only export/ (plus the navigation cache and its
debug map) writes files, all through baker/atomic.py (temporary file, then rename)."""

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "baker"

#: what each part may import from baker (besides itself, errors and geometry)
ALLOWED = {
    "geometry": {"parallel"},           # fused: quat_rotate's kernel run on the main thread
                                        # once compiled (parallel imports only the stdlib
                                        # and signals, which imports only the stdlib)
    "errors": set(),
    "signals": set(),
    "atomic": {"signals"},
    "schema": set(),
    "streams": set(),
    "parallel": {"signals"},            # a crowd's per-creature work on forked processes;
                                        # the workers ignore the signals a bake handles
    "config": {"schema"},
    "context": {"signals"},
    "environment": {"parallel"},        # large ray batches cast on every CPU
    "navmesh": {"environment", "config", "atomic", "parallel"},   # the build's tiles on threads
    "locomotion": {"environment", "navmesh", "config", "rig",
                   "parallel"},         # the crowd's compiled chain; the head's look-ahead walks
                                        # the navigation's links (navmesh.surface.DIRS)
    "behaviour": {"environment", "navmesh", "locomotion", "config"},
    "rig": {"config"},
    "run": {"environment", "navmesh", "behaviour", "locomotion", "config", "context", "streams",
            "parallel"},                # a crowd's followers stepped on a forked peer too
    "solve": {"environment", "locomotion", "behaviour", "config", "run"},   # a run's record
    "sim": {"run", "solve", "config", "context", "streams", "parallel"},   # run, then solve
    "metrics": {"solve", "parallel"},        # the spine-gap search on every CPU
    "clip": {"rig", "solve"},
    "rootmotion": {"clip", "rig"},
    "export": {"clip", "rig", "solve", "environment", "config", "navmesh", "atomic",
               "inspect",                  # export/preview.py draws a bake read back from its GLB
               "parallel"},                # the reduction's compiled kernels off the main thread
    "inspect": {"environment", "metrics",      # reads a bake's files back to judge them
                "parallel"},                   # a USD opened on a thread with a large stack
    "inspect_file": {"inspect"},               # `baker inspect`: a file's summary
    "memory": {"navmesh", "config"},                     # a bake's memory, against the same RAM reading
}
TOP = {"pipeline", "cycles", "cli", "entry", "__init__", "__main__"}   # cycles: a pipeline too


def part_of(path: Path) -> str:
    rel = path.relative_to(PKG)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def baker_imports(path: Path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("baker"):
            yield node.module
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("baker"):
                    yield a.name


TOP |= {"batch"}     # `baker batch`: runs the pipeline once per job
MODULES = sorted(p for p in PKG.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_imports_point_one_way(path):
    part = part_of(path)
    if part in TOP:
        return
    allowed = ALLOWED[part] | {part, "errors", "geometry"}
    for mod in baker_imports(path):
        parts = mod.split(".")
        target = parts[1] if len(parts) > 1 else "__init__"
        if target == "__init__":
            continue
        assert target in allowed, f"{path.relative_to(PKG)} imports {mod}"


WRITERS = {"export", "atomic.py", "navmesh/cache.py", "navmesh/debug.py", "navmesh/report.py"}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_only_export_writes_files(path):
    rel = str(path.relative_to(PKG))
    if rel.split("/")[0] in WRITERS or rel in WRITERS or part_of(path) in TOP:
        return
    text = path.read_text()
    for call in ("write_bytes(", "write_text(", ".savefig(", "np.save", "os.replace(",
                 ".Export(", "mkstemp("):
        assert call not in text, f"{rel} writes files ({call})"
    assert not re.search(r"open\([^)]*[\"'][wax]b?[\"']", text), f"{rel} opens a file for writing"
