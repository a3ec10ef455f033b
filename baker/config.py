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
from baker.geometry.transforms import direction_from_angles

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
    rough_speed: float = 0.5        # [(0..1]] speed factor while the body is on or near risers
                                    # (steps and stairs: the legs need the time)


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
    ultimate_warning_raise: float = math.radians(80.0)  # [0..pi/2) [rad] raise at full warning
                                    # (Posture 1: proportional to Trajectory.warning)
    antenna_length: float = 0.03    # [>0] [m] each of the two antenna joints
    antenna_sweep: float = math.radians(25.0)    # [0..pi/2] [rad] side-to-side sweep amplitude
    antenna_rate: float = 1.3       # [>=0] [Hz] sweep frequency
    forcipule_length: float = 0.012  # [>0] [m] each forcipule bone


@dataclass(frozen=True)
class BehaviourConfig:
    """The brain (SEED.md numbers, converted to body lengths in rig files)."""

    decision_interval: float = 5.0    # [>0] [s] how often the d10 is rolled (shade vs wander)
    shade_roll_max: int = 4           # [0..9] a roll of 0..9 at or below this goes to shade
    shade_min_spots: int = 2          # [>=1] known shade spots needed before seeking shade
    shade_memory_interval: float = 5.0  # [>0] [s] at most one new shade spot this often
    shade_spot_spacing: float = 0.25  # [>0] [m] remembered spots are at least this far apart
    shade_sense_radius: float = 0.5   # [>=0] [m] it also notices shade this far around its head
                                      # (light/dark contrast; 0: only where the head is)
    perception_rate: float = 10.0     # [>0] [Hz] shade, prey and obstacle checks
    detection_range: float = 1.0      # [>0] [m] prey closer than this starts a hunt (SEED: 20 units)
    strike_range: float = 0.05        # [>0] [m] head to prey surface distance for a capture
    onslaught_speed: float = 2.0      # [>=1] speed multiplier while hunting (SEED: x2)
    onslaught_turn_rate: float = 2.0  # [>=1] slither turn-rate multiplier (SEED: 4 -> 8)
    strike_time: float = 0.6          # [>0] [s] the bite
    feed_time: float = 8.0            # [>0] [s] holding and eating the prey
    scout_time: float = 0.8           # [>=0] [s] cobra-raised look when prey is first detected
    warning_time: float = 2.0         # [>=0] [s] Posture 1 when its shade is lost


@dataclass(frozen=True)
class CobraConfig:
    """Cobra mode: the front of the body rises along a curve sampled at 1 - i/n (SEED.md)."""

    height: float = 0.04              # [>=0] [m] lift at the head (curve value 1)
    curve: tuple[tuple[float, float], ...] = ((0.0, 0.0), (0.6667, 0.0), (1.0, 1.0))  # [0..1]
    ramp_time: float = 0.4            # [>0] [s] time to rise or settle
    obstacle_probe: float = 0.0625    # [>0] [m] look-ahead for obstacles worth rearing at
    ceiling_margin: float = 0.01      # [>=0] [m] kept free above every raised joint


@dataclass(frozen=True)
class PreyConfig:
    """Prey: a capsule that wanders and flees (a cricket-sized navigation agent)."""

    length: float = 0.06              # [>0] [m] capsule length
    radius: float = 0.012             # [>0] [m] capsule radius
    wander_speed: float = 0.06        # [>0] [m/s]
    flee_speed: float = 0.5           # [>0] [m/s] burst speed while fleeing
    tired_speed: float = 0.1          # [>0] [m/s] after the burst is spent
    stamina: float = 2.5              # [>0] [s] of burst
    recovery: float = 0.25            # [>=0] stamina regained per second when not fleeing
    flee_trigger: float = 0.5         # [>0] [m] a centipede closer than this makes it flee
    acceleration: float = 2.0         # [>0] [m/s^2]
    color: tuple[float, float, float] = (0.32, 0.42, 0.12)  # [0..1] linear RGB


