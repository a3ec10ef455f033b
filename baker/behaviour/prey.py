"""Prey: a capsule-shaped navigation agent that wanders, and flees directly away from the
centipede when it comes close (with a burst of speed that tires). Under cover (in shade) it
keeps still longer: it bolts only when the centipede is within `cover_trigger` of its usual
flee distance."""

from __future__ import annotations

import math

import numpy as np

from baker.config import PreyConfig
from baker.locomotion.agent import PathAgent

#: per-frame prey modes, as recorded in the trajectory
FREE, CAPTURED, HELD, HIDDEN = 0, 1, 2, 3


class Prey:
    """One prey animal. `mode` is FREE, CAPTURED (bitten, stopped), HELD (carried at the
    centipede's head while it feeds) or HIDDEN (eaten)."""

    def __init__(self, index: int, position: np.ndarray, cfg: PreyConfig, nav,
                 rng: np.random.Generator, in_cover=None):
        self.index = index
        self.name = f"prey_{index + 1:02d}"
        self.cfg = cfg
        self.nav = nav
        self.rng = rng
        self.agent = PathAgent(position, cfg.wander_speed, cfg.acceleration, 0.0)
        self.mode = FREE
        self.fleeing = False
        self.stamina = cfg.stamina
        self._next_wander = 0.0
        self._next_flee_plan = 0.0
        # (t, (3,) point) -> bool: the point is in shade at time t (None: never under cover)
        self.in_cover = in_cover

    @property
    def position(self) -> np.ndarray:
        return self.agent.position

    def step(self, t: float, dt: float, threat: np.ndarray | None) -> None:
        if self.mode != FREE:
            self.agent.speed = 0.0
            return
        c = self.cfg
        if threat is not None:
            # position - threat in Python floats (the same bits as the (3,) arrays'), the array
            # built only when a flight is planned
            (px, py, pz), (tx, ty, tz) = self.agent.position.tolist(), threat.tolist()
            away = (px - tx, py - ty, pz - tz)
            dist = math.hypot(away[0], away[2])
        else:
            away, dist = None, math.inf
        # flee when the centipede comes within the trigger (closer when under cover, where it
        # keeps still); keep running until well clear
        trigger = c.flee_trigger * (1.5 if self.fleeing else 1.0)
        if (not self.fleeing and dist < trigger and self.in_cover is not None
                and self.in_cover(t, self.position)):
            trigger *= c.cover_trigger
        self.fleeing = dist < trigger
        if self.fleeing:
            self.stamina = max(self.stamina - dt, 0.0)
            self.agent.max_speed = c.flee_speed if self.stamina > 0 else c.tired_speed
            if t >= self._next_flee_plan:
                self._next_flee_plan = t + 0.25
                self._flee(np.array(away) / max(dist, 1e-9))
        else:
            self.stamina = min(self.stamina + c.recovery * dt, c.stamina)
            self.agent.max_speed = c.wander_speed
            if t >= self._next_wander:
                self._next_wander = t + 3.0
                target = self.nav.random_point_near(self.position, 4.0 * c.flee_trigger, self.rng)
                if target is not None:
                    self.agent.set_path(self.nav.find_path(self.position, target).points)
        self.agent.step(dt)

    def _flee(self, away: np.ndarray) -> None:
        """Run directly away; if that is blocked, the reachable point closest to it."""
        away = away.copy()
        away[1] = 0.0
        goal = self.position + away * (4.0 * self.cfg.flee_trigger)
        self.agent.set_path(self.nav.find_path(self.position, goal).points)
