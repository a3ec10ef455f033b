"""The brain: a state machine that picks what the centipede does, from SEED.md's behaviours.

States
    wander         walk to a random reachable point; a new one at every decision (with
                   wander.keep_target > 0: once it is reached, or kept that long). A target
                   on another floor (wander.journey_rise above or below the head, the path to
                   it running over another walkable layer) is a journey: no d10 is rolled
                   until it arrives or wander.journey_time has passed
    seek_shade     walk to a remembered shaded spot
    rest_in_shade  stay put in shade
    cobra          scout: rear the front third up for a look over an obstacle ahead (taller than
                   a step, lower than the cobra height) while walking on
    hunt           onslaught: speed x2, slither turn rate x2, runs onto the prey; the front is
                   raised for a look (scouting) for its first moments
    strike         the bite: the prey stops
    feed           hold the prey at the head, then it is gone
    warning        Posture 1 (ultimate legs raised) when the shade it rested in is lost

Every `decision_interval` seconds a d10 (0-9) is rolled: with enough known shade spots and a
roll <= shade_roll_max the centipede goes to a random known spot, or stays if it is already in
shade; otherwise it wanders. Prey within detection range interrupts that with hunt -> strike ->
feed, or gives up (back to wander) when the prey has stayed out of range for GIVE_UP_TIME.
After a meal it is sated for `sated_time` seconds: it hunts no more, and every roll in that time
goes to shade (it digests in a shaded spot, where its kind shelter).
Every transition is logged and recorded in the timeline as (start, end, state, details).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from baker.behaviour import perception
from baker.behaviour.claims import Claims
from baker.behaviour.intent import Intent, IntentSource
from baker.behaviour.prey import CAPTURED, FREE, HELD, HIDDEN, Prey
from baker.behaviour.sun import SunPath
from baker.config import RigConfig

log = logging.getLogger(__name__)

#: [s] after the agent has arrived at a shade spot, how long the head has to get into its shade
SETTLE_TIME = 1.0
#: [s] longest cobra rearing at one obstacle (it may be pressing against one it cannot climb)
COBRA_MAX_TIME = 3.0
#: [s] a hunt gives up once the prey has stayed out of range this long (beyond 1.2 detection
#: ranges); a prey out of cover bolts at about the detection range, faster than the hunter, and
#: crossed that margin within its burst, so a hunt ended the moment it did, just before the
#: prey tired
GIVE_UP_TIME = 2.0
#: a hunt that is gaining on its prey goes on out of range (the prey's burst has tired), while
#: the gap shrinks by at least GAIN_BL body lengths every GAP_INTERVAL seconds and is within
#: GAIN_RANGE detection ranges
GAP_INTERVAL = 0.25
GAIN_BL = 0.02
GAIN_RANGE = 2.0
#: [m] a remembered shade spot has shade this far around it (4 rays on the level)
SPOT_MARGIN = 0.05

STATES = ("wander", "seek_shade", "rest_in_shade", "cobra", "hunt", "strike", "feed", "warning")
MODES = ("auto", "wander", "shade", "hunt")


@dataclass
class Senses:
    """What the brain is told each step about the body."""

    t: float
    head: np.ndarray          # (3,) world
    heading: np.ndarray       # (3,) unit, horizontal
    arrived: bool             # the agent reached its target (within stopping distance)


class Brain(IntentSource):
    """Chooses targets and drives: `step(senses)` returns this step's Intent
    (behaviour.intent), made from the drive attributes below.

    target, new_target, halt : the goal point, a new goal this step, stop this step
    speed_scale, turn_scale  : multipliers on max speed and slither turn rate
    stopping_distance        : metres
    cobra                    : 0/1 request for the cobra lift (smoothed by the body stage)
    warning                  : 0/1 request for Posture 1
    route                    : always None: the brain gives targets, the path is planned
    """

    route = None

    def __init__(self, rig: RigConfig, nav, rays, sun: SunPath, rng: np.random.Generator,
                 preys: list[Prey], *, mode: str = "auto", cobra_mode: str = "auto",
                 claims: Claims | None = None, who: int = 0):
        """claims, who : in a crowd, the shade spots and prey its creatures hold (shared by
        all brains), and this creature's number; None for a lone creature."""
        self.rig = rig
        self.claims, self.who = claims, who
        self.b = rig.behaviour
        self.nav = nav
        self.rays = rays
        self.sun = sun
        self.rng = rng
        self.preys = preys
        self.shade_on = mode in ("auto", "shade")
        self.hunt_on = mode in ("auto", "hunt")
        self.cobra_mode = cobra_mode
        self.state = ""
        self.since = 0.0
        self.events: list[dict] = []
        self.shade_spots: list[np.ndarray] = []
        self._last_memory = -math.inf
        self._next_decision = 0.0
        self._next_perception = 0.0
        self._next_replan = 0.0
        self._scout_until = -1.0
        self._obstacle = False     # an obstacle worth rearing at is ahead (last perception)
        self._ignore: dict[str, float] = {}   # prey given up on, until this time
        self._sated_until = -math.inf   # after a meal: no hunting, and it digests in shade
        self._out_of_range = math.inf   # when the hunted prey last went out of range
        self._gap, self._next_gap, self._gaining = math.inf, 0.0, False  # gaining on the prey
        self._reachable, self._next_reach_check = True, 0.0   # the prey within reach (of late)
        self._now = 0.0
        # (senses, _sense's answer) measured ahead of the step for a crowd (sense_together)
        self._sensed: tuple | None = None
        # two rings of points around the head where shade is noticed (8 at half the sense
        # radius, 16 at the full radius)
        r = self.b.shade_sense_radius
        rings = []
        for frac, n in ((0.5, 8), (1.0, 16)):
            a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
            rings.append(np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], 1) * (frac * r))
        self._ring = np.vstack(rings) if r > 0 else np.zeros((0, 3))
        self._resume = ("wander", None)
        self.shaded = False
        self._sought = None        # the remembered shade spot being walked to
        self._arrived_at = None    # when the agent reached it
        self._target_at = -math.inf  # when the wander target was drawn
        self._journey = 0.0        # how long that target is walked to through the d10's rolls
        self.prey: Prey | None = None
        self.target: np.ndarray | None = None
        self.new_target = False
        self.halt = False
        self.speed_scale = 1.0
        self.turn_scale = 1.0
        self.stopping_distance = rig.locomotion.stopping_distance
        self.cobra = 1.0 if cobra_mode == "always" else 0.0
        self.warning = 0.0

    # ------------------------------------------------------------------ transitions
    def _enter(self, state: str, t: float, **details) -> None:
        if self.events:
            self.events[-1]["end"] = round(t, 6)
        self.events.append({"start": round(t, 6), "end": None, "state": state,
                            "details": details})
        log.info("t=%.2f %s -> %s %s", t, self.state or "start", state, details or "")
        self.state, self.since = state, t
        if self.claims is not None:
            if state not in ("seek_shade", "rest_in_shade", "cobra"):
                self.claims.free_spot(self.who)
            if state not in ("hunt", "strike", "feed"):
                self.claims.free_prey(self.who)
        hunting = state in ("hunt",)
        self.speed_scale = self.b.onslaught_speed if hunting else 1.0
        self.turn_scale = self.b.onslaught_turn_rate if hunting else 1.0
        # While hunting the agent runs onto the prey (the strike check stops it); a shade spot
        # is walked right onto, since its shadow may be small.
        self.stopping_distance = (0.0 if hunting else self.rig.body.spacing if state == "seek_shade"
                                  else self.rig.locomotion.stopping_distance)

    def _go(self, target: np.ndarray | None) -> None:
        self.target = target
        self.new_target = target is not None

    def _stop(self, head: np.ndarray) -> None:
        """Stop where the agent is (the head closes up behind it)."""
        self.target = None
        self.halt = True

    def finish(self, t: float) -> tuple[dict, ...]:
        if self.events:
            self.events[-1]["end"] = round(t, 6)
        return tuple(self.events)

    # ------------------------------------------------------------------ the step
    def step(self, s: Senses) -> Intent:
        t = s.t
        self._now = t
        self.new_target = False
        self.halt = False
        if t + 1e-9 >= self._next_perception:       # perceives(t)
            self._next_perception = t + 1.0 / self.b.perception_rate
            self._perceive(s)
        _ACTS[self.state](self, s, t + 1e-9 >= self._next_decision)
        state = self.state
        if self.cobra_mode == "always":
            self.cobra = 1.0
        elif self.cobra_mode == "never":
            self.cobra = 0.0
        else:
            self.cobra = 1.0 if (state == "cobra" or t < self._scout_until) else 0.0
        self.warning = 1.0 if state == "warning" else 0.0
        return self.intent()

    def perceives(self, t: float) -> bool:
        """This step (at time t) perceives."""
        return t + 1e-9 >= self._next_perception

    def _looks_ahead(self) -> bool:
        """The perception looks for an obstacle to rear at (in the state the step starts in)."""
        return self.cobra_mode == "auto" and self.state in ("wander", "seek_shade", "cobra")

    def _sense(self, s: Senses) -> tuple:
        """What a perception measures: (sun, the head on its layer, the head and the ring of
        points around it (25, 3) on their layers, their shade (25,) bool, an obstacle ahead
        (None when not looked for)); measured for a whole crowd at once by
        sense_together."""
        if self._sensed is not None:
            key, sensed = self._sensed
            self._sensed = None
            if key == _senses_key(s):
                return sensed
        return sense_together([self], [s], keep=False)[0]

    def _perceive(self, s: Senses) -> None:
        sun, head, pts, shade, obstacle = self._sense(s)
        self.shaded = bool(shade[0])
        if self.shade_on and shade.any() and s.t - self._last_memory >= self.b.shade_memory_interval:
            here = self.nav.component_of(head)
            for p in pts[shade]:
                if (all(np.linalg.norm(q - p) >= self.b.shade_spot_spacing for q in self.shade_spots)
                        and self.nav.component_of(p) == here and self._deep_shade(p, sun)):
                    self.shade_spots.append(p.copy())
                    self._last_memory = s.t
                    break
        if obstacle is not None:
            # SEED: rearing is for climbing onto objects taller than the step height (and
            # lower than the cobra height)
            self._obstacle = obstacle
            if self._obstacle and self.state != "cobra":
                # rear up for a look over it, then carry on with the same path
                self._resume = (self.state, self.target)
                self._enter("cobra", s.t, reason="obstacle ahead")
        if self.hunt_on and self.state not in ("hunt", "strike", "feed"):
            prey = self._closest_prey(s.head)
            if prey is not None:
                # onslaught at once, scouting with the front raised for the first moments
                self.prey = prey
                self._enter("hunt", s.t, prey=prey.name)
                if self.claims is not None:
                    self.claims.take_prey(self.who, prey.name)
                self._scout_until = s.t + self.b.scout_time
                self._next_replan = s.t
                self._out_of_range = math.inf
                self._gap, self._next_gap, self._gaining = math.inf, s.t, False
                self._reachable, self._next_reach_check = True, s.t + GAP_INTERVAL

    def _deep_shade(self, p: np.ndarray, sun: np.ndarray) -> bool:
        """The shade around p reaches SPOT_MARGIN every way: a spot worth walking to, not a
        sliver the head may miss or the moving sun uncovers on the way."""
        ring = p + SPOT_MARGIN * np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0], [0, 0, -1.0]])
        return bool(perception.in_shade(self.rays, ring, sun, self.rig.body.clearance).all())

    def _closest_prey(self, head: np.ndarray) -> Prey | None:
        if self._now < self._sated_until:
            return None
        free = [p for p in self.preys
                if p.mode == FREE and self._ignore.get(p.name, -1.0) < self._now
                and (self.claims is None or self.claims.hunter(p.name) in (None, self.who))]
        if not free:
            return None
        d = [float(np.linalg.norm(p.position - head)) for p in free]
        i = int(np.argmin(d))
        if d[i] > self.b.detection_range or not self._within_reach(free[i], head):
            return None
        return free[i]

    def _within_reach(self, prey: Prey, head: np.ndarray) -> bool:
        """The hunter's walkable surface comes within striking distance of the prey, on the
        head's own component: a prey seen on a ledge or a floor the hunter cannot walk to is
        not hunted (the hunter used to run to the nearest point it could reach and hunt on
        there for as long as the prey stayed in range)."""
        reach = (self.b.strike_range + self.rig.body.spacing + self.rig.prey.radius
                 + self.nav.agent_radius)
        q = self.nav.nearest(prey.position, max_dist=reach)
        return q is not None and self.nav.component_of(q) == self.nav.component_of(head)

    def _recheck_spots(self, t: float) -> None:
        """Drop remembered spots that are no longer shaded (the sun moved)."""
        if self.shade_spots and self.sun.moving:
            pts = np.array(self.shade_spots)
            ok = perception.in_shade(self.rays, pts, self.sun.at(t), self.rig.body.clearance)
            self.shade_spots = [p for p, k in zip(self.shade_spots, ok) if k]

    def _roll(self, s: Senses) -> None:
        """SEED's d10: shade (go or stay) on a low roll when enough spots are known, else wander."""
        self._next_decision = s.t + self.b.decision_interval
        self._recheck_spots(s.t)
        if self._walking_to_target(s, self._journey):
            return       # a journey to another floor: the d10 waits until it arrives
        roll = int(self.rng.integers(0, 10))
        spots = self._free_spots()
        shade = roll <= self.b.shade_roll_max or s.t < self._sated_until
        if self.shade_on and len(spots) >= self.b.shade_min_spots and shade:
            if self.shaded and self._may_rest(s.head):
                if self.state != "rest_in_shade":
                    self._enter("rest_in_shade", s.t, roll=roll, spot=_r(s.head))
                    self._hold_spot(s.head)
                    self._stop(s.head)
                return
            if self.state == "seek_shade":
                return  # keep walking to the chosen spot
            k = int(self.rng.integers(0, len(spots)))
            spot = spots[k]
            self._enter("seek_shade", s.t, roll=roll, spot=_r(spot), spot_index=k)
            self._hold_spot(spot)
            self._sought = spot
            self._go(spot.copy())
            return
        if self._walking_to_target(s, self.rig.wander.keep_target):
            return       # keep walking to the target: a walk to another room outlasts a roll
        w = self.rig.wander
        target = self.nav.random_point_near(s.head, w.radius, self.rng)
        journey = w.journey_time > 0 and target is not None and perception.on_another_floor(
            self.nav, s.head, target, w.journey_rise)
        details = {"journey": True} if journey else {}
        self._enter("wander", s.t, roll=roll, target=_r(target) if target is not None else None,
                    **details)
        self._target_at = s.t
        self._journey = w.journey_time if journey else 0.0
        self._go(target)

    def _walking_to_target(self, s: Senses, keep: float) -> bool:
        """A wander target not yet reached, drawn less than `keep` seconds ago."""
        return (self.state == "wander" and self.target is not None and not s.arrived
                and s.t - self._target_at < keep)

    def _free_spots(self) -> list[np.ndarray]:
        """The remembered spots no other creature of a crowd holds (all of them alone)."""
        if self.claims is None:
            return self.shade_spots
        return [p for p in self.shade_spots if not self.claims.spot_taken(p, self.who)]

    def _may_rest(self, head: np.ndarray) -> bool:
        """No other creature of a crowd holds the shade here."""
        return self.claims is None or not self.claims.spot_taken(head, self.who)

    def _hold_spot(self, p: np.ndarray) -> None:
        if self.claims is not None:
            self.claims.take_spot(self.who, p)

    # ------------------------------------------------------------------ states
    def _start(self, s: Senses, decide: bool) -> None:
        self._roll(s)

    def _wander(self, s: Senses, decide: bool) -> None:
        if decide:
            self._roll(s)

    def _seek_shade(self, s: Senses, decide: bool) -> None:
        if not s.arrived:
            self._arrived_at = None
        elif self._arrived_at is None:
            self._arrived_at = s.t
        if decide:
            self._roll(s)
        elif s.arrived and self.shaded and self._may_rest(s.head):
            self._enter("rest_in_shade", s.t, spot=_r(s.head))
            self._hold_spot(s.head)
            self._stop(s.head)
        elif s.arrived and s.t - self._arrived_at >= SETTLE_TIME:
            # arrived, but the head is not in shade (a sliver of shade the head cannot reach):
            # forget the spot and roll again
            self.shade_spots = [p for p in self.shade_spots if p is not self._sought]
            self._roll(s)

    def _rest_in_shade(self, s: Senses, decide: bool) -> None:
        if not self.shaded and self.sun.moving:
            self._enter("warning", s.t, reason="shade lost")
            return
        if decide:
            self._roll(s)

    def _warning(self, s: Senses, decide: bool) -> None:
        if s.t - self.since >= self.b.warning_time:
            self._roll(s)

    def _cobra(self, s: Senses, decide: bool) -> None:
        """Scouting over an obstacle while walking on, reared until it is no longer ahead (it
        has climbed it or turned away; at most COBRA_MAX_TIME); then back to what it was
        doing."""
        held = s.t - self.since
        if held >= max(self.b.scout_time, self.rig.cobra.ramp_time * 2) and (
                not self._obstacle or held >= COBRA_MAX_TIME):
            state, target = self._resume
            self._enter(state, s.t, reason="scouted", target=_r(target) if target is not None else None)

    def _hunt(self, s: Senses, decide: bool) -> None:
        prey = self.prey
        d = float(np.linalg.norm(prey.position - s.head))
        if s.t >= self._next_gap:
            # (the first sample of a hunt has nothing to compare with)
            self._gaining = (math.isfinite(self._gap)
                             and d <= self._gap - GAIN_BL * self.rig.body.length)
            self._gap, self._next_gap = d, s.t + GAP_INTERVAL
        # a margin, so a hunt does not flicker at the edge, and a time out of it (unless the
        # hunter is gaining on a prey that has tired)
        far = d > 1.2 * self.b.detection_range and not (
            self._gaining and d <= GAIN_RANGE * self.b.detection_range)
        if s.t >= self._next_reach_check:
            self._next_reach_check = s.t + GAP_INTERVAL
            self._reachable = self._within_reach(prey, s.head)
        far = far or not self._reachable
        self._out_of_range = min(self._out_of_range, s.t) if far else math.inf
        if far and s.t - self._out_of_range >= GIVE_UP_TIME:
            gone = "escaped" if self._reachable else "out of reach"
            self.events[-1]["details"]["outcome"] = gone
            self._ignore[prey.name] = s.t + 2.0 * self.b.decision_interval
            self.prey = None
            self._roll(s)        # gives up: back to the d10 (wander, or shade)
            self.events[-1]["details"]["reason"] = "prey " + gone
            return
        if d - self.rig.prey.radius <= self.b.strike_range + self.rig.body.spacing:
            self.events[-1]["details"]["outcome"] = "caught"
            prey.mode = CAPTURED
            self._enter("strike", s.t, prey=prey.name)
            self._stop(s.head)
            return
        if s.t >= self._next_replan:
            self._next_replan = s.t + 0.25
            self._go(prey.position.copy())

    def _strike(self, s: Senses, decide: bool) -> None:
        if s.t - self.since >= self.b.strike_time:
            self.prey.mode = HELD
            self._enter("feed", s.t, prey=self.prey.name)

    def _feed(self, s: Senses, decide: bool) -> None:
        if s.t - self.since >= self.b.feed_time:
            self.prey.mode = HIDDEN
            self.prey = None
            # sated: it hunts no more for a while and digests in shade (its rolls go to shade)
            self._sated_until = s.t + self.b.sated_time
            self._roll(s)


