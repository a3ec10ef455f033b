"""Wander (SEED.md): every `interval` seconds pick a random reachable point within `radius` of
the head and walk there."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Intent:
    """What the brain wants this tick.

    state  : behaviour name for the timeline, e.g. "wander"
    target : (3,) float metres world, or None to keep the current path
    details: JSON-safe extra facts for the timeline
    """

    state: str
    target: np.ndarray | None
    details: dict


class WanderBrain:
    """Picks a new reachable wander target every `interval` seconds."""

    def __init__(self, nav, interval: float, radius: float, rng: np.random.Generator):
        self.nav = nav
        self.interval = float(interval)
        self.radius = float(radius)
        self.rng = rng
        self._next = 0.0

    def step(self, t: float, head: np.ndarray) -> Intent | None:
        """Return a new Intent when it is time to choose, else None."""
        if t + 1e-9 < self._next:
            return None
        self._next = t + self.interval
        target = self.nav.random_point_near(head, self.radius, self.rng)
        if target is None:
            return Intent("wander", None, {"target": None})
        return Intent("wander", target, {"target": [round(float(x), 4) for x in target]})
