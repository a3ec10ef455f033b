"""Configuration: frozen dataclasses, one section per stage, loaded from TOML and validated.

Every field documents its [Limit] and [Units]. Rig files give lengths in body lengths [BL];
`load_rig_config` converts them to metres, so everything downstream is in metres and seconds.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from baker.errors import ConfigError
from baker.geometry.conventions import SIM_RATE_HZ

PACKAGE_ROOT = Path(__file__).resolve().parent
REPO_ROOT = PACKAGE_ROOT.parent
DEFAULT_RIG = REPO_ROOT / "rigs" / "scolopendra.toml"
DEFAULT_ENVIRONMENT = REPO_ROOT / "environments" / "rainforest_floor.glb"
MAX_FPS = 240  # [Limit] export fps must divide SIM_RATE_HZ and be at most this


# --------------------------------------------------------------------------- rig sections
@dataclass(frozen=True)
class BodyConfig:
    length: float = 0.25           # [>0] [m] head tip to last trunk joint
    segments: int = 21             # [3..255] head + trunk segments
    width_profile: tuple[float, ...] = ()  # [>0] [m] half-width per segment, head to tail
    height_ratio: float = 0.55     # [>0] cross-section height / width
    clearance: float = 0.0075      # [>=0] [m] centre line above the surface below
    leg_stub_length: float = 0.015  # [>=0] [m] static leg stubs on the mesh

    @property
    def spacing(self) -> float:
        """[m] arc length between neighbouring spine joints."""
        return self.length / (self.segments - 1)


@dataclass(frozen=True)
class ColorsConfig:
    body: tuple[float, float, float] = (0.105, 0.065, 0.034)  # [0..1] linear RGB
    legs: tuple[float, float, float] = (0.195, 0.125, 0.053)  # [0..1] linear RGB


@dataclass(frozen=True)
class LocomotionConfig:
    max_speed: float = 0.2          # [>0] [m/s] agent cruising speed
    acceleration: float = 0.4       # [>0] [m/s^2]
    stopping_distance: float = 0.15  # [>=0] [m] slow down within this distance of the target
    head_turn_rate: float = 4.0     # [>=0] [rad/s] slither angular frequency at max speed
    slither_amplitude: float = math.radians(25.0)  # [0..pi/2] [rad] heading swing at max speed


@dataclass(frozen=True)
class WanderConfig:
    interval: float = 5.0   # [>0] [s] time between new targets
    radius: float = 5.0     # [>0] [m] target sphere radius around the head


@dataclass(frozen=True)
class NavAgentConfig:
    radius: float = 0.015       # [>0] [m] agent radius (erosion)
    height: float = 0.05        # [>0] [m] free space needed above a walkable sample
    step_height: float = 0.05   # [>=0] [m] largest height difference between linked samples
    max_slope: float = math.radians(60.0)  # [0..pi/2) [rad]
    cell_size: float = 0.015    # [>0] [m] horizontal sample spacing


@dataclass(frozen=True)
class LegsConfig:
    """Walking legs, ultimate legs, antennae and forcipules. Rig files give lengths in [BL]."""

    enabled: bool = True            # [bool] False: spine only, static leg stubs on the mesh
    upper_length: float = 0.0275    # [>0] [m] hip -> knee bone (coxa..femur)
    tip_length: float = 0.03        # [>0] [m] knee -> foot bone (tibia..tarsus)
    hip_width: float = 0.75         # [0..1.5] hip's lateral offset as a fraction of the half-width
    reach: float = 0.0425           # [>0] [m] foot anchor's lateral distance from the centre line
    knee_out: float = 0.35          # [>=0] knee pole = up (across the leg) + knee_out * outward
    duty: float = 0.6               # (0..1) fraction of a step cycle a foot is planted
    waves: float = 2.0              # [>0] gait waves along the body (lag = waves * 360 / pairs)
    stride_min: float = 0.04        # [>0] [m] body travel per step cycle when slow
    stride_max: float = 0.075       # [>=stride_min] [m] body travel per step cycle at max speed
    lift: float = 0.0075            # [>=0] [m] swing height at mid swing
    settle_time: float = 0.35       # [>0] [s] longest swing; feet land by then when the body stops
    max_swing_rate: float = math.radians(420.0)  # [>0] [rad/s] fastest leg sweep in a swing;
                                    # the duty factor drops at high speed to respect it
    radius: float = 0.0016          # [>0] [m] leg tube radius at the hip (tapers to a point)
    ultimate_upper: float = 0.025   # [>0] [m] ultimate leg bones, trailing backward
    ultimate_tip: float = 0.03      # [>0] [m]
    ultimate_raise: float = math.radians(15.0)   # [0..pi/2] [rad] pitch above the body axis
                                                 # (warning posture: up to vertical)
    ultimate_spread: float = math.radians(20.0)  # [0..pi/2] [rad] outward from the body axis
    antenna_length: float = 0.03    # [>0] [m] each of the two antenna joints
    antenna_sweep: float = math.radians(25.0)    # [0..pi/2] [rad] side-to-side sweep amplitude
    antenna_rate: float = 1.3       # [>=0] [Hz] sweep frequency
    forcipule_length: float = 0.012  # [>0] [m] each forcipule bone


@dataclass(frozen=True)
class RigConfig:
    name: str = "scolopendra"
    source: str = ""
    body: BodyConfig = field(default_factory=BodyConfig)
    colors: ColorsConfig = field(default_factory=ColorsConfig)
    locomotion: LocomotionConfig = field(default_factory=LocomotionConfig)
    wander: WanderConfig = field(default_factory=WanderConfig)
    navigation: NavAgentConfig = field(default_factory=NavAgentConfig)
    legs: LegsConfig = field(default_factory=LegsConfig)


# --------------------------------------------------------------------------- bake run
@dataclass(frozen=True)
class BakeConfig:
    environment: Path = DEFAULT_ENVIRONMENT  # file to load
    seconds: float = 20.0        # [>0, <=3600] [s] simulated duration
    fps: int = 30                # [1..240, divides 240] [Hz] export frame rate
    seed: int = 0                # [>=0] random seed
    rig: RigConfig = field(default_factory=RigConfig)
    out: Path = Path("outputs/centipede")  # output path without extension
    formats: tuple[str, ...] = ("glb", "usd")  # subset of {"glb", "usd", "usda"}
    sun_direction: tuple[float, float, float] | None = None  # toward the sun; None: from file
    debug_navmesh: bool = False
    nav_cache_dir: Path | None = None  # None: no on-disk navigation cache

    @property
    def sim_rate(self) -> int:
        return SIM_RATE_HZ

    @property
    def n_frames(self) -> int:
        """Frames exported, including frame 0 and the last frame at `seconds`."""
        return int(round(self.seconds * self.fps)) + 1

    def output_paths(self) -> dict[str, Path]:
        ext = {"glb": ".glb", "usd": ".usd", "usda": ".usda"}
        paths = {f: self.out.with_name(self.out.name + ext[f]) for f in self.formats}
        paths["json"] = self.out.with_name(self.out.name + ".json")
        return paths


def validate_bake(cfg: BakeConfig) -> BakeConfig:
    """Raise ConfigError for out-of-range run options; returns cfg unchanged."""
    if not (isinstance(cfg.seconds, (int, float)) and math.isfinite(cfg.seconds)) or cfg.seconds <= 0:
        raise ConfigError(f"--seconds must be > 0 (got {cfg.seconds})")
    if cfg.seconds > 3600:
        raise ConfigError(f"--seconds must be at most 3600 (got {cfg.seconds})")
    if cfg.fps <= 0:
        raise ConfigError(f"--fps must be > 0 (got {cfg.fps})")
    if cfg.fps > MAX_FPS or SIM_RATE_HZ % cfg.fps:
        divisors = [d for d in range(1, MAX_FPS + 1) if SIM_RATE_HZ % d == 0]
        raise ConfigError(
            f"--fps {cfg.fps} is not supported: it must divide the {SIM_RATE_HZ} Hz simulation "
            f"step (one of {', '.join(map(str, divisors))})")
    if cfg.seed < 0:
        raise ConfigError(f"--seed must be >= 0 (got {cfg.seed})")
    bad = set(cfg.formats) - {"glb", "usd", "usda"}
    if bad or not cfg.formats:
        raise ConfigError(f"unknown output format(s): {', '.join(sorted(bad)) or 'none given'}")
    if cfg.sun_direction is not None:
        d = np.asarray(cfg.sun_direction, dtype=float)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-9:
            raise ConfigError("--sun must be three numbers x,y,z pointing toward the sun")
        if d[1] <= 0:
            raise ConfigError("--sun must point upward (y > 0): the sun is above the horizon")
    return cfg


# --------------------------------------------------------------------------- TOML loading
def _section(cls, data: dict, where: str, scale: dict[str, float]):
    """Build dataclass `cls` from TOML table `data`, multiplying fields in `scale`."""
    known = {f.name: f for f in fields(cls)}
    unknown = set(data) - set(known)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
    kw = {}
    for k, v in data.items():
        if isinstance(v, list):
            v = tuple(float(x) * scale.get(k, 1.0) for x in v)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            if k in scale:
                v = float(v) * scale[k]
        kw[k] = v
    return cls(**kw)


def load_rig_config(path: Path | str) -> RigConfig:
    """Read a rig TOML file. Lengths in [BL] become metres; degrees become radians."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"rig file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ConfigError(f"rig file {path} is not valid TOML: {e}") from None
    body_t = dict(data.get("body", {}))
    length = float(body_t.get("length", 0.25))
    if not length > 0:
        raise ConfigError(f"{path}: body.length must be > 0")
    bl = {"width_profile": length, "clearance": length, "leg_stub_length": length}
    body = _section(BodyConfig, body_t, f"{path} [body]", bl)
    deg = math.pi / 180.0
    loco = _section(LocomotionConfig, data.get("locomotion", {}), f"{path} [locomotion]",
                    {"max_speed": length, "acceleration": length, "stopping_distance": length,
                     "slither_amplitude": deg})
    wander = _section(WanderConfig, data.get("wander", {}), f"{path} [wander]", {"radius": length})
    nav_t = dict(data.get("navigation", {}))
    nav_t = {{"agent_radius": "radius", "agent_height": "height"}.get(k, k): v for k, v in nav_t.items()}
    nav = _section(NavAgentConfig, nav_t, f"{path} [navigation]",
                   {"radius": length, "height": length, "step_height": length,
                    "cell_size": length, "max_slope": deg})
    colors = _section(ColorsConfig, data.get("colors", {}), f"{path} [colors]", {})
    legs = _section(LegsConfig, data.get("legs", {}), f"{path} [legs]",
                    {**{k: length for k in _LEG_LENGTHS},
                     **{k: deg for k in ("ultimate_raise", "ultimate_spread", "antenna_sweep",
                                         "max_swing_rate")}})
    extra = set(data) - {"name", "body", "colors", "locomotion", "wander", "navigation", "legs"}
    if extra:
        raise ConfigError(f"{path}: unknown section(s) {', '.join(sorted(extra))}")
    rig = RigConfig(name=str(data.get("name", path.stem)), source=str(path), body=body,
                    colors=colors, locomotion=loco, wander=wander, navigation=nav, legs=legs)
    return validate_rig(rig, str(path))


