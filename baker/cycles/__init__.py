"""Locomotion cycles: a clip library (walk, run, turns, idle, one-shots) on flat ground,
written by `baker cycles` (see library.py for the steps)."""

from baker.cycles.library import CyclesResult, bake_cycles
from baker.cycles.spec import CyclesConfig, validate_cycles

__all__ = ["CyclesConfig", "CyclesResult", "bake_cycles", "validate_cycles"]
