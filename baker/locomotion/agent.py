"""The navigation agent: moves along a planned path with a maximum speed, an acceleration
limit and a stopping distance (as Unity's NavMeshAgent does)."""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

from baker.geometry import polyline
from baker.locomotion.contain import largest_jump


class PathAgent:
    """A point that travels along a path polyline.

    position : (3,) float, metres, world — on the path
    speed    : float, m/s, along the path
    """

    def __init__(self, position: np.ndarray, max_speed: float, acceleration: float,
                 stopping_distance: float):
        self.max_speed = float(max_speed)
        self.acceleration = float(acceleration)
        self.stopping_distance = float(stopping_distance)
        self.speed_scale = 1.0
        self.position = np.asarray(position, dtype=np.float64).copy()
        self.speed = 0.0
        self._points = self.position[None, :].copy()
        self._cum = [0.0]           # arc lengths as Python floats, for the step loop's look-ups
        self._rows = self._points.tolist()   # the points as Python floats, for the same
        self._placed = None         # the position step() put at _s on the current path
        self._s = 0.0

    def set_path(self, points: np.ndarray) -> None:
        """Follow a new path from the agent's current position. points : (k, 3) float."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0 or np.linalg.norm(pts[0] - self.position) > 1e-9:
            pts = np.vstack([self.position, pts])
        self._points = np.ascontiguousarray(pts)
        self._cum = polyline.arc_lengths(pts).tolist()
        self._rows = pts.tolist()
        self._s = 0.0
        self._placed = None

    def point_behind(self, distance: float) -> np.ndarray:
        """The path's point `distance` metres behind the agent (its start at most)."""
        return self._at(max(self._s - distance, 0.0))

    def skip(self, distance: float) -> None:
        """Move `distance` metres along the path at once (not past its end)."""
        self._s = min(self._s + max(distance, 0.0), self._cum[-1])
        self.position = self._at(self._s)

    @property
    def remaining(self) -> float:
        """Metres left along the path."""
        return float(self._cum[-1] - self._s)

    @property
    def arrived(self) -> bool:
        return self.remaining <= self.stopping_distance + 1e-9 and self.speed == 0.0

    def _at(self, s: float) -> np.ndarray:
        """Point at arc length s (scalar fast path of polyline.sample, for the step loop; in
        Python floats, the same operations as on the (3,) rows)."""
        cum = self._cum
        if len(cum) == 1:
            return self._points[0].copy()
        i = min(max(bisect_right(cum, s) - 1, 0), len(cum) - 2)   # np.searchsorted "right"
        seg = cum[i + 1] - cum[i]
        t = (s - cum[i]) / seg if seg > 0 else 0.0
        (ax, ay, az), (bx, by, bz) = self._rows[i], self._rows[i + 1]
        return np.array([ax + t * (bx - ax), ay + t * (by - ay), az + t * (bz - az)])

    def largest_rise(self, back: float, ahead: float) -> float:
        """Largest height jump [m] between neighbouring path points from `back` metres behind the
        agent to `ahead` metres in front of it (the path carries its layer's heights)."""
        cum = self._cum
        if len(cum) < 2:
            return 0.0
        i0 = max(bisect_right(cum, self._s - back) - 1, 0)
        i1 = min(bisect_right(cum, self._s + ahead) + 1, len(cum))
        if i1 - i0 < 2:
            return 0.0
        return largest_jump(self._points, i0, i1)

    @property
    def goal(self) -> np.ndarray:
        return self._points[-1]

    def step(self, dt: float, slack: float = 1.0) -> None:
        """Advance by dt seconds: brake to stop at the stopping distance, else accelerate.

        slack : 0..1, how much of the maximum speed the follower allows (1 = free, 0 = wait for
                the head, which is still turning toward the path)
        """
        end, s0, acc, speed = self._cum[-1], self._s, self.acceleration, self.speed
        vmax = self.max_speed * self.speed_scale * min(max(slack, 0.0), 1.0)
        free = max(end - s0 - self.stopping_distance, 0.0)      # (remaining, less the stop)
        target = min(vmax, math.sqrt(2.0 * acc * free))
        dv = acc * dt
        speed = min(max(target, speed - dv), speed + dv)
        if free <= 0.0:
            speed = max(speed - dv, 0.0)
        self.speed = speed
        s = min(s0 + speed * dt, end)
        if s == s0 and self.position is self._placed:
            return        # standing still on the same path: the same point
        self._s = s
        self.position = self._placed = self._at(s)
