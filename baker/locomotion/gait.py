"""The gait clock: a retrograde metachronal wave whose phase advances with distance travelled.

Every walking leg has phase  phi_l = travel / stride + lag_l  (in cycles). A foot is planted while
frac(phi_l) < duty and swings otherwise. Because the phase is a function of the distance the body
has moved along its trail, not of time, a planted foot stays still by construction and a body that
stops stops its gait. The stride (body travel per cycle) grows with speed.

Lags (rig/limbs.py): leg k on one side lags leg k-1 by waves / pairs cycles (2 waves over 20 pairs:
36 degrees), so the wave runs head to tail; right legs are half a cycle from the left ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d


@dataclass(frozen=True)
class GaitClock:
    """Per-frame gait state shared by all legs.

    travel : (F,) float64, metres travelled along the trail since frame 0 (non-decreasing)
    speed  : (F,) float64, m/s, smoothed
    stride : (F,) float64, metres of body travel per step cycle at each frame
    phase  : (F,) float64, cycles; leg l's phase is phase + lag_l
    """

    travel: np.ndarray
    speed: np.ndarray
    stride: np.ndarray
    phase: np.ndarray


def stride_length(speed: np.ndarray, max_speed: float, stride_min: float, stride_max: float
                  ) -> np.ndarray:
    """Body travel per step cycle: stride_min at rest, growing linearly to stride_max at max_speed."""
    x = np.clip(np.asarray(speed, float) / max(max_speed, 1e-12), 0.0, 1.0)
    return stride_min + (stride_max - stride_min) * x


def gait_clock(arc: np.ndarray, times: np.ndarray, max_speed: float, stride_min: float,
               stride_max: float, smooth_s: float = 0.1) -> GaitClock:
    """Integrate the gait phase over the body's travel.

    arc   : (F,) float, metres, the body's arc length along its trail at each frame
    times : (F,) float, seconds, strictly increasing
    """
    arc = np.asarray(arc, float)
    times = np.asarray(times, float)
    ds = np.maximum(np.diff(arc, prepend=arc[:1]), 0.0)
    travel = np.cumsum(ds)
    dt = np.diff(times, prepend=times[0] - (times[1] - times[0]) if len(times) > 1 else 1.0)
    speed = ds / np.maximum(dt, 1e-12)
    if len(times) > 2 and smooth_s > 0:
        sigma = smooth_s / float(np.median(np.diff(times)))
        speed = gaussian_filter1d(speed, sigma, mode="nearest")
    stride = stride_length(speed, max_speed, stride_min, stride_max)
    phase = np.cumsum(ds / stride)
    return GaitClock(travel=travel, speed=speed, stride=stride, phase=phase)


def leg_phase(clock: GaitClock, lag: np.ndarray) -> np.ndarray:
    """(F, L) phase of every leg, in cycles."""
    return clock.phase[:, None] + np.asarray(lag, float)[None, :]


def stance_mask(phase: np.ndarray, duty: float) -> np.ndarray:
    """True where the ideal gait has the foot planted: frac(phase) < duty."""
    return (phase - np.floor(phase)) < duty
