"""Path following on the walkable surface: the navigation agent walks its planned path and the
head follows it (Detour's corridor following, for a creature with a turning radius).

Every step:
- the agent advances along its path, and waits while the head lags more than two turning radii
  behind it (a sharp turn);
- the head chases the agent with a bounded turning radius (aiming at the agent when it can walk
  there straight, else at the last point of the agent's path it can), and is kept on the
  walkable surface of its own layer (a step that would leave it turns or slides along the edge
  instead);
- the head's height continues the layer it is on (never a floor above or below it);
- when the head has been held back for REPLAN_AFTER seconds (blocked, or off the agent's
  corridor), the path is planned again from the head;
- in a crowd, a head cornered by other creatures' bodies while they walk holds still for them
  to move on (up to HOLD_MAX seconds) rather than turn on the spot;
- while a sharp bend of the trail lies under the body (a hook the head made in a dead end),
  the whole creature slows so that no segment turns more than BEND_TURN in an exported frame
  as it rounds the bend: the body moves at the head's speed along the trail, and a segment
  turns at speed / radius;
- while the body passes a wall (or a slope too steep to stand on) beside it, it slows so that
  no planted foot is swept round its hip faster than the gait's STANCE_TURN in an exported
  frame: the legs on that side fold in toward the body (locomotion.legs.folded_lever), and a
  foot planted beside its hip turns at speed / lever.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from baker.behaviour.intent import Intent
from baker.config import RigConfig
from baker.geometry import polyline
from baker.geometry.transforms import normalize
from baker.locomotion.agent import PathAgent
from baker.locomotion.body import project_to_surface
from baker.locomotion.contain import (FLAT, SurfaceTest, grid_arrays, line_clear, nearest_sq,
                                      plain_test)
from baker.locomotion.contain import layer_height as compiled_layer_height
from baker.locomotion.contain import slope_grades as compiled_slope
from baker.locomotion.contain import ready as compiled_ready
from baker.locomotion.head import HeadSteer, grid_array, way_points
from baker.locomotion.legs import STANCE_TURN, folded_lever, hip_line
from baker.navmesh.lazy import LazyNav
from baker.navmesh.query import NavSurface

#: steps between checks of what the head can see of the agent's path
AIM_EVERY = 4
#: largest sideways slither of the head [BL] (SEED's amplitude at top speed, about the body's
#: half-width)
SLITHER_OFFSET = 0.032
#: a height jump of the head (or along the path ahead) over this fraction of the riser limit is
#: a riser (a step or a stair)
ROUGH_RISER = 0.5
#: [s] how long the agent waits for the head before the path is planned again from the head
REPLAN_AFTER = 1.5
#: [rad] the most a segment may turn in an exported frame while it rounds a bend of the trail
#: (the limit on a joint's per-frame rotation is 30 degrees)
BEND_TURN = math.radians(20.0)
#: [spacings] the trail under the body is kept at this spacing to measure its bends
BEND_SAMPLE = 0.25
#: [rows] the trail's bends are measured over pairs of chords this long (half a spacing)
_BEND_CHORD = int(round(0.5 / BEND_SAMPLE))
#: [spacings] the head's tightest turning radius, where the walkable surface leaves no room for
#: its usual one (a dead end): a reversal is then a loop 1.5 spacings wide, which the spine's
#: chord placement follows without a joint jumping across it (it jumps on a loop under one
#: spacing wide)
MIN_TURN = 0.75
#: [rad] directions of the rays that measure the room beside the hips (as the legs' anchors
#: do): straight out, ahead and behind
WALL_YAWS = np.radians([0.0, 40.0, -40.0])
#: [s] the longest a head cornered by other creatures' bodies holds still for them to move on,
#: before it turns on the spot
HOLD_MAX = 4.0
#: [cells] the head's layer is measured this far either side of the head for its slope
#: (Follower._slope): inside the head's own column most steps
SLOPE_PROBE = 0.05
#: straight down (the ray under the head in _leg_lever)
_DOWN = np.array([[0.0, -1.0, 0.0]])


def turn_radius(rig: RigConfig) -> float:
    """[m] the head's turning radius (its pure pursuit's lead too): the agent's radius, at
    least three spacings."""
    return max(rig.navigation.radius, 3.0 * rig.body.spacing)


class Follower:
    """The navigation agent and the head that follows it.

    nav  : NavSurface; rays : RayCaster of the environment
    start: (3,) on the walkable surface; heading : (3,) unit horizontal
    position : (3,) the head (slither included), height on its layer
    """

    def __init__(self, nav, rays, start: np.ndarray, heading: np.ndarray, rig: RigConfig,
                 fps: int = 30):
        body, loco, navc = rig.body, rig.locomotion, rig.navigation
        self.nav, self.rays = nav, rays
        self.max_speed = loco.max_speed
        self.turn_radius = turn_radius(rig)
        self.tol = 0.5 * navc.height     # vertical reach of a layer lookup
        self.max_grade = math.tan(navc.max_slope) + 1e-9    # the steepest walkable rise a metre
        self.probe = 0.5 * navc.height   # floor search above and below the head off the surface
        self.agent = PathAgent(start, loco.max_speed, loco.acceleration, loco.stopping_distance)
        # Pure pursuit: the head chases the agent one turning radius ahead on the path.
        self.head = HeadSteer(start, heading, max_speed=loco.max_speed,
                              turn_radius=self.turn_radius, lead=self.turn_radius,
                              turn_rate=loco.head_turn_rate, amplitude=loco.slither_amplitude,
                              max_offset=SLITHER_OFFSET * body.length,
                              min_radius=MIN_TURN * body.spacing)
        self.head.grid = (float(nav.origin[0]), float(nav.origin[1]), float(nav.cell_size))
        # the head's surface tests compiled (contain.py), reading the grid's arrays as the
        # navigation's layer_height does (a NavSurface's, a lazy surface's window's); else in
        # Python through its layer_height
        self._compiled = type(nav).layer_height in (NavSurface.layer_height,
                                                    LazyNav.layer_height)
        if self._compiled:
            compiled_ready(nav)
        self._lookup = (None, None)      # (grid_arrays, its compiled layer_height): _layer_lookup
        self.height = float(start[1])
        self.body_length = body.length
        self.rough_speed = loco.rough_speed
        self.riser = ROUGH_RISER * navc.step_height   # a height jump this big is a riser
        self.gait_scale = 1.0       # the brain's speed factor
        self.terrain_scale = 1.0    # rough_speed on risers, else 1
        self.bend = math.inf        # [m] radius of the sharpest bend of the trail under the body
        self.bend_speed = BEND_TURN * fps    # [rad/s] a segment's largest turn rate
        self.spacing = body.spacing
        self.lever = math.inf       # [m] the shortest legs' lever on the trail under the body
        # [rad/s] a planted foot's largest turn rate (no legs, or feet that reach no farther
        # out than the hips, so nothing to fold: no bound)
        hip_x, hip_y = hip_line(rig)
        legged = rig.legs.enabled and rig.legs.reach > hip_x
        self.stance_speed = STANCE_TURN * fps if legged else math.inf
        self._hip = (hip_x, body.clearance + hip_y, rig.legs.upper_length, rig.legs.reach)
        self._lever_rays = _lever_rays(*self._hip[:3])
        # (key, lever) measured ahead of the step for a crowd (measure_levers)
        self._lever_ready: tuple | None = None
        # rows _trail[_lo:_hi] of one buffer, (walked, x, z, the legs' lever there, the
        # radius of the bend that ends there: _bend_at), under the body: the straight start
        # line behind the head first, so a turn back at the start is a bend under the body
        # like any other
        step = BEND_SAMPLE * body.spacing
        behind = step * np.arange(math.ceil((body.length + body.spacing) / step), -1, -1)
        rows = [(-d, float(start[0] - d * heading[0]), float(start[2] - d * heading[2]),
                 math.inf, math.inf) for d in behind]
        self._trail = np.array(rows * 2)
        self._lo, self._hi = 0, len(rows)
        for i in range(len(rows)):
            self._trail[i, 4] = self._bend_at(i)
        self._walked = 0.0          # horizontal metres the head has walked
        self._riser_at = -np.inf    # ... when it last went up or down a riser
        self._steps = 0
        self._measured = False      # the bend and lever of the trail as it is are measured
        self._back = 0.0
        self._backs = self.turn_radius * np.arange(0.0, 4.01, 0.25)
        self.target: np.ndarray | None = None
        self.pending: np.ndarray | None = None   # a target waiting for the body to leave risers
        self.waited = 0.0
        self.replans = 0
        # a crowd's local avoidance (run.crowd): other creatures' body points near the head,
        # (m, 2) x, z, or None; the head keeps `separation` metres from them
        self.others: np.ndarray | None = None
        # _surface_test's sort of `others`: (others, (x, z) it was sorted from, (m, 3) rows
        # (distance, x, z) nearest first), or None
        self._sorted: tuple | None = None
        self.separation = 0.0
        # _surface_test's test off a crowd: (height, grid_arrays, test), or None
        self._lone_test: tuple | None = None
        self.slope = FLAT    # the head's layer as a plane, as its surface test last took it
        self.held_for = 0.0         # [s] the head has held still, cornered by other bodies
        self.others_move = False    # the creatures whose bodies are near all walk

    @property
    def position(self) -> np.ndarray:
        p = self.head.position.copy()
        p[1] = self.height
        return p

    def go(self, target: np.ndarray, route: np.ndarray | None = None) -> None:
        """A new path from the agent to `target` (a partial one when it is out of reach).
        On risers (a staircase) a path that would turn the head round waits until the body is
        off them or the current path is walked: the body does not turn back across steps.

        route : (k, 3) float or None: walk this polyline (from the agent, ending at `target`)
                instead of planning a path (scripted locomotion: a straight line, a circle)"""
        target = np.asarray(target, dtype=np.float64)
        self.pending = None
        path = (self._path(self.agent.position, target) if route is None
                else np.asarray(route, dtype=np.float64).reshape(-1, 3))
        if self.terrain_scale < 1.0 and self.target is not None and not self.agent.arrived:
            ahead = path[min(np.searchsorted(polyline.arc_lengths(path), 0.5 * self.body_length),
                             len(path) - 1)]
            to = ahead - self.head.base
            if to[0] * self.head.heading[0] + to[2] * self.head.heading[2] < 0.0:
                self.pending = target
                return
        self.target = target
        self.head.new_path()   # a U-turn chooses its side afresh on a new or re-planned path
        self.agent.set_path(path)

    def apply(self, intent: Intent) -> None:
        """This step's Intent: a new goal means a new path (else a halt stops the agent), and
        its speed, stopping distance and turn scale set the gait."""
        if intent.new_target:
            self.go(intent.target, route=intent.route)
        elif intent.halt:
            self.halt()
        self.drive(intent.speed_scale, intent.stopping_distance, intent.turn_scale)

    def halt(self) -> None:
        """Stop where the agent is; the head closes up behind it."""
        self.target = self.pending = None
        self.agent.set_path(self.agent.position[None])

    def drive(self, speed_scale: float, stopping_distance: float, turn_scale: float) -> None:
        """The brain's gait: speed factor, stopping distance and slither turn-rate factor."""
        self.gait_scale = speed_scale
        self.agent.stopping_distance = stopping_distance
        self.head.turn_rate_scale = turn_scale
        self._apply_speed()

    def _apply_speed(self) -> None:
        scale = self.gait_scale * self.terrain_scale
        # the bend bounds the speed itself, whatever the brain's and the terrain's factors (a
        # hunt's doubled speed would round the bend at twice bend_speed), and so does the
        # legs' lever; the head's catching up with the agent included
        bend, lever = self.bend_speed * self.bend, self.stance_speed * self.lever
        scale *= min(1.0, bend / max(self.max_speed * scale, 1e-12))
        scale *= min(1.0, lever / max(self.max_speed * scale, 1e-12))
        self.agent.speed_scale = scale
        self.head.max_speed = self.max_speed * scale
        self.head.speed_cap = min(bend, lever)

    def step(self, dt: float) -> None:
        agent, head = self.agent, self.head
        gap = math.hypot(agent.position[0] - head.base[0], agent.position[2] - head.base[2])
        self.waited = self.waited + dt if gap >= 2.0 * self.turn_radius else 0.0
        if self.waited >= REPLAN_AFTER:
            self.replan()
            gap = math.hypot(agent.position[0] - head.base[0], agent.position[2] - head.base[2])
        agent.step(dt, slack=2.0 - gap / self.turn_radius)
        self._steps += 1
        if self._steps % AIM_EVERY == 0:
            self._back = self._aim_back()
            self._terrain(gap)
            self._bends()
        aim = agent.point_behind(self._back) if self._back > 0.0 else None
        base = head.base.copy()
        allowed = self._surface_test()
        head.hold = self.others is not None and self.others_move and self.held_for < HOLD_MAX
        head.held = False
        head.step(dt, agent.position, agent.speed, allowed=allowed, aim=aim)
        # held, or turning on the spot after holding: until the head walks on
        stuck = head.held or (self.held_for >= HOLD_MAX and head.speed == 0.0)
        self.held_for = self.held_for + dt if stuck else 0.0
        height = self._layer_height(head.position)
        self._walked += math.hypot(head.base[0] - base[0], head.base[2] - base[2])
        if abs(height - self.height) > self.riser:
            self._riser_at = self._walked
        self.height = height
        self._lever_ready = None        # measured for this step only

    def _terrain(self, gap: float) -> None:
        """Slow to rough_speed while a riser is under the body (the head went over one within a
        body length) or on the path ahead of the head (within half a body length); steps and
        stairs then get the swings they need."""
        rough = (self._walked - self._riser_at < self.body_length
                 or self.agent.largest_rise(gap, 0.5 * self.body_length) > self.riser)
        scale = self.rough_speed if rough else 1.0
        if scale != self.terrain_scale:
            self.terrain_scale = scale
            self._apply_speed()
        if self.pending is not None and (not rough or self.agent.arrived):
            self.go(self.pending)

    def _bends(self) -> None:
        """Keep the trail under the body (every BEND_SAMPLE spacings of walked distance) and
        slow while its sharpest bend there would turn a segment faster than bend_speed, or a
        wall beside it folds the legs so that a planted foot would turn faster than
        stance_speed."""
        p = self.head.position
        if self._walked - self._trail[self._hi - 1, 0] >= BEND_SAMPLE * self.spacing:
            lever = (self._leg_lever(*self._lever_point())
                     if math.isfinite(self.stance_speed) else math.inf)
            self._push(self._walked, float(p[0]), float(p[2]), lever)
            while self._walked - self._trail[self._lo, 0] > self.body_length + self.spacing:
                self._lo += 1
        elif self._measured:
            return            # the trail is as it was: so are its bend and lever
        self._measured = True
        # the bends whose chords lie under the body, each measured once, as its row was pushed
        radii = self._trail[self._lo + 2 * _BEND_CHORD:self._hi, 4]
        radius = float(radii.min()) if len(radii) else math.inf
        lever = float(self._trail[self._lo:self._hi, 3].min())
        if radius != self.bend or lever != self.lever:
            self.bend, self.lever = radius, lever
            self._apply_speed()

    def _push(self, walked: float, x: float, z: float, lever: float) -> None:
        """Append a row (walked, x, z, lever, the radius of the bend ending there) to the
        trail, moving its rows to the buffer's start (or into one twice the size) when it is
        full."""
        if self._hi == len(self._trail):
            rows = self._trail[self._lo:self._hi]
            if 2 * len(rows) > len(self._trail):
                self._trail = np.concatenate([rows, np.empty_like(rows)])
            else:
                self._trail[:len(rows)] = rows.copy()
            self._lo, self._hi = 0, len(rows)
        self._trail[self._hi, :4] = (walked, x, z, lever)
        self._hi += 1
        self._trail[self._hi - 1, 4] = self._bend_at(self._hi - 1)

    def _bend_at(self, i: int) -> float:
        """The radius of the trail's bend over the pair of chords _BEND_CHORD rows long that
        ends at row i (bend_radius), inf where the trail under the body does not reach back
        that far (then the pair never lies under it)."""
        if i - 2 * _BEND_CHORD < self._lo:
            return math.inf
        (x0, z0), (x1, z1), (x2, z2) = self._trail[i - 2 * _BEND_CHORD:i + 1:_BEND_CHORD,
                                                   1:3].tolist()
        return bend_radius(x0, z0, x1, z1, x2, z2)

    def _leg_lever(self, p: np.ndarray, dx: float, dz: float) -> float:
        """[m] the legs' lever (folded_lever) where the hips pass the head's point p, the
        trail heading (dx, dz) there: one batch of rays outward from both hips, along the
        surface, straight out, ahead and behind, at hip and knee height, as the legs' anchors
        measure the room beside them. (A crowd measures every creature's at once:
        measure_levers.)"""
        if self._lever_ready is not None:
            key, lever = self._lever_ready
            self._lever_ready = None
            if key == self._lever_key(p, dx, dz):
                return lever
        # the ground's normal from a ray cast down (rays.cast_down's ray), facing up
        prim = self.rays.cast(np.array([self._ground_ray(p)]), _DOWN, 2.0 * self.probe)[1][0]
        o, d = self._side_rays(p, dx, dz, prim)
        return self._lever_of(*self.rays.cast(o, d, 1.2 * self._hip[3]))

    def lever_request(self) -> tuple | None:
        """(p, dx, dz): the point and trail heading at which this step's _bends will measure
        the legs' lever (read before the step: the head, its height and the trail are as the
        last step left them), or None when it will not."""
        if (self._steps + 1) % AIM_EVERY or not math.isfinite(self.stance_speed):
            return None
        if self._walked - self._trail[self._hi - 1, 0] < BEND_SAMPLE * self.spacing:
            return None
        return self._lever_point()

    def _lever_point(self) -> tuple:
        """(p, dx, dz): the head's point and the trail's heading there (from the trail point
        a spacing back), where _bends measures the legs' lever."""
        p = self.head.position
        back = self._trail[self._hi - int(round(1.0 / BEND_SAMPLE))]
        return p, p[0] - back[1], p[2] - back[2]

    def _lever_key(self, p: np.ndarray, dx: float, dz: float) -> tuple:
        """What a lever measured at (p, dx, dz) depends on, as Python floats."""
        return float(p[0]), float(p[2]), self.height, float(dx), float(dz)

    def _ground_ray(self, p: np.ndarray) -> list:
        """The origin of the ray cast down for the ground's normal under p."""
        return [p[0], self.height + self.probe, p[2]]

    def _side_rays(self, p: np.ndarray, dx: float, dz: float, prim: int):
        """((12, 3), (12, 3)) the origins and directions of the rays out from the hips, over
        the ground face `prim` (-1: none, flat) under p."""
        n = self.rays.face_normals[prim] if prim >= 0 else np.array([0.0, 1.0, 0.0])
        if n[1] < 0.0:
            n = -n
        f = np.array([dx, 0.0, dz])
        f = f - (f @ n) * n
        if np.linalg.norm(f) < 1e-9:
            f = self.head.heading - (self.head.heading @ n) * n
        f = f / max(np.linalg.norm(f), 1e-12)
        (n0, n1, n2), (f0, f1, f2) = n.tolist(), f.tolist()
        left = np.array([n1 * f2 - n2 * f1, n2 * f0 - n0 * f2, n0 * f1 - n1 * f0])  # cross(n, f)
        ground = np.array([p[0], self.height, p[2]])
        h, side_x, side_cos, sin, _ = self._lever_rays
        return ground + h * n + side_x * left, normalize(side_cos * left + sin * f)

    def _lever_of(self, t: np.ndarray, prim: np.ndarray) -> float:
        """The lever from the side rays' hits (t, prim)."""
        hip_x, reach, cos = self._hip[0], self._hip[3], self._lever_rays[4]
        free = np.where(prim >= 0, t * cos[:, 0], np.inf)
        return float(folded_lever(free.min(), reach, hip_x))

    def _surface_test(self):
        """The head's surface test this step (a SurfaceTest, or plain_test where the
        navigation's layer_height is not a NavSurface's): on its layer, and in a crowd
        (`others`) at least `separation` from every other creature's body point (or, where it
        already is closer, no closer than it is), so other bodies are obstacles the head turns
        or slides along as it does edges.

        A point is measured only against the body points that can come within `separation`
        of it: those not much farther from a reference point than it is (the base where these
        `others` were first tested: the points are kept nearest it first, each with its
        distance from it less a margin far above the rounding of these distances, once per
        neighbour query). The points skipped cannot be within `separation`, so the answer is
        that of every point measured."""
        test = SurfaceTest if self._compiled else plain_test
        if self.others is None:
            # the last step's test while the layer's height and the grid are as they were
            # (on level ground, most steps)
            grid = grid_arrays(self.nav) if self._compiled else None
            last = self._lone_test
            if last is None or last[0] != self.height or last[1] is not grid:
                self.slope = self._slope()
                self._lone_test = last = (self.height, grid, test(
                    self.nav, self.height, self.tol, slope=self.slope))
            return last[2]
        others = self.others
        bx, _, bz = self.head.base.tolist()
        need = min(self.separation ** 2, nearest_sq(others, bx, bz))
        need -= 1e-12
        if self._sorted is None or self._sorted[0] is not others:
            ox, oz = others[:, 0], others[:, 1]
            d2 = (ox - bx) ** 2 + (oz - bz) ** 2
            order = np.argsort(d2, kind="stable")
            self._sorted = (others, (bx, bz),
                            np.stack([np.sqrt(d2[order]) - 1e-6, ox[order], oz[order]], axis=1))
        _, ref, near = self._sorted
        self.slope = self._slope()
        return test(self.nav, self.height, self.tol, near, ref, need, self.slope)

    def _layer_lookup(self):
        """layer_height(x, y, z, tol) of the navigation: compiled on a NavSurface's arrays
        (kept while they are the grid's)."""
        if self._compiled:
            grid = grid_arrays(self.nav)
            if self._lookup[0] is not grid:
                self._lookup = (grid, partial(compiled_layer_height, *grid))
            return self._lookup[1]
        return self.nav.layer_height

    def _slope(self) -> tuple[float, float, float, float]:
        """(x, z, gx, gz): the head's layer as a plane through the head (its rise a metre
        along x and z, from its heights SLOPE_PROBE cells either side, or one side and the
        head's where a probe crosses into a step's column), for the surface test's steps net
        of a ramp's rise; FLAT where both are missing or the plane is steeper than the
        walkable slope."""
        x, z = float(self.head.position[0]), float(self.head.position[2])
        d = SLOPE_PROBE * self.nav.cell_size
        y, tol = self.height, self.tol
        if self._compiled:
            gx, gz = compiled_slope(*grid_arrays(self.nav), x, z, d, y, tol)
        else:
            layer = self.nav.layer_height
            gx = _grade(layer(x + d, y, z, tol), y, layer(x - d, y, z, tol), d)
            gz = _grade(layer(x, y, z + d, tol), y, layer(x, y, z - d, tol), d)
        if not (math.hypot(gx, gz) <= self.max_grade):     # NaN too
            return FLAT
        return x, z, gx, gz

    def _aim_back(self) -> float:
        """How far back along the agent's path the head should aim: 0 (at the agent) when it
        can walk straight to the agent, else the first point, a quarter turning radius at a
        time back along the path (up to four turning radii), that it can walk to straight; 0
        when none is. Pure pursuit would cut the corner round a thin obstacle and chase the
        agent from its wrong side."""
        for back in self._backs:
            p = self.agent.point_behind(back)
            if self._clear(p):
                return back
        return 0.0

    def _clear(self, p: np.ndarray) -> bool:
        """True when the straight line from the head's base to p stays on the head's layer of
        the walkable surface (tested in every column it crosses, head.way_points)."""
        bx, bz = float(self.head.base[0]), float(self.head.base[2])
        dx, dz = float(p[0]) - bx, float(p[2]) - bz
        n = math.hypot(dx, dz)
        if n < 1e-12:
            return True
        if self._compiled:
            cols, positions, normals, grid = grid_arrays(self.nav)
            return line_clear(cols, positions, normals, grid, bx, bz, dx, dz, n, self.height,
                              self.tol, grid_array(self.head.grid))
        y = self.height
        for r in way_points(bx, bz, dx / n, dz / n, 0.0, n, self.head.grid):
            y = self.nav.layer_height(bx + r * dx / n, y, bz + r * dz / n, self.tol)
            if y != y:  # NaN
                return False
        return True

    def replan(self) -> None:
        """Plan again from the head: the agent restarts a turning radius along a new path from
        the surface point nearest the head."""
        self.waited = 0.0
        p = self.nav.nearest(np.array([self.head.base[0], self.height, self.head.base[2]]))
        if p is None:
            return
        self.replans += 1
        self.agent.position = p
        if self.target is None:
            self.agent.set_path(p[None])
        else:
            self._plan(p)
            # the head chases the new path a turning radius ahead, as it does any path
            self.agent.skip(self.turn_radius)

    def _plan(self, a: np.ndarray) -> None:
        self.head.new_path()   # a U-turn chooses its side afresh on a new or re-planned path
        self.agent.set_path(self._path(a, self.target))

    def _path(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Dense path points from a to b carrying the walked layer's heights (chords cut
        through bumps)."""
        return self.nav.resample_path(self.nav.find_path(a, b).points)

    def _layer_height(self, p: np.ndarray) -> float:
        """Height of the surface under the head at p = (x, _, z), continuing its layer: the
        walkable layer in its column closest to the previous height (a step moves the head
        millimetres, so this never jumps to a floor above or below), or nearest the plane of
        its layer (a step on a ramp, as the surface test takes it: `slope`); off the eroded
        surface (the slither), the layer's height under the head's base (kept on the surface), then the
        floor found by rays near that height; else the previous height. (Rays at the side of a
        staircase can find the tread below; the base's column is on the flight.)"""
        layer = self._layer_lookup()
        y = layer(float(p[0]), self.height, float(p[2]), self.tol)
        if y == y:      # not NaN
            return y
        # up (or down) a step on a ramp, as the surface test took it: net of the ramp's rise
        sx, sz, gx, gz = self.slope
        if gx != 0.0 or gz != 0.0:
            x, z = float(p[0]), float(p[2])
            y = layer(x, self.height + gx * (x - sx) + gz * (z - sz), z,
                      self.tol + math.hypot(gx, gz) * self.nav.cell_size)
            if y == y:
                return y
        b = self.head.base
        y = layer(float(b[0]), self.height, float(b[2]), self.tol)
        if not math.isnan(y):
            return y
        g, _, hit = project_to_surface(self.rays, np.array([[p[0], self.height, p[2]]]), self.probe)
        return float(g[0, 1]) if hit[0] else self.height


def _grade(ahead: float, here: float, behind: float, d: float) -> float:
    """The rise a metre of a layer whose heights are `ahead` and `behind` d either side of a
    point at `here`: one-sided where one of them is missing (NaN: the probe crossed into a
    step's column), NaN where both are."""
    if ahead == ahead and behind == behind:
        return (ahead - behind) / (2.0 * d)
    return (ahead - here) / d if ahead == ahead else (here - behind) / d


def measure_levers(follows) -> None:
    """The legs' levers that the followers' next steps will measure (Follower.lever_request),
    for all of them in two ray batches (the ground rays, then the hips' rays): each follower's
    own casts give the same bits, one ray at a time. Each is kept on its follower, with the
    inputs it was measured at, for its _bends."""
    asks = [(f, r) for f in follows if (r := f.lever_request()) is not None]
    if not asks:
        return
    rays = asks[0][0].rays
    o = np.array([f._ground_ray(p) for f, (p, _, _) in asks])
    prim = rays.cast(o, np.broadcast_to(_DOWN, o.shape),
                     np.array([2.0 * f.probe for f, _ in asks]))[1]
    sides = [f._side_rays(p, dx, dz, int(k)) for (f, (p, dx, dz)), k in zip(asks, prim)]
    m = len(sides[0][0])
    t, hit = rays.cast(np.concatenate([o for o, _ in sides]), np.concatenate([d for _, d in sides]),
                       np.repeat([1.2 * f._hip[3] for f, _ in asks], m))
    for i, (f, (p, dx, dz)) in enumerate(asks):
        f._lever_ready = (f._lever_key(p, dx, dz),
                          f._lever_of(t[i * m:(i + 1) * m], hit[i * m:(i + 1) * m]))


def _lever_rays(hip_x: float, hip_y: float, l1: float) -> np.ndarray:
    """(5, 12, 1) per ray of Follower._leg_lever (left hip then right, at hip height hip_y and
    knee height hip_y + l1 / 2, each of WALL_YAWS): its height above the ground, its hip's
    offset along `left` (side x hip_x), the weights of `left` (cos(yaw) x side) and of the
    heading (sin(yaw)) in its direction, and cos(yaw)."""
    rows = [(h, side * hip_x, math.cos(yaw) * side, math.sin(yaw), math.cos(yaw))
            for side in (1.0, -1.0) for h in (hip_y, hip_y + 0.5 * l1) for yaw in WALL_YAWS]
    return np.array(rows).T[..., None]


def bend_radius(x0: float, z0: float, x1: float, z1: float, x2: float, z2: float) -> float:
    """The radius of a polyline's bend over the pair of chords (x0, z0)-(x1, z1)-(x2, z2):
    the chords' mean length over the angle between them (inf when a chord is shorter than
    1e-9). In Python floats, the arithmetic of the bends of the whole trail in numpy that it
    replaces (the same bits: the angle by np.arccos, whose bits math.acos does not give), so
    the trail's bends are measured one pair at a time as its points are pushed."""
    ax, az, bx, bz = x1 - x0, z1 - z0, x2 - x1, z2 - z1
    la, lb = math.sqrt(ax * ax + az * az), math.sqrt(bx * bx + bz * bz)
    if not (la > 1e-9 and lb > 1e-9):
        return math.inf
    cos = (ax * bx + az * bz) / (la * lb)
    ang = float(np.arccos(np.array([min(max(cos, -1.0), 1.0)]))[0])
    return 0.5 * (la + lb) / max(ang, 1e-12)
