"""Scripted intent: the brain's drives from a fixed timeline instead of decisions.

`simulate(..., intent=ScriptedIntent(...))` (baker.sim.loop) runs the same agent, head, body and
legs as a bake, but what the creature does comes from a list of `Drive`s (walk this route at
this speed, stand, rear up, raise the ultimate legs, lunge): locomotion cycles (baker/cycles/)
are made this way.
It draws no random numbers and spawns no prey.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from baker.behaviour.brain import Senses
from baker.behaviour.intent import Intent, IntentSource

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Drive:
    """What the creature does from `start` seconds on (until the next drive starts).

    state       : timeline label (walk, run, turn_left, idle, cobra_rear, warning, strike, ...)
    route       : (k, 3) float metres or None: walk this polyline (from where the agent is)
    ahead       : metres or None: walk straight ahead of the head this far (a lunge)
    halt        : stop where the agent is
    speed_scale, turn_scale : multipliers on max speed and slither turn rate (the brain's)
    stopping_distance : metres
    cobra, warning    : 0/1 requests (the simulation ramps and smooths them)
    """

    start: float
    state: str
    route: np.ndarray | None = None
    ahead: float | None = None
    halt: bool = False
    speed_scale: float = 1.0
    turn_scale: float = 1.0
    stopping_distance: float = 0.0
    cobra: float = 0.0
    warning: float = 0.0


class ScriptedIntent(IntentSource):
    """The brain's drive interface (behaviour.brain.Brain) played from a timeline of drives:
    `step(senses)` returns this step's Intent (behaviour.intent).

    drives       : Drive, sorted by start (the first at 0)
    chain_period : [s] or None: antennae and ultimate legs repeat after this period (their
                   frequencies are rounded to whole cycles in it; locomotion.legs.posed_chains)
    """

    def __init__(self, drives, chain_period: float | None = None):
        self.drives = tuple(sorted(drives, key=lambda d: d.start))
        self.chain_period = chain_period
        self.events: list[dict] = []
        self._i = -1
        self.target: np.ndarray | None = None
        self.route: np.ndarray | None = None
        self.new_target = False
        self.halt = False
        self.speed_scale = 1.0
        self.turn_scale = 1.0
        self.stopping_distance = 0.0
        self.cobra = 0.0
        self.warning = 0.0

    def step(self, s: Senses) -> Intent:
        self.new_target = False
        self.halt = False
        nxt = self._i + 1
        if nxt < len(self.drives) and s.t + 1e-9 >= self.drives[nxt].start:
            self._enter(nxt, s)
        return self.intent()

    def _enter(self, i: int, s: Senses) -> None:
        d = self.drives[i]
        self._i = i
        if self.events:
            self.events[-1]["end"] = round(s.t, 6)
        self.events.append({"start": round(s.t, 6), "end": None, "state": d.state,
                            "details": {"scripted": True}})
        log.info("t=%.2f scripted -> %s", s.t, d.state)
        self.speed_scale, self.turn_scale = d.speed_scale, d.turn_scale
        self.stopping_distance = d.stopping_distance
        self.cobra, self.warning = d.cobra, d.warning
        if d.route is not None:
            self.route = np.asarray(d.route, dtype=np.float64).reshape(-1, 3)
            self.target, self.new_target = self.route[-1].copy(), True
        elif d.ahead is not None:
            h = np.asarray(s.heading, dtype=np.float64)
            self.target = np.asarray(s.head, dtype=np.float64) + h * float(d.ahead)
            self.route, self.new_target = self.target[None].copy(), True
        elif d.halt:
            self.target, self.route, self.halt = None, None, True

    def finish(self, t: float) -> tuple[dict, ...]:
        if self.events:
            self.events[-1]["end"] = round(t, 6)
        return tuple(self.events)
