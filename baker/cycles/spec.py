"""Locomotion cycles: options, clip specifications, constants and the flat ground."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from baker.config import BakeConfig, RigConfig

#: [s] simulated before a loop window (speed, slither amplitude and body on the trail settle)
WARMUP = 5.0
#: [s] simulated after a window (smoothing along the trail and the legs' look-ahead)
COOLDOWN = 2.5
#: [s] standing still before the idle window and the one-shots (feet settle)
IDLE_WARMUP = 2.0
#: [s] shortest and longest loop window (longer for slow speeds: at least 4 slowest periods)
LOOP_MIN, LOOP_MAX = 2.0, 10.0
#: largest relative nudge of the slither frequency and the stride to fit whole cycles
NUDGE_TOL = 0.01
#: ... of the antennae's sweep and grope frequencies (then rounded to whole cycles regardless)
CHAIN_TOL = 0.05
#: [s] how long the first rate measurement looks at the steady walk
PROBE = 3.0
#: [BL] radius of the turning circles (walked by the navigation agent)
TURN_RADIUS = 1.0
#: [BL] distance of the strike's lunge
LUNGE = 0.3
#: [deg] largest rotation per frame the blend into and out of a one-shot adds to a joint
BLEND_RATE = 6.0
#: [s] shortest blend ramp
BLEND_MIN = 0.3
#: walk and run speeds accepted by --speeds [BL/s] (faster turns on the 1 BL circle and runs
#: leave residuals of millimetres: the walk is not periodic enough any more)
WALK_RANGE = (0.2, 2.0)
RUN_RANGE = (0.2, 3.0)
#: [m] a residual above this is logged as a warning (the seam is closed all the same)
RESIDUAL_WARN = 1e-4
#: clip names: loops end in `_loop` (Godot imports them as looping and strips the suffix)
LOOP_SUFFIX = "_loop"


@dataclass(frozen=True)
class CyclesConfig:
    """`baker cycles` options.

    rig        : the rig (metres)
    out        : output folder; writes cycles.glb, cycles.usd and cycles.json in it
    fps        : [Hz] export frame rate (divides 240)
    walk_speed : [BL/s] walk and turn speed; None: the rig's locomotion.max_speed
    run_speed  : [BL/s] run speed; None: max_speed x behaviour.onslaught_speed
    """

    rig: RigConfig = field(default_factory=RigConfig)
    out: Path = Path("outputs")
    fps: int = 30
    walk_speed: float | None = None
    run_speed: float | None = None

    def speeds(self) -> tuple[float, float]:
        """(walk, run) in BL/s."""
        bl, loco = self.rig.body.length, self.rig.locomotion
        walk = self.walk_speed if self.walk_speed is not None else loco.max_speed / bl
        run = (self.run_speed if self.run_speed is not None
               else loco.max_speed * self.rig.behaviour.onslaught_speed / bl)
        return float(walk), float(run)

    def output_paths(self) -> dict[str, Path]:
        return {k: Path(self.out) / f"cycles.{k}" for k in ("glb", "usd", "json")}


@dataclass(frozen=True)
class LoopSpec:
    """A looping clip: walk `speed` [m/s] along a straight line (turn 0) or a circle to the
    left (+1) or right (-1), with the brain's speed and slither turn-rate scales."""

    name: str
    state: str
    speed: float
    speed_scale: float
    turn_scale: float
    turn: int = 0


def validate_cycles(cfg: CyclesConfig) -> CyclesConfig:
    """ConfigError for an fps that does not divide the simulation rate or speeds out of range."""
    from baker.config import validate_bake
    from baker.errors import ConfigError

    validate_bake(BakeConfig(fps=cfg.fps))
    for what, v, (lo, hi) in (("walk", cfg.walk_speed, WALK_RANGE),
                              ("run", cfg.run_speed, RUN_RANGE)):
        if v is not None and not (math.isfinite(v) and lo <= v <= hi):
            raise ConfigError(f"--speeds: the {what} speed must be in [{lo}, {hi}] body lengths "
                              f"per second (got {v:g})", where="--speeds")
    return cfg


