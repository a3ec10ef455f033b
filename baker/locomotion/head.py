"""Head steering: the head follows the navigation agent with a bounded turning radius and a
sine slither whose frequency and amplitude rise with speed (SEED.md: turn rate 4, amplitude 5).

The head has a smooth "base" point that chases the agent (turn rate limited to speed / turn
radius, so the trail has no kinks, even when a new path starts behind it) and a lateral slither
offset on top. Heights are only approximate here; the body stage re-projects everything onto the
surface with ray casts.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from baker.locomotion import contain as compiled
from baker.locomotion.contain import way_end, way_points

#: The head walks up to this multiple of its top speed to close the gap to the agent
CATCH_UP = 1.25
#: Directions tried when the head is cornered (radians off the wanted turn, toward the agent's
#: side first): up to a right angle, in 7.5 degree steps; it turns on the spot toward the first
#: free one
_DEFLECT = np.radians(7.5) * np.arange(1, 13)
#: Points along half a turning circle when a U-turn chooses its side (about an eighth of the
#: turning radius apart: finer than the gap the agent radius leaves round a wall), and their
#: angles.
_ARC_STEPS = 26
_ARC_COS_SIN = (np.cos(np.linspace(0.0, math.pi, _ARC_STEPS + 1)),
                np.sin(np.linspace(0.0, math.pi, _ARC_STEPS + 1)))
_ARC_COS, _ARC_SIN = (a.tolist() for a in _ARC_COS_SIN)
#: Turns tried, as fractions of the tightest turn a step may make, when the wanted one would
#: leave the walkable surface (toward the agent's side first)
_TIGHT = (0.25, 0.5, 0.75, 1.0)
_TIGHT_ARRAY = np.array(_TIGHT)
#: no aim point (contain.head_step)
_NO_AIM = np.full(3, np.nan)
#: such a turn's largest yaw rate, in multiples of the head's yaw-rate limit (about the rate of
#: its usual turning circle at full speed)
CONTAIN_YAW = 2.0


class HeadSteer:
    """Kinematic head follower.

    base     : (3,) float, metres — smooth follower of the agent
    heading  : (3,) float, unit, horizontal
    position : (3,) float, metres — base plus the slither offset
    """

    def __init__(self, position: np.ndarray, heading: np.ndarray, *, max_speed: float,
                 turn_radius: float, lead: float, turn_rate: float, amplitude: float,
                 max_offset: float, max_yaw_rate: float = math.pi,
                 min_radius: float | None = None):
        self.base = np.asarray(position, dtype=np.float64).copy()
        h = np.asarray(heading, dtype=np.float64).copy()
        h[1] = 0.0
        self.heading = h / max(np.linalg.norm(h), 1e-12)
        self.max_speed = float(max_speed)
        self.turn_radius = float(turn_radius)
        self.lead = float(lead)
        self.turn_rate = float(turn_rate)      # rad/s of slither phase at max speed
        self.amplitude = float(amplitude)      # rad of heading swing at max speed
        self.max_offset = float(max_offset)    # metres, lateral offset cap
        self.max_yaw_rate = float(max_yaw_rate)  # rad/s, heading change limit
        # metres, the tightest turn, where the walkable surface leaves no room for turn_radius
        # (a reversal in a dead end is a loop this wide, never a cusp the body cannot follow)
        self.min_radius = float(turn_radius if min_radius is None else min_radius)
        # m/s, the speed of a turn on that circle (CONTAIN_YAW yaw-rate limits)
        self.tight_speed = CONTAIN_YAW * self.max_yaw_rate * self.min_radius
        self.turn_rate_scale = 1.0
        self.speed_cap = math.inf   # m/s, a hard bound (the body's bends), catching up included
        self.phase = 0.0
        self.lateral_amp = 0.0
        self.speed = 0.0
        self.position = self.base.copy()
        self._u_side = 0.0   # the side a U-turn in progress turns to (+1 left, -1 right)
        self._creep = 0.0    # metres still to walk slowly after a turn on the spot
        self._spun = 0.0     # radians turned on the spot since (contain.SPIN)
        # cornered, hold still instead of turning on the spot (set by the follower: other
        # creatures' bodies corner it, and they move on); held: it did this step
        self.hold = False
        self.held = False
        # the direction the slither offset is measured across: the heading, followed only as
        # the base travels (a turn on the spot does not swing the head round the base)
        self.sway_dir = self.heading.copy()
        # (x0, z0, cell) of the grid of columns the surface test answers for (a navigation
        # grid's): a look-ahead is tested at one point in each column it crosses; None: at
        # LOOK_SAMPLES even steps
        self.grid: tuple[float, float, float] | None = None
        # (grid, grid_array(grid)) for the compiled step (none yet: False is never a grid)
        self._grid_array: tuple = (False, None)

    def step(self, dt: float, agent_pos: np.ndarray, agent_speed: float,
             allowed: Callable[[float, float], bool] | None = None,
             aim: np.ndarray | None = None) -> None:
        """Advance by dt seconds toward the agent.

        allowed : optional test of a base position (x, z) -> on the walkable surface. While the
                  base is on it, a step that would leave it turns instead (tighter toward the
                  agent, else sliding along the edge: Detour's move-along-surface for the head),
                  at most on a circle of min_radius, or on the spot at the very edge.
        aim     : optional point to steer toward instead of the agent (a point of the agent's
                  path the head can see); the speed still keeps the head a lead behind the agent
        """
        if isinstance(allowed, compiled.SurfaceTest):
            return self._step_compiled(dt, agent_pos, agent_speed, allowed, aim)
        # in Python floats (the same operations, so the same bits as on the (3,) arrays)
        bx, by, bz = self.base.tolist()
        ax, ay, az = np.asarray(agent_pos, dtype=np.float64).tolist()
        tx, tz = ax - bx, az - bz
        dist = math.hypot(tx, tz)
        if aim is not None and math.hypot(aim[0] - bx, aim[2] - bz) > 1e-9:
            # steer at the aim point; the agent is as far as the way round through it
            tx, tz = float(aim[0]) - bx, float(aim[2]) - bz
            dist = math.hypot(tx, tz) + math.hypot(ax - aim[0], az - aim[2])
        # Speed: match the agent, plus a gain that closes the gap to the lead distance.
        gain = 4.0
        u = max(0.0, min(agent_speed + gain * (dist - self.lead), CATCH_UP * self.max_speed,
                         self.speed_cap))
        if dist < 1e-9:
            u = 0.0
        if u > 0.0 and dist > 1e-9:
            # Don't overshoot the agent when it has stopped.
            step = min(u * dt, max(dist - 0.25 * self.lead, 0.0)) if agent_speed == 0.0 else u * dt
            if self._creep > 0.0:
                # just out of a turn on the spot: walk away from the corner it leaves in the
                # trail at the tight turns' speed, until the body's slow-down can see it
                step = min(step, self.tight_speed * dt)
            m = max(math.hypot(tx, tz), 1e-12)
            wx, wz = tx / m, tz / m
            # Turn toward the agent by at most step / turn_radius: the path's curvature is bounded.
            hx, _, hz = self.heading.tolist()
            cross = hz * wx - hx * wz
            dot = hx * wx + hz * wz
            ang = math.atan2(cross, dot)
            ang = self._u_turn(ang, allowed)
            lim = step / self.turn_radius
            if abs(ang) > 0.5:
                # A sharp turn (a corner, or a new path behind): slow down to bound the yaw rate.
                step = min(step, self.max_yaw_rate * self.turn_radius * dt)
                lim = step / self.turn_radius
            a = max(-lim, min(lim, ang))
            if allowed is not None and allowed(bx, bz):
                a, step = self._contain(a, ang, step, dt, allowed)
            self._creep = max(0.0, self._creep - step)
            if self._creep == 0.0:
                self._spun = 0.0
            c, s = math.cos(a), math.sin(a)
            hx, hz = c * hx + s * hz, -s * hx + c * hz
            self.heading = np.array([hx, 0.0, hz])
            bx, by, bz = bx + hx * step, ay, bz + hz * step
            self.base = np.array([bx, by, bz])
            u = step / dt
        self.speed = u
        # Slither: frequency ~ speed; lateral amplitude = v * A(v) / w(v) rises with speed. The
        # amplitude changes by at most a tenth of the distance walked, so speeding up or slowing
        # down never swings the head sideways on the spot.
        frac = min(u / self.max_speed, 2.0)
        omega = self.turn_rate * self.turn_rate_scale * frac
        self.phase += omega * dt
        want = min(u * self.amplitude / max(self.turn_rate * self.turn_rate_scale, 1e-9),
                   self.max_offset) if omega > 1e-9 else self.lateral_amp
        dmax = 0.1 * u * dt
        self.lateral_amp += max(-dmax, min(dmax, want - self.lateral_amp))
        w = min(1.0, u * dt / (0.5 * self.turn_radius))
        sx, _, sz = self.sway_dir.tolist()
        hx, _, hz = self.heading.tolist()
        dx, dz = sx + w * (hx - sx), sz + w * (hz - sz)
        n = math.hypot(dx, dz)
        if n > 1e-9:
            sx, sz = dx / n, dz / n
            self.sway_dir = np.array([sx, 0.0, sz])
        k = self.lateral_amp * math.sin(self.phase)
        self.position = np.array([bx + sz * k, by + 0.0 * k, bz + -sx * k])

    def _step_compiled(self, dt: float, agent_pos, agent_speed: float,
                       test: compiled.SurfaceTest, aim) -> None:
        """step() with a SurfaceTest, compiled (contain.head_step: the same bits)."""
        base, heading, sway = self.base, self.heading, self.sway_dir
        st = np.array((base[0], base[1], base[2], heading[0], heading[2], self.phase,
                       self.lateral_amp, sway[0], sway[2], self._u_side, self._creep,
                       float(self.hold), float(self.held), self.speed, 0.0, 0.0, 0.0,
                       self._spun))
        prm = np.array((self.lead, self.max_speed, self.speed_cap, self.tight_speed,
                        self.turn_radius, self.max_yaw_rate, self.min_radius, self.turn_rate,
                        self.turn_rate_scale, self.amplitude, self.max_offset, CATCH_UP))
        if self._grid_array[0] is not self.grid:       # grid_array(self.grid), once a grid
            self._grid_array = (self.grid, grid_array(self.grid))
        moved = compiled.head_step(*test.kernel_args(), st, prm,
                                   np.asarray(agent_pos, dtype=np.float64),
                                   _NO_AIM if aim is None else np.asarray(aim, dtype=np.float64),
                                   float(agent_speed), float(dt), self._grid_array[1],
                                   *_ARC_COS_SIN, _TIGHT_ARRAY, _DEFLECT)
        if moved:
            self.base = st[0:3].copy()
            self.heading = np.array((st[3], 0.0, st[4]))
        self.phase, self.lateral_amp, sx, sz, self._u_side, self._creep, _, held, self.speed = \
            st[5:14].tolist()
        self.held = bool(held)
        self.sway_dir = np.array((sx, 0.0, sz))
        self.position = st[14:17].copy()
        self._spun = float(st[17])

    def _u_turn(self, ang: float, allowed) -> float:
        """A target more than a right angle off the heading is a U-turn: it keeps to the side it
        started on (no dithering when the target is almost straight behind; `new_path` forgets
        the side), and with a surface test it starts to the side where the head can walk farther
        round its turning circle (the agent's side, the shorter turn, on a tie). Returns the turn
        angle to use (the long way round when that side is not the shorter one)."""
        if abs(ang) <= 0.5 * math.pi:
            self._u_side = 0.0
            return ang
        if self._u_side == 0.0:
            side = 1.0 if ang >= 0.0 else -1.0
            if allowed is not None:
                side = -side if self._more_room(side, -side, allowed) else side
            self._u_side = side
        if ang * self._u_side < 0.0:
            ang += self._u_side * 2.0 * math.pi
        return ang

    def new_path(self) -> None:
        """The agent has a new path: a U-turn in progress chooses its side afresh."""
        self._u_side = 0.0

    def _more_room(self, first: float, second: float, allowed,
                   radius: float | None = None) -> bool:
        """True when the head reaches more points round its circle on side `second` than on
        side `first` (_circle_room); the second circle is walked only until that is known."""
        room = self._circle_room(first, allowed, radius)
        return self._circle_room(second, allowed, radius, beat=room) > room

    def _circle_room(self, side: float, allowed, radius: float | None = None,
                     beat: int | None = None) -> int:
        """How many of _ARC_STEPS points round the first half of the turning circle on `side`
        (of `radius`, else turn_radius)
        the head reaches walking the circle from its base: from the last point reached, the
        straight line to the next point must stay on the walkable surface (tested every arc
        step), so where the circle only grazes an edge the head cuts inside it, but ground
        beyond a gap in the surface is never reached. Points tested on their own would see
        through a zero-thickness wall that has walkable ground on both sides; walked, the arc
        meets the gap the agent radius leaves round the wall. With `beat`, the walk stops once
        the count is above it or can no longer get above it (a count on the same side of
        `beat` as the whole walk's)."""
        hx, _, hz = self.heading.tolist()      # Python floats: the same bits, sooner
        lx, lz = side * hz, -side * hx
        r = self.turn_radius if radius is None else radius
        px, _, pz = self.base.tolist()
        cx, cz = px + r * lx, pz + r * lz
        d = math.pi * r / _ARC_STEPS
        n = 0
        for j, (c, s) in enumerate(zip(_ARC_COS[1:], _ARC_SIN[1:])):
            if beat is not None and (n > beat or n + _ARC_STEPS - j <= beat):
                break
            qx, qz = cx + r * (-lx * c + hx * s), cz + r * (-lz * c + hz * s)
            m = max(1, math.ceil(math.hypot(qx - px, qz - pz) / d - 1e-9))
            for i in range(1, m + 1):
                if not allowed(px + (qx - px) * i / m, pz + (qz - pz) * i / m):
                    break
            else:
                n += 1
                px, pz = qx, qz
        return n

    def _contain(self, a: float, ang: float, step: float, dt: float, allowed) -> tuple[float, float]:
        """The turn angle and step length that keep the base on the walkable surface.

        a : wanted turn this step; ang : full angle to the agent. Returns (a, step), or a
        sharper turn, slowed to at most CONTAIN_YAW yaw-rate limits on a circle of at least
        min_radius, that keeps the base on the surface (toward the agent first); else (at the
        very edge) a turn on the spot toward the nearest free direction. Sharp turns a few
        steps apart, or turns on the spot, fold the trail back on itself in a cusp that the
        body's chord placement cannot follow (joints jump across it); a reversal on circles of
        min_radius is a loop it follows.
        """
        hx, _, hz = self.heading.tolist()      # Python floats: the same bits, sooner
        bx, _, bz = self.base.tolist()
        side = 1.0 if ang >= a else -1.0
        # a turn sharper than the wanted one is slowed so that the heading turns no faster
        # than CONTAIN_YAW times the yaw-rate limit, on circles of at least min_radius
        slow = min(step, self.tight_speed * dt)
        tight = slow / self.min_radius

        walk = getattr(allowed, "walk", None)

        def free(t: float, s: float, reach: float) -> bool:
            """The step, and the straight way on from it to `reach`, on the surface: a
            look-ahead point alone would see past the corner of an obstacle the way runs
            into."""
            c, sn = math.cos(t), math.sin(t)
            dx, dz = c * hx + sn * hz, -sn * hx + c * hz
            if walk is not None:        # walked by the navigation's links
                return walk(bx, bz, dx, dz, s, reach, self.grid)
            # the look-ahead's end first: where a turn is blocked, it mostly is there
            end = way_end(s, reach, self.grid)
            if end is not None and not allowed(bx + dx * end, bz + dz * end):
                return False
            if not allowed(bx + dx * s, bz + dz * s):
                return False
            if end is not None:
                for r in way_points(bx, bz, dx, dz, s, reach, self.grid)[:-1]:
                    if not allowed(bx + dx * r, bz + dz * r):
                        return False
            return True

        # look a quarter turning radius ahead (and far enough to turn away on the tightest
        # circle), so an edge is met with a few small turns rather than one sharp one
        reach = max(0.25 * self.turn_radius, 2.0 * self.min_radius, step)
        if free(a, step, reach):            # the wanted turn, most often clear
            return a, step
        tighter = tuple((max(-tight, min(tight, a + sd * f * tight)), slow)
                        for f in _TIGHT for sd in (side, -side))
        for t, s in tighter:
            if free(t, s, reach):
                return t, s
        # nothing clear that far ahead: the tightest turn to the side with more room round its
        # circle (the agent's first; a U-turn goes on that way), else any turn whose step stays
        # on; on the spot only at the very edge. (The rooms are measured only when the step of
        # a tightest turn stays on: else the side does not matter.)
        sides = (side, -side)
        clear = [free(sd * tight, slow, slow) for sd in sides]
        if clear[0] or clear[1]:
            k = int(self._more_room(sides[0], sides[1], allowed, self.min_radius))
            if clear[k]:
                if self._u_side != 0.0:
                    self._u_side = sides[k]
                return sides[k] * tight, slow
        for t, s in ((a, step), *tighter):
            if free(t, s, s):
                return t, s
        # cornered: turn on the spot toward the nearest free direction up to a right angle off
        # (toward the agent's side first), else toward the agent
        if self.hold:
            self.held = True
            return 0.0, 0.0
        turn = self.max_yaw_rate * dt
        want = next((t for t in (a + sd * d for d in _DEFLECT for sd in (side, -side))
                     if free(t, step, step)), ang)
        t = max(-turn, min(turn, want))
        # among other bodies, no more than SPIN in turns on the spot before the head has walked
        # off (held instead), where the surface alone would let it walk toward the agent
        bare = getattr(allowed, "bare", None)
        if bare is not None and self._spun + abs(t) > compiled.SPIN:
            c, sn = math.cos(ang), math.sin(ang)
            if bare(bx + (c * hx + sn * hz) * step, bz + (-sn * hx + c * hz) * step):
                self.held = True
                return 0.0, 0.0
        self._creep = 2.0 * self.min_radius
        self._spun += abs(t)
        return t, 0.0


def grid_array(grid: tuple[float, float, float] | None) -> np.ndarray:
    """HeadSteer.grid as the compiled kernels take it: (x0, z0, cell), a zero cell for none."""
    return np.array(grid if grid is not None else (0.0, 0.0, 0.0), dtype=np.float64)
