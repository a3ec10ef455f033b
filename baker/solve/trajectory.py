"""The simulation's output: frames of the creature, sampled at the export fps, in the
environment's local frame (world = Environment.origin + position; "world" below means that
frame, the one the simulation runs in)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Trajectory:
    """World-space motion of the spine, one row per exported frame.

    times           : (F,) float64, seconds, starts at 0, strictly increasing
    spine_positions : (F, S, 3) float64, metres, world; joint origins head (0) to tail (S-1)
    spine_rotations : (F, S, 4) float64, xyzw, world; local +Z points toward the segment ahead
                      (the head's toward its heading), local +Y along the surface normal
    head_surface_normal : (F, 3) float64, unit normal of the surface under the head
    ground_heights  : (F, S) float64, metres, height of the surface below each spine joint
                      (NaN where nothing is below)
    events          : behaviour timeline, list of dicts {start, end, state, details}

    Limb joints (legs, antennae, ...; empty for a spine-only bake):
    joint_names     : K skeleton joint names driven by the two arrays below
    joint_positions : (F, K, 3) float64, metres, world joint origins (None when K == 0)
    joint_rotations : (F, K, 4) float64, xyzw, world; limb bones run along local +Y
    foot_contacts   : (F, L) bool, walking leg planted, legs ordered L_01, R_01, L_02, ...
                      (None without legs)

    Behaviour channels:
    cobra_lift      : (F, S) float64 metres, cobra lift applied to each spine joint (or None)
    warning         : (F,) float64 0..1, Posture 1 (ultimate legs raised) request (or None)
    sun_directions  : (F, 3) float64 unit vectors toward the sun (or None: the environment's)
    prey_names      : P prey node names
    prey_positions  : (F, P, 3) float64 metres, world capsule centres
    prey_rotations  : (F, P, 4) float64 xyzw world; capsule long axis along local +Z
    prey_visible    : (F, P) bool, False once eaten
    prey_modes      : (F, P) int8, behaviour.prey FREE / CAPTURED / HELD / HIDDEN

    Clocks (what the gait and the slither run on; for looping cycles, not exported):
    head_arc        : (F,) float64 metres, the head's arc length along its trail (the gait
                      clock's input), or None
    slither_phase   : (F,) float64 radians, the head's slither phase (unwrapped), or None
    """

    times: np.ndarray
    spine_positions: np.ndarray
    spine_rotations: np.ndarray
    head_surface_normal: np.ndarray
    ground_heights: np.ndarray
    events: tuple[dict, ...] = field(default_factory=tuple)
    joint_names: tuple[str, ...] = ()
    joint_positions: np.ndarray | None = None
    joint_rotations: np.ndarray | None = None
    foot_contacts: np.ndarray | None = None
    cobra_lift: np.ndarray | None = None
    warning: np.ndarray | None = None
    sun_directions: np.ndarray | None = None
    prey_names: tuple[str, ...] = ()
    prey_positions: np.ndarray | None = None
    prey_rotations: np.ndarray | None = None
    prey_visible: np.ndarray | None = None
    prey_modes: np.ndarray | None = None
    head_arc: np.ndarray | None = None
    slither_phase: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return len(self.times)