@dataclass(frozen=True)
class RigConfig:
    name: str = "scolopendra"
    source: str = ""
    body: BodyConfig = field(default_factory=BodyConfig)
    colors: ColorsConfig = field(default_factory=ColorsConfig)
    locomotion: LocomotionConfig = field(default_factory=LocomotionConfig)
    wander: WanderConfig = field(default_factory=WanderConfig)
    navigation: NavAgentConfig = field(default_factory=NavAgentConfig)
    behaviour: BehaviourConfig = field(default_factory=BehaviourConfig)
    cobra: CobraConfig = field(default_factory=CobraConfig)
    prey: PreyConfig = field(default_factory=PreyConfig)
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
    behaviour: str = "auto"      # auto | wander | shade | hunt: which drives the brain may use
    cobra: str = "auto"          # auto | always | never
    prey: int = 0                # [0..16] prey capsules
    sun_path: str | None = None  # "AZ,EL;AZ,EL;..." degrees, evenly spaced over the bake
    clips: bool = False          # also write one animation per behaviour segment
    start: tuple[float, float, float] | None = None  # [m, world] creature start (snapped to
                                 # the walkable surface); None: random near the scene centre
    start_heading: tuple[float, float, float] | None = None  # horizontal facing at the start
    prey_positions: tuple[tuple[float, float, float], ...] = ()  # [m, world] explicit prey
                                 # starts (snapped); when given, they replace the `prey` count
                                 # (world positions are moved into the environment's local
                                 # frame by pipeline.in_local_frame)
    nav_cache_dir: Path | None = None  # None: no cache; a folder or a navmesh.cache.NavCache (folder + bound)
    nav_build: str = "auto"      # auto | full | lazy: the whole level at once, or windows
                                 # around where the creatures go (auto: lazy on big levels)

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
    if cfg.behaviour not in ("auto", "wander", "shade", "hunt"):
        raise ConfigError(f"--behaviour must be auto, wander, shade or hunt (got {cfg.behaviour})")
    if cfg.cobra not in ("auto", "always", "never"):
        raise ConfigError(f"--cobra must be auto, always or never (got {cfg.cobra})")
    if cfg.nav_build not in ("auto", "full", "lazy"):
        raise ConfigError(f"--nav-build must be auto, full or lazy (got {cfg.nav_build})")
    if not 0 <= cfg.prey <= 16:
        raise ConfigError(f"--prey must be in 0..16 (got {cfg.prey})")
    if cfg.sun_path is not None:
        parse_sun_path(cfg.sun_path)
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
        if isinstance(v, list) and v and isinstance(v[0], list):
            v = tuple(tuple(float(x) for x in row) for row in v)
        elif isinstance(v, list):
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
                                         "max_swing_rate", "ultimate_warning_raise")}})
    behaviour = _section(BehaviourConfig, data.get("behaviour", {}), f"{path} [behaviour]",
                         {k: length for k in ("shade_spot_spacing", "shade_sense_radius",
                                              "detection_range", "strike_range")})
    cobra = _section(CobraConfig, data.get("cobra", {}), f"{path} [cobra]",
                     {k: length for k in ("height", "obstacle_probe", "ceiling_margin")})
    prey = _section(PreyConfig, data.get("prey", {}), f"{path} [prey]",
                    {k: length for k in ("length", "radius", "wander_speed", "flee_speed",
                                         "tired_speed", "flee_trigger", "acceleration")})
    extra = set(data) - {"name", "body", "colors", "locomotion", "wander", "navigation", "legs",
                         "behaviour", "cobra", "prey"}
    if extra:
        raise ConfigError(f"{path}: unknown section(s) {', '.join(sorted(extra))}")
    rig = RigConfig(name=str(data.get("name", path.stem)), source=str(path), body=body,
                    colors=colors, locomotion=loco, wander=wander, navigation=nav, legs=legs,
                    behaviour=behaviour, cobra=cobra, prey=prey)
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
        (0 < rig.locomotion.rough_speed <= 1, "locomotion.rough_speed must be in (0, 1]"),
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
             ("ultimate_raise", "ultimate_spread", "antenna_sweep", "ultimate_warning_raise")),
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
        behaviour=sc(rig.behaviour, ["shade_spot_spacing", "shade_sense_radius", "detection_range",
                                     "strike_range"]),
        cobra=sc(rig.cobra, ["height", "obstacle_probe", "ceiling_margin"]),
        prey=sc(rig.prey, ["length", "radius", "wander_speed", "flee_speed", "tired_speed",
                           "flee_trigger", "acceleration"]),
    )


#: [Limit] --scale factor range (a 0.25 m rig scaled to 0.25 mm .. 250 m)
SCALE_RANGE = (1e-3, 1e3)


def override_rig(rig: RigConfig, *, scale: float | None = None, agent_radius: float | None = None,
                 agent_height: float | None = None, step_height: float | None = None,
                 max_slope_deg: float | None = None, cell_size: float | None = None) -> RigConfig:
    """The rig with the CLI's overrides applied: first uniformly scaled by `scale` (scale_rig),
    then the navigation agent's fields set (metres; max slope in degrees). None keeps a value.
    Raises ConfigError naming the option for out-of-range values."""
    def num(v, opt):
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{opt} must be a finite number (got {v})")
        return float(v)

    scale = num(scale, "--scale")
    if scale is not None:
        if not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
            raise ConfigError(f"--scale must be in [{SCALE_RANGE[0]:g}, {SCALE_RANGE[1]:g}] "
                              f"(got {scale:g})")
        rig = scale_rig(rig, scale)
    nav = rig.navigation
    kw = {}
    for opt, name, v, ok, rule in (
            ("--agent-radius", "radius", agent_radius, lambda x: x > 0, "> 0"),
            ("--agent-height", "height", agent_height, lambda x: x > 0, "> 0"),
            ("--step-height", "step_height", step_height, lambda x: x >= 0, ">= 0"),
            ("--cell-size", "cell_size", cell_size, lambda x: x > 0, "> 0")):
        v = num(v, opt)
        if v is not None:
            if not ok(v):
                raise ConfigError(f"{opt} must be {rule} metres (got {v:g})")
            kw[name] = v
    slope = num(max_slope_deg, "--max-slope")
    if slope is not None:
        if not 0 < slope < 90:
            raise ConfigError(f"--max-slope must be in (0, 90) degrees (got {slope:g})")
        kw["max_slope"] = math.radians(slope)
    if kw:
        rig = replace(rig, navigation=replace(nav, **kw))
    return rig


def parse_sun_path(text: str, samples_per_key: int = 16) -> np.ndarray:
    """'AZ,EL;AZ,EL;...' in degrees (azimuth from +Z toward +X, elevation above the horizon),
    evenly spaced over the bake -> (K, 3) unit directions toward the sun, densified so that
    interpolating them follows the sky (azimuth and elevation are interpolated, not vectors)."""
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
        return direction_from_angles(ang[:1, 0], ang[:1, 1])
    u = np.linspace(0, len(ang) - 1, (len(ang) - 1) * samples_per_key + 1)
    az = np.interp(u, np.arange(len(ang)), ang[:, 0])
    el = np.interp(u, np.arange(len(ang)), ang[:, 1])
    return direction_from_angles(az, el)