def loop_specs(cfg: CyclesConfig) -> list[LoopSpec]:
    """walk, run, turn_left_walk and turn_right_walk (names with the loop suffix)."""
    bl, loco, beh = cfg.rig.body.length, cfg.rig.locomotion, cfg.rig.behaviour
    walk, run = (s * bl for s in cfg.speeds())
    w = LoopSpec("walk" + LOOP_SUFFIX, "walk", walk, walk / loco.max_speed, 1.0)
    r = LoopSpec("run" + LOOP_SUFFIX, "run", run, run / loco.max_speed, beh.onslaught_turn_rate)
    return [w, r, replace(w, name="turn_left_walk" + LOOP_SUFFIX, state="turn_left", turn=1),
            replace(w, name="turn_right_walk" + LOOP_SUFFIX, state="turn_right", turn=-1)]


def flat_environment(extent, name: str = "flat_ground"):
    """A plane y = 0 over extent = (x0, x1, z0, z1) metres: two triangles, facing up."""
    from baker.environment.model import EnvMesh, Environment, Sun

    x0, x1, z0, z1 = (float(v) for v in extent)
    v = np.array([[x0, 0, z0], [x1, 0, z0], [x0, 0, z1], [x1, 0, z1]], np.float32)
    f = np.array([[0, 2, 1], [1, 2, 3]], np.uint32)
    n = np.tile(np.array([[0.0, 1.0, 0.0]], np.float32), (4, 1))
    mesh = EnvMesh(name="ground", vertices=v, faces=f, normals=n,
                   color=(0.066, 0.05, 0.04, 1.0), roughness=1.0, metallic=0.0)
    sun = np.array([0.3, 1.0, 0.2])
    return Environment(meshes=(mesh,), sun=Sun(direction=sun / np.linalg.norm(sun)), name=name)


def sim_seconds(spec: LoopSpec, rig: RigConfig) -> float:
    """Longest a loop's simulation runs: warm-up, the longest window, cool-down."""
    return warmup(spec, rig) + window_range(spec, rig)[1] + COOLDOWN


def warmup(spec: LoopSpec, rig: RigConfig) -> float:
    """[s] warm-up: WARMUP, or longer for a slow walk (the whole body on the walked trail) or
    a fast one (3 s after the agent has reached its speed)."""
    return max(WARMUP, 3.0 * rig.body.length / spec.speed + 2.0,
               spec.speed / rig.locomotion.acceleration + 3.0)


def window_range(spec: LoopSpec, rig: RigConfig) -> tuple[float, float]:
    """[s] shortest and longest loop window: LOOP_MIN..LOOP_MAX, or up to 4 slither periods
    (the head's slither runs at head_turn_rate x turn scale x speed / max speed, at most 2x)."""
    loco = rig.locomotion
    rate = loco.head_turn_rate * spec.turn_scale * min(spec.speed / loco.max_speed, 2.0)
    return LOOP_MIN, max(LOOP_MAX, 4.0 * 2.0 * math.pi / max(rate, 1e-9))


def sim_extent(cfg: CyclesConfig, specs) -> tuple[float, float, float, float]:
    """(x0, x1, z0, z1) of a plane that holds every simulated path (with a margin)."""
    bl = cfg.rig.body.length
    r = TURN_RADIUS * bl
    reach = max(s.speed * sim_seconds(s, cfg.rig) for s in specs if s.turn == 0) * 1.2 + bl
    side = 2.0 * r + 2.0 * bl
    return (-side, side, -side, max(reach, side))


def ground_extent(clips) -> tuple[float, float, float, float]:
    """(x0, x1, z0, z1) of a small plane under every clip's root path (0.5 m margin)."""
    pts = np.concatenate([np.asarray(c.translations[:, 0], np.float64) for c in clips])
    lo, hi = pts.min(axis=0) - 0.5, pts.max(axis=0) + 0.5
    return (round(float(lo[0]), 1), round(float(hi[0]), 1), round(float(lo[2]), 1),
            round(float(hi[2]), 1))


