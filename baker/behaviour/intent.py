"""Intent: what the creature means to do this step, the one record a decision maker hands the
run stage (baker/run). The brain (behaviour.brain.Brain) and a scripted timeline
(behaviour.script.ScriptedIntent) both produce one every step from `step(senses)`; the
follower (run.follow.Follower.apply) turns it into the agent's path and the head's gait.

A producer keeps returning the same Intent object while nothing in it changes, so a step
costs no allocation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Intent:
    """The drives of one step.

    Goal (what the agent walks to):
    target     : (3,) float64 metres world, or None: the goal point
    route      : (k, 3) float64 metres world, or None: walk this polyline to `target` instead
                 of planning a path (scripted locomotion)
    new_target : this step brings a new goal: plan (or take) a new path now
    halt       : this step stops the agent where it is (the head closes up behind it)

    Speed:
    speed_scale       : multiplier on the maximum speed (2 while hunting)
    turn_scale        : multiplier on the slither's turn rate
    stopping_distance : metres short of the goal the agent stops

    Posture (0/1 requests; the run stage ramps the cobra, the solve stage smooths both):
    cobra   : rear the front third up
    warning : Posture 1, the ultimate legs raised
    """

    target: np.ndarray | None = None
    route: np.ndarray | None = None
    new_target: bool = False
    halt: bool = False
    speed_scale: float = 1.0
    turn_scale: float = 1.0
    stopping_distance: float = 0.0
    cobra: float = 0.0
    warning: float = 0.0


class IntentSource:
    """Mixin of the two producers: `intent()` packs the producer's drive attributes (target,
    route, new_target, halt, speed_scale, turn_scale, stopping_distance, cobra, warning) into
    an Intent, reusing the last one while they are unchanged."""

    _last: Intent | None = None

    def intent(self) -> Intent:
        last = self._last
        if (last is None or self.new_target or self.halt or last.new_target or last.halt
                or last.target is not self.target or last.route is not self.route
                or last.speed_scale != self.speed_scale or last.turn_scale != self.turn_scale
                or last.stopping_distance != self.stopping_distance
                or last.cobra != self.cobra or last.warning != self.warning):
            last = self._last = Intent(self.target, self.route, self.new_target, self.halt,
                                       self.speed_scale, self.turn_scale,
                                       self.stopping_distance, self.cobra, self.warning)
        return last