#: LegsConfig fields given in body lengths in rig files (metres in LegsConfig)
_LEG_LENGTHS = ("upper_length", "tip_length", "reach", "stride_min", "stride_max", "lift",
                "radius", "ultimate_upper", "ultimate_tip", "antenna_length", "forcipule_length")


def validate_rig(rig: RigConfig, where: str = "rig") -> RigConfig:
    b = rig.body
    if not 3 <= b.segments <= 255:
        raise ConfigError(f"{where}: body.segments must be in 3..255 (got {b.segments})")
    if b.width_profile and len(b.width_profile) != b.segments:
        raise ConfigError(f"{where}: body.width_profile needs {b.segments} values "
                          f"(got {len(b.width_profile)})")
    if any(w <= 0 for w in b.width_profile):
        raise ConfigError(f"{where}: body.width_profile values must be > 0")
    checks = [
        (rig.locomotion.max_speed > 0, "locomotion.max_speed must be > 0"),
        (rig.locomotion.acceleration > 0, "locomotion.acceleration must be > 0"),
        (rig.wander.interval > 0, "wander.interval must be > 0"),
        (rig.wander.radius > 0, "wander.radius must be > 0"),
        (rig.navigation.radius > 0, "navigation.agent_radius must be > 0"),
        (rig.navigation.height > 0, "navigation.agent_height must be > 0"),
        (rig.navigation.cell_size > 0, "navigation.cell_size must be > 0"),
        (0 < rig.navigation.max_slope < math.pi / 2, "navigation.max_slope must be in (0, 90) deg"),
        (b.clearance >= 0, "body.clearance must be >= 0"),
    ]
    lg = rig.legs
    checks += [
        (isinstance(lg.enabled, bool), "legs.enabled must be true or false"),
        (all(getattr(lg, k) > 0 for k in _LEG_LENGTHS if k != "lift"),
         "legs lengths (bones, reach, strides, radius) must be > 0"),
        (lg.lift >= 0, "legs.lift must be >= 0"),
        (0 < lg.duty < 1, "legs.duty must be in (0, 1)"),
        (lg.waves > 0, "legs.waves must be > 0"),
        (lg.stride_max >= lg.stride_min, "legs.stride_max must be >= legs.stride_min"),
        (lg.settle_time > 0, "legs.settle_time must be > 0"),
        (lg.max_swing_rate > 0, "legs.max_swing_rate must be > 0"),
        (0 <= lg.hip_width <= 1.5, "legs.hip_width must be in [0, 1.5]"),
        (lg.knee_out >= 0, "legs.knee_out must be >= 0"),
        (all(0 <= getattr(lg, k) <= math.pi / 2 for k in
             ("ultimate_raise", "ultimate_spread", "antenna_sweep")),
         "legs angles must be in [0, 90] deg"),
        (lg.antenna_rate >= 0, "legs.antenna_rate must be >= 0"),
    ]
    for ok, msg in checks:
        if not ok:
            raise ConfigError(f"{where}: {msg}")
    if not b.width_profile:
        rig = replace(rig, body=replace(b, width_profile=tuple([0.045 * b.length] * b.segments)))
    return rig


def scale_rig(rig: RigConfig, factor: float) -> RigConfig:
    """The same rig uniformly scaled by `factor` (lengths, speeds, navigation sizes)."""
    def sc(obj, names):
        return replace(obj, **{n: (tuple(x * factor for x in getattr(obj, n))
                                   if isinstance(getattr(obj, n), tuple) else getattr(obj, n) * factor)
                               for n in names})
    return replace(
        rig,
        body=sc(rig.body, ["length", "width_profile", "clearance", "leg_stub_length"]),
        locomotion=sc(rig.locomotion, ["max_speed", "acceleration", "stopping_distance"]),
        wander=sc(rig.wander, ["radius"]),
        navigation=sc(rig.navigation, ["radius", "height", "step_height", "cell_size"]),
        legs=sc(rig.legs, list(_LEG_LENGTHS)),
    )
