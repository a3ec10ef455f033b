"""benchmarks/quality_sweep.py as a module for the tests (it is a script, not part of the
package): its bake-and-judge job and its far-from-the-origin copy of a GLB."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "quality_sweep.py"
_spec = importlib.util.spec_from_file_location("quality_sweep", _PATH)
quality_sweep = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(quality_sweep)

bake_and_judge = quality_sweep.bake_and_judge
moved_glb = quality_sweep.moved_glb
scene_environment = quality_sweep.scene_environment
