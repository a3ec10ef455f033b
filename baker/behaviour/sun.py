"""The sun over the bake: fixed, or moving along an azimuth/elevation path."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from baker.geometry.transforms import normalize


@dataclass(frozen=True)
class SunPath:
    """Direction toward the sun over time.

    keys : (K, 3) float unit directions, evenly spaced over [0, duration]; K = 1 is a fixed sun.
    Between keys the direction is interpolated along the great circle (normalized lerp of
    close keys is enough for paths sampled every few degrees).
    """

    keys: np.ndarray
    duration: float

    @property
    def moving(self) -> bool:
        return len(self.keys) > 1

    def at(self, t) -> np.ndarray:
        """(..., 3) directions toward the sun at times t (seconds)."""
        if isinstance(t, float) and self.moving:
            return self._at_scalar(t)
        t = np.asarray(t, dtype=np.float64)
        if not self.moving:
            return np.broadcast_to(self.keys[0], t.shape + (3,)).copy()
        u = np.clip(t / max(self.duration, 1e-9), 0.0, 1.0) * (len(self.keys) - 1)
        i = np.minimum(u.astype(int), len(self.keys) - 2)
        f = (u - i)[..., None]
        return normalize(self.keys[i] * (1 - f) + self.keys[i + 1] * f)

    def _at_scalar(self, t: float) -> np.ndarray:
        """at(t) for one time (the run stage asks every step), in Python floats: the same
        operations in the same order, so the same bits (transforms.normalize: the squares
        summed left to right)."""
        last = len(self.keys) - 1
        u = min(max(t / max(self.duration, 1e-9), 0.0), 1.0) * last
        i = min(int(u), last - 1)
        f = u - i
        g = 1 - f
        k0, k1 = self.keys[i].tolist(), self.keys[i + 1].tolist()
        x, y, z = (k0[0] * g + k1[0] * f, k0[1] * g + k1[1] * f, k0[2] * g + k1[2] * f)
        n = max(math.sqrt(x * x + y * y + z * z), 1e-12)
        return np.array([x / n, y / n, z / n])


def sun_path(keys: np.ndarray | None, fixed: np.ndarray, duration: float,
             azimuth_rate: float = 0.0) -> SunPath:
    """The bake's sun: `keys` (K, 3) from config.parse_sun_path; else the environment's light
    `fixed` (3,), turning about +Y at `azimuth_rate` [rad/s] (counter-clockwise seen from
    above; the environment's Sun.azimuth_rate) over the bake, with keys at most 1 deg apart."""
    if keys is None:
        fixed = np.asarray(fixed, dtype=np.float64)
        turn = azimuth_rate * duration
        if abs(turn) < 1e-9:
            return SunPath(fixed[None], duration)
        a = np.linspace(0.0, turn, int(np.ceil(abs(np.degrees(turn)))) + 1)
        c, s = np.cos(a), np.sin(a)
        keys = np.stack([c * fixed[0] + s * fixed[2], np.full_like(a, fixed[1]),
                         -s * fixed[0] + c * fixed[2]], 1)
    return SunPath(np.asarray(keys, dtype=np.float64), duration)
