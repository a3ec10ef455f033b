"""Fast start (issue 15): `baker --help`, `baker bake --help` and option errors are answered
before the heavy libraries are imported. Each case runs the console entry point in a fresh
interpreter and reports which modules it had imported when it returned (no timing here: the
--help time is in benchmarks/quickstart.py)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: the console script `baker` (baker.entry:main), then the heavy modules that were imported
PROBE = """
import json, sys
from baker.entry import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.stdout)
"""

#: never imported before a command runs: geometry, meshes, USD, ray casting, glTF, compiled code
HEAVY = ("scipy", "trimesh", "pxr", "embreex", "pygltflib", "matplotlib", "numba", "llvmlite")
#: nor, for the help texts, the option schema and the arrays
HELP_HEAVY = HEAVY + ("numpy", "pydantic", "baker.config", "baker.schema")


def run_probe(*args: str) -> tuple[dict, str]:
    r = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True,
                       timeout=120)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    return out, r.stderr


def heavy_loaded(modules: list[str], names: tuple[str, ...]) -> list[str]:
    return sorted(n for n in names if any(m == n or m.startswith(n + ".") for m in modules))


@pytest.mark.parametrize("args", [["--help"], ["bake", "--help"], ["navmesh", "--help"],
                                  ["--version"]])
def test_help_imports_nothing_heavy(args):
    out, err = run_probe(*args)
    assert out["code"] == 0
    assert heavy_loaded(out["modules"], HELP_HEAVY) == []
    assert err == ""


@pytest.mark.parametrize("args, where", [
    (["bake", "--seconds", "abc"], "--seconds"),
    (["bake", "--fps", "7"], "--fps"),
    (["bake", "--prey", "99"], "--prey"),
    (["bake", "--tolerance", "-1"], "--tolerance"),
    (["bake", "--bogus"], "--bogus"),
])
def test_option_errors_come_before_heavy_imports(args, where):
    out, err = run_probe(*args)
    assert out["code"] == 2
    assert heavy_loaded(out["modules"], HEAVY) == []
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and where in lines[0], err
    assert "Traceback" not in err


def test_click_type_errors_import_no_schema():
    """An option that is not a number is rejected by the command line parser alone."""
    out, _ = run_probe("bake", "--seconds", "abc")
    assert heavy_loaded(out["modules"], HELP_HEAVY) == []