#: each state's step (Brain._<state>; the start's before the first state)
_ACTS = {name: getattr(Brain, "_" + (name or "start")) for name in ("",) + STATES}


def _r(p) -> list[float]:
    return [round(float(x), 4) for x in p]


def _senses_key(s: Senses) -> tuple:
    """What a perception's measures depend on, as Python floats."""
    return (s.t, *s.head.tolist(), *s.heading.tolist())


def sense_together(brains: list[Brain], senses: list[Senses], keep: bool = True) -> list[tuple]:
    """Brain._sense for several brains (a crowd's that perceive this step, sharing the
    surface, the rays, the sun and the rig) in one surface query and one ray batch per kind,
    the same answers bit for bit as each brain's own; with `keep`, each is also kept on its
    brain, with the senses it was measured for, for its step."""
    b0 = brains[0]
    sun = b0.sun.at(senses[0].t)
    heads = np.array([s.head for s in senses], dtype=np.float64)
    h = b0.nav.surface_height(heads)
    heads[np.isfinite(h), 1] = h[np.isfinite(h)]
    # the head, then a ring of points around it (light/dark contrast), in one ray batch
    pts = np.concatenate([heads[:, None], heads[:, None] + b0._ring[None]], axis=1)
    m = pts.shape[1]
    h = b0.nav.surface_height(pts.reshape(-1, 3)).reshape(len(brains), m)
    # a ring point on the surface (put at its layer's height, so walkable there) or not
    ok = np.isfinite(h)
    ok[:, 0] = True
    pts[:, 1:, 1] = np.where(ok[:, 1:], h[:, 1:], pts[:, 1:, 1])
    shade = (perception.in_shade(b0.rays, pts.reshape(-1, 3), sun, b0.rig.body.clearance)
             .reshape(len(brains), m) & ok)
    look = [i for i, b in enumerate(brains) if b._looks_ahead()]
    ahead = {}
    if look:
        rig = b0.rig
        hit = perception.obstacles_ahead(
            b0.rays, np.array([senses[i].head for i in look]),
            np.array([senses[i].heading for i in look]), rig.cobra.obstacle_probe,
            low=rig.navigation.step_height, high=rig.cobra.height)
        ahead = dict(zip(look, hit.tolist()))
    out = []
    for i, (b, s) in enumerate(zip(brains, senses)):
        sensed = (sun, heads[i], pts[i], shade[i], ahead.get(i))
        if keep:
            b._sensed = (_senses_key(s), sensed)
        out.append(sensed)
    return out
