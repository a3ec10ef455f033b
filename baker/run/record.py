"""What the run stage hands the solve stage: one creature's run, small and plain."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class RunRecord:
    """One creature's run. F exported frames, N = seconds x sim_rate steps, P prey.

    fps, sim_rate : export frame rate and simulation rate [Hz] (sim_rate % fps == 0)
    start, heading: (3,) float64, the start point (metres, world) and unit horizontal heading
    start_line    : (n, 3) float64 metres, the straight body line behind the start (tail end
                    first, the head's point excluded), on the layer nearest the start
    heads         : (N + 1, 3) float64 metres, the head (slither included) after every step
    cobra         : (F,) float64 0..1, the cobra request ramped over the cobra's ramp time
    warning       : (F,) float64 0/1, the Posture 1 request
    slither       : (F,) float64 radians, the head's slither phase
    sun_directions: (F, 3) float64 unit vectors toward the sun
    prey_names    : P names; prey_positions (F, P, 3) float64 metres on their agents' paths;
    prey_modes    : (F, P) int8, behaviour.prey FREE / CAPTURED / HELD / HIDDEN
    events        : the behaviour timeline, dicts {start, end, state, details}
    chain_period  : [s] or None: antennae and ultimate legs repeat after this period
    replans       : paths planned again from the head (the report's path_replans)
    """

    fps: int
    sim_rate: int
    start: np.ndarray
    heading: np.ndarray
    start_line: np.ndarray
    heads: np.ndarray
    cobra: np.ndarray
    warning: np.ndarray
    slither: np.ndarray
    sun_directions: np.ndarray
    prey_names: tuple[str, ...] = ()
    prey_positions: np.ndarray | None = None
    prey_modes: np.ndarray | None = None
    events: tuple[dict, ...] = ()
    chain_period: float | None = None
    replans: int = 0

    @property
    def per_frame(self) -> int:
        """Simulation steps per exported frame."""
        return self.sim_rate // self.fps

    @property
    def frame_steps(self) -> np.ndarray:
        """(F,) int, the step of every exported frame."""
        return np.arange(0, len(self.heads), self.per_frame)

    @property
    def times(self) -> np.ndarray:
        """(F,) float64 seconds of every exported frame."""
        return self.frame_steps * (1.0 / self.sim_rate)


class Recorder:
    """Per-frame samples of what the loop decided (drives and prey states), filled in place."""

    def __init__(self, n_frames: int, n_prey: int):
        self.cobra = np.zeros(n_frames)
        self.warning = np.zeros(n_frames)
        self.prey_pos = np.zeros((n_frames, n_prey, 3))
        self.prey_mode = np.zeros((n_frames, n_prey), dtype=np.int8)
        self.slither = np.zeros(n_frames)

    def sample(self, f: int, intent, preys, cobra: float, slither: float = 0.0) -> None:
        self.cobra[f] = cobra
        self.slither[f] = slither
        self.warning[f] = intent.warning
        for j, p in enumerate(preys):
            self.prey_pos[f, j] = p.position
            self.prey_mode[f, j] = p.mode
