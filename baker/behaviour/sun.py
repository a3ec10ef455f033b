"""The sun over the bake: fixed, or moving along an azimuth/elevation path."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from baker.errors import ConfigError
from baker.geometry.transforms import normalize


def direction_from_angles(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Unit vectors toward the sun. Azimuth is measured from +Z toward +X, elevation from the
    horizon, both in radians. Shapes broadcast; returns (..., 3)."""
    az, el = np.broadcast_arrays(np.asarray(azimuth, float), np.asarray(elevation, float))
    return np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], axis=-1)


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
        t = np.asarray(t, dtype=np.float64)
        if not self.moving:
            return np.broadcast_to(self.keys[0], t.shape + (3,)).copy()
        u = np.clip(t / max(self.duration, 1e-9), 0.0, 1.0) * (len(self.keys) - 1)
        i = np.minimum(u.astype(int), len(self.keys) - 2)
        f = (u - i)[..., None]
        return normalize(self.keys[i] * (1 - f) + self.keys[i + 1] * f)


def parse_sun_path(text: str, duration: float, samples_per_key: int = 16) -> SunPath:
    """'AZ,EL;AZ,EL;...' in degrees, evenly spaced over the bake, densified so that the
    interpolation follows the sky (azimuth and elevation are interpolated, not vectors)."""
    try:
        pairs = [tuple(float(v) for v in part.split(",")) for part in text.split(";") if part.strip()]
    except ValueError:
        raise ConfigError("--sun-path must look like 'AZ,EL;AZ,EL' in degrees, e.g. '90,30;270,30'") from None
    if len(pairs) < 1 or any(len(p) != 2 for p in pairs):
        raise ConfigError("--sun-path must look like 'AZ,EL;AZ,EL' in degrees, e.g. '90,30;270,30'")
    ang = np.radians(np.array(pairs))
    if np.any(ang[:, 1] <= 0) or np.any(ang[:, 1] > math.pi / 2):
        raise ConfigError("--sun-path elevations must be in (0, 90] degrees")
    if len(ang) == 1:
        return SunPath(direction_from_angles(ang[:1, 0], ang[:1, 1]), duration)
    u = np.linspace(0, len(ang) - 1, (len(ang) - 1) * samples_per_key + 1)
    az = np.interp(u, np.arange(len(ang)), ang[:, 0])
    el = np.interp(u, np.arange(len(ang)), ang[:, 1])
    return SunPath(direction_from_angles(az, el), duration)
