"""Test helpers for the two validators the project runs on its own output.

- `gltf_validate(path)`: the Khronos glTF-Validator (npm `gltf-validator`, pinned in
  tests/tools/package-lock.json), run through tests/tools/gltf_validate.mjs. `npm ci` installs it
  (and `three`, for tests/tools/three_probe.mjs) into tests/tools/node_modules on first use. Tests skip (with the reason) when node/npm are not on
  PATH; CI has them.
- `usd_validate(stage)`: pxr.UsdValidation with every registered validator; returns the errors.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import threading
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parent
SCRIPT = TOOLS / "gltf_validate.mjs"
_install_lock = threading.Lock()


@contextlib.contextmanager
def _file_lock():
    """Serialize `npm ci` across threads and processes (pytest-xdist workers)."""
    with _install_lock:
        try:
            import fcntl
        except ImportError:          # Windows: the thread lock is all we have
            yield
            return
        import tempfile

        with open(Path(tempfile.gettempdir()) / "baker-gltf-validator-npm.lock", "w") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)


def node_packages() -> list[str]:
    """The npm packages tests/tools/package.json pins (gltf-validator, three)."""
    return sorted(json.loads((TOOLS / "package.json").read_text())["dependencies"])


def ensure_node(what: str = "glTF validation") -> str:
    """The `node` executable, with every package of tests/tools/package.json installed in
    tests/tools/node_modules (`npm ci` from the pinned package-lock.json when one is missing).
    Skips the test (fails it in CI) when node or npm is not on PATH."""
    node = shutil.which("node")
    npm = shutil.which("npm")
    if node is None or npm is None:
        msg = f"{what} needs node and npm on PATH"
        if os.environ.get("CI"):
            pytest.fail(f"{msg}; CI must provide them")
        pytest.skip(f"{msg} (CI has them)")
    with _file_lock():
        if not all((TOOLS / "node_modules" / p / "package.json").is_file()
                   for p in node_packages()):
            r = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"],
                               cwd=TOOLS, capture_output=True, text=True, timeout=600)
            if r.returncode != 0:
                raise RuntimeError(f"npm ci failed in {TOOLS}:\n{r.stdout}\n{r.stderr}")
    return node


def _ensure_validator() -> str:
    return ensure_node("glTF validation")


def gltf_validate(path: Path | str) -> dict:
    """Run the Khronos validator on a .glb/.gltf file; return its JSON report."""
    node = _ensure_validator()
    r = subprocess.run([node, str(SCRIPT), str(Path(path).resolve())], cwd=TOOLS,
                       capture_output=True, text=True, timeout=600,
                       env={**os.environ, "NODE_NO_WARNINGS": "1"})
    if r.returncode not in (0, 1):
        raise RuntimeError(f"glTF validator failed ({r.returncode}):\n{r.stderr}")
    return json.loads(r.stdout)


def issues_summary(report: dict, severity: int) -> list[tuple[str, str, str]]:
    """(code, pointer, message) of the report's messages at `severity` (0 error, 1 warning,
    2 info, 3 hint)."""
    return [(m.get("code", ""), m.get("pointer", ""), m.get("message", ""))
            for m in report["issues"]["messages"] if m["severity"] == severity]


def usd_validate(stage) -> list:
    """pxr.UsdValidation errors (ValidationErrorType.Error) for an open stage."""
    from pxr import UsdValidation

    registry = UsdValidation.ValidationRegistry()
    ctx = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    errors = ctx.Validate(stage)
    return [e for e in errors if e.GetType() == UsdValidation.ValidationErrorType.Error]


def usd_issues(stage) -> list:
    """Every pxr.UsdValidation finding (errors, warnings, notes) for an open stage."""
    from pxr import UsdValidation

    registry = UsdValidation.ValidationRegistry()
    return list(UsdValidation.ValidationContext(registry.GetOrLoadAllValidators()).Validate(stage))
