"""Configuration: frozen dataclasses, one section per stage, loaded from TOML and validated.

Every field documents its [Limit] and [Units] in the units downstream code uses. Rig files and
options are checked against the declarations in baker/schema.py (types, ranges, units in the
user's units: rig lengths in body lengths [BL], angles in degrees); `load_rig_config` converts
them to metres and radians, so everything downstream is in metres and seconds.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from baker import schema
from baker.errors import ConfigError
from baker.geometry.conventions import SIM_RATE_HZ
from baker.geometry.transforms import direction_from_angles

PACKAGE_ROOT = Path(__file__).resolve().parent
REPO_ROOT = PACKAGE_ROOT.parent
DEFAULT_RIG = REPO_ROOT / "rigs" / "scolopendra.toml"
#: the default scene: the bundled showcase, a rainforest floor patch laid out so that the
#: default minute (60 s, 2 prey, a slowly turning sun) meets every behaviour
DEFAULT_ENVIRONMENT = REPO_ROOT / "environments" / "showcase.glb"
#: the other bundled scene: a plainer 22.5 m rainforest floor (boxes, rocks, a log, ferns)
FLOOR_ENVIRONMENT = REPO_ROOT / "environments" / "rainforest_floor.glb"
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
    keep_target: float = 0.0  # [>=0] [s] a target not yet reached is kept this long at most
                            # when the d10 says wander again (0: a new one at every roll, SEED)
    journey_rise: float = 0.25  # [>0] [m] a target this far above or below the head, whose path
                                # runs over a walkable layer this far below it, is on another
                                # floor: walking there is a journey
    journey_time: float = 45.0  # [>=0] [s] a journey is not interrupted by the d10 until it
                                # arrives or has lasted this long (0: no journeys)


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
    sated_time: float = 20.0          # [>=0] [s] after a meal: prey ignored, rolls go to shade


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
    cover_trigger: float = 0.5        # [(0..1]] flee_trigger multiplier while the prey is in
                                      # shade: under cover it keeps still and lets the
                                      # centipede come closer before it bolts
    color: tuple[float, float, float] = (0.32, 0.42, 0.12)  # [0..1] linear RGB


@dataclass(frozen=True)
class RigConfig:
    name: str = "scolopendra"
    #: the rig file, as the outputs record it (source_label)
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
#: the pictures of a bake (export.preview), named after the output path: PATH_map.png, ...
PREVIEW_SUFFIXES = {"map": "_map.png", "sheet": "_sheet.png", "gif": ".gif"}


def frame_count(seconds: float, fps: int) -> int:
    """Frames a bake of `seconds` exports at `fps`: frame 0 to the last frame at `seconds`."""
    return int(round(seconds * fps)) + 1


@dataclass(frozen=True)
class BakeConfig:
    environment: Path = DEFAULT_ENVIRONMENT  # file to load
    seconds: float = 60.0        # [>0, <=3600] [s] simulated duration
    fps: int = 30                # [1..240, divides 240] [Hz] export frame rate
    seed: int = 0                # [>=0] random seed
    rig: RigConfig = field(default_factory=RigConfig)
    out: Path = Path("outputs/centipede")  # output path without extension
    formats: tuple[str, ...] = ("glb", "usd")  # subset of {"glb", "usd", "usda"}
    sun_direction: tuple[float, float, float] | None = None  # toward the sun, fixed; None: the
                                 # file's light (turning about +Y when its extras say so)
    debug_navmesh: bool = False
    up_axis: str | None = None   # y | z: the level file's up axis, when it says otherwise or
                                 # nothing (OBJ, PLY, STL); None: the file's own
    units: str | None = None     # m | cm | mm | km | in | ft: the level file's unit, likewise
    behaviour: str = "auto"      # auto | wander | shade | hunt: which drives the brain may use
    cobra: str = "auto"          # auto | always | never
    prey: int = 2                # [0..16] prey capsules
    creatures: int = 1           # [1..1000] centipedes baked together (run.crowd); 1 is the
                                 # lone creature, byte-identical to a bake without the option
    sun_path: str | None = None  # "AZ,EL;AZ,EL;..." degrees, evenly spaced over the bake
    clips: bool = False          # also write one animation per behaviour segment
    root_motion: str = "world"   # world | root | in-place (see baker.rootmotion)
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
    max_memory_mb: float | None = None  # [>0] [MB] largest navigation build and bake allowed;
                                 # None: half (a build, navmesh.budget) or 80 % (a bake,
                                 # baker.memory) of the memory the process may use
    tolerance: float = 0.001     # [0..0.1] [BL] keyframe reduction: largest world-space
                                 # position error of any joint at any frame, in body lengths
                                 # (0.001 = 0.1% BL); 0 keeps every frame as a key
    rotations: str = "short"     # short | float: reduced rotation keys stored as 16-bit
                                 # normalized integers (checked within the tolerance) or float
    workers: int | None = None   # [1..1024] processes sharing a crowd's per-creature stages
                                 # (solve, metrics, reduce; baker.parallel); None: every CPU
                                 # this process may use. The files do not depend on it
    preview: bool = False        # also draw the bake's map and contact sheet (PNG) from its
                                 # GLB (export.preview; needs "glb" in formats and matplotlib)

    @property
    def sim_rate(self) -> int:
        return SIM_RATE_HZ

    @property
    def n_frames(self) -> int:
        """Frames exported, including frame 0 and the last frame at `seconds`."""
        return frame_count(self.seconds, self.fps)

    def output_paths(self) -> dict[str, Path]:
        ext = {"glb": ".glb", "usd": ".usd", "usda": ".usda"}
        paths = {f: self.out.with_name(self.out.name + ext[f]) for f in self.formats}
        paths["json"] = self.out.with_name(self.out.name + ".json")
        if self.preview:
            for key in ("map", "sheet"):
                paths[key] = self.out.with_name(self.out.name + PREVIEW_SUFFIXES[key])
        return paths


def validate_bake(cfg: BakeConfig) -> BakeConfig:
    """Raise ConfigError for out-of-range run options (declared in schema.Options). Returns cfg,
    with a one-key `sun_path` turned into the fixed sun it is (`sun_direction`)."""
    sun = cfg.sun_direction
    if sun is not None:
        try:
            sun = tuple(float(x) for x in sun)
        except (TypeError, ValueError):
            raise ConfigError("--sun must be three numbers x,y,z", where="command line") from None
    schema.validate_options(seconds=cfg.seconds, fps=cfg.fps, seed=cfg.seed, prey=cfg.prey,
                            creatures=cfg.creatures, workers=cfg.workers, sun=sun,
                            tolerance=cfg.tolerance)
    if SIM_RATE_HZ % cfg.fps:
        divisors = [d for d in range(1, MAX_FPS + 1) if SIM_RATE_HZ % d == 0]
        raise ConfigError(
            f"--fps {cfg.fps} is not supported: it must divide the {SIM_RATE_HZ} Hz simulation "
            f"step (one of {', '.join(map(str, divisors))})", where="--fps")
    bad = set(cfg.formats) - {"glb", "usd", "usda"}
    if bad or not cfg.formats:
        raise ConfigError(f"unknown output format(s): {', '.join(sorted(bad)) or 'none given'}",
                          where="--format")
    if cfg.preview and "glb" not in cfg.formats:
        raise ConfigError("--preview draws the pictures from the GLB: use --format glb or both",
                          where="--preview")
    for opt, value, allowed in (("--behaviour", cfg.behaviour, ("auto", "wander", "shade", "hunt")),
                                ("--cobra", cfg.cobra, ("auto", "always", "never")),
                                ("--nav-build", cfg.nav_build, ("auto", "full", "lazy")),
                                ("--root-motion", cfg.root_motion, ("world", "root", "in-place")),
                                ("--rotations", cfg.rotations, ("short", "float")),
                                ("--up", cfg.up_axis or "y", ("y", "z")),
                                ("--units", cfg.units or "m", ("m", "cm", "mm", "km", "in", "ft"))):
        if value not in allowed:
            raise ConfigError(f"{opt} must be one of {', '.join(allowed)} (got {value})", where=opt)
    for what, p in [("start", cfg.start)] + [("prey position", q) for q in cfg.prey_positions]:
        if p is not None:
            schema.check_point(tuple(float(x) for x in p), what)
    if sun is not None:
        d = np.asarray(sun, dtype=float)
        if np.linalg.norm(d) < 1e-9:
            raise ConfigError("--sun must be a non-zero direction x,y,z toward the sun",
                              where="--sun")
        if d[1] <= 0:
            raise ConfigError("--sun must point upward (y > 0): the sun is above the horizon",
                              where="--sun")
    if cfg.sun_path is not None:
        if sun is not None:
            raise ConfigError("--sun and --sun-path both set the sun: give one (a fixed sun is a "
                              "one-key --sun-path 'AZ,EL')", where="--sun-path")
        keys = parse_sun_path(cfg.sun_path)
        if len(keys) == 1:  # one key: a fixed sun, exported as one
            cfg = replace(cfg, sun_direction=tuple(float(x) for x in keys[0]), sun_path=None)
    return cfg


# --------------------------------------------------------------------------- TOML loading
#: dataclass per rig-file table (the schema's tables are in baker/schema.py)
_SECTION_CLASSES = {"body": BodyConfig, "colors": ColorsConfig, "locomotion": LocomotionConfig,
                    "wander": WanderConfig, "navigation": NavAgentConfig, "legs": LegsConfig,
                    "behaviour": BehaviourConfig, "cobra": CobraConfig, "prey": PreyConfig}
#: rig-file key -> dataclass field, where they differ
_RENAMED = {"navigation": {"agent_radius": "radius", "agent_height": "height"}}


def read_rig_table(path: Path | str) -> dict:
    """The parsed TOML document of a rig file, or ConfigError (missing, unreadable, not TOML)."""
    return read_toml_file(path, "rig", max_bytes=1 << 20)


def read_toml_file(path: Path | str, what: str, max_bytes: int | None = None) -> dict:
    """The parsed TOML document of a `what` file ("rig", "jobs"), or ConfigError: missing, not
    a file, unreadable, over max_bytes, not UTF-8, not TOML, or nested deeper than tomllib
    recurses."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{what} file not found", where=str(path))
    if not path.is_file():
        raise ConfigError(f"{what} path is not a file", where=str(path))
    try:
        with open(path, "rb") as f:     # at most one byte past the bound is read
            raw = f.read() if max_bytes is None else f.read(max_bytes + 1)
            size = len(raw) if max_bytes is None or len(raw) <= max_bytes \
                else os.fstat(f.fileno()).st_size
    except OSError as e:
        raise ConfigError(f"cannot read {what} file: {e.strerror or e}", where=str(path)) from None
    if max_bytes is not None and len(raw) > max_bytes:
        raise ConfigError(f"{what} file is {max(size, len(raw))} bytes; expected at most "
                          f"{max_bytes / (1 << 20):g} MB", where=str(path))
    try:
        return tomllib.loads(raw.decode("utf-8-sig"))    # (a byte order mark is passed over)
    except UnicodeDecodeError as e:
        raise ConfigError(f"{what} file is not UTF-8 text (byte {e.start})",
                          where=str(path)) from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{what} file is not valid TOML: {e}", where=str(path)) from None
    except RecursionError:      # tomllib parses nested arrays and tables recursively
        raise ConfigError(f"{what} file is not valid TOML: its arrays or tables nest too "
                          "deeply", where=str(path)) from None


def load_rig_config(path: Path | str) -> RigConfig:
    """Read a rig TOML file, checked against the declared schema (baker/schema.py). Lengths in
    [BL] become metres; degrees become radians. A missing key keeps the dataclass default."""
    path = Path(path)
    table = schema.validate_rig_table(read_rig_table(path), str(path))
    length = float(table.body.length)
    sections = {}
    for name, cls in _SECTION_CLASSES.items():
        t = getattr(table, name)
        kw = {} if t is None else schema.convert(schema.SECTIONS[name], t, length)
        kw = {_RENAMED.get(name, {}).get(k, k): v for k, v in kw.items()}
        if name == "body":
            kw["length"] = length
        sections[name] = cls(**kw)
    rig = RigConfig(name=table.name or path.stem, source=source_label(path), **sections)
    return validate_rig(rig, str(path))


def source_label(path: Path) -> str:
    """A file's path as the outputs record it: relative to the project's folder when the file
    lies in it (the bundled rigs), so that a bake's files are the same bytes wherever the
    project is checked out (CI runners, a second clone); else as given."""
    try:
        return Path(path).resolve().relative_to(REPO_ROOT).as_posix()
    except (ValueError, OSError):
        return str(path)


#: LegsConfig fields given in body lengths in rig files (metres in LegsConfig)
_LEG_LENGTHS = ("upper_length", "tip_length", "reach", "stride_min", "stride_max", "lift",
                "radius", "ultimate_upper", "ultimate_tip", "antenna_length", "forcipule_length")


def validate_rig(rig: RigConfig, where: str = "rig") -> RigConfig:
    """Consistency of a RigConfig built in code (rig files are checked by the schema first):
    width_profile matches segments. Fills a missing width_profile (0.045 body lengths)."""
    b = rig.body
    if not 3 <= b.segments <= 255:
        raise ConfigError(f"body.segments = {b.segments}: expected an integer in [3, 255]",
                          where=where)
    if b.width_profile and len(b.width_profile) != b.segments:
        raise ConfigError(f"body.width_profile has {len(b.width_profile)} values; expected "
                          f"{b.segments}", where=where)
    if not b.width_profile:
        rig = replace(rig, body=replace(b, width_profile=tuple([0.045 * b.length] * b.segments)))
    return check_sizes(rig, where)


#: [m] the smallest body length and navigation size a bake works with (float32 geometry)
MIN_SIZE = 1e-6


def check_sizes(rig: RigConfig, where: str = "rig") -> RigConfig:
    """ConfigError when the body length or a navigation size (in metres, after the body-length
    conversion and any scaling) is under MIN_SIZE: a rig file's 1e-300 m body or a cell of
    1e-30 body lengths would divide by zero downstream."""
    nav = rig.navigation
    for name, v in (("body.length", rig.body.length), ("navigation.radius", nav.radius),
                    ("navigation.height", nav.height), ("navigation.cell_size", nav.cell_size)):
        if not v >= MIN_SIZE:
            raise ConfigError(f"{name} comes to {v:.3g} m: under the {MIN_SIZE:g} m a bake can "
                              "represent", where=where)
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
        wander=sc(rig.wander, ["radius", "journey_rise"]),
        navigation=sc(rig.navigation, ["radius", "height", "step_height", "cell_size"]),
        legs=sc(rig.legs, list(_LEG_LENGTHS)),
        behaviour=sc(rig.behaviour, ["shade_spot_spacing", "shade_sense_radius", "detection_range",
                                     "strike_range"]),
        cobra=sc(rig.cobra, ["height", "obstacle_probe", "ceiling_margin"]),
        prey=sc(rig.prey, ["length", "radius", "wander_speed", "flee_speed", "tired_speed",
                           "flee_trigger", "acceleration"]),
    )


def override_rig(rig: RigConfig, *, scale: float | None = None, agent_radius: float | None = None,
                 agent_height: float | None = None, step_height: float | None = None,
                 max_slope_deg: float | None = None, cell_size: float | None = None) -> RigConfig:
    """The rig with the CLI's overrides applied: first uniformly scaled by `scale` (scale_rig),
    then the navigation agent's fields set (metres; max slope in degrees). None keeps a value.
    Raises ConfigError naming the option for out-of-range values."""
    opts = schema.validate_options(scale=scale, agent_radius=agent_radius,
                                   agent_height=agent_height, step_height=step_height,
                                   max_slope=max_slope_deg, cell_size=cell_size)
    if opts.scale is not None:
        rig = scale_rig(rig, float(opts.scale))
    nav = rig.navigation
    kw = {name: float(v) for name, v in (("radius", opts.agent_radius),
                                         ("height", opts.agent_height),
                                         ("step_height", opts.step_height),
                                         ("cell_size", opts.cell_size)) if v is not None}
    if opts.max_slope is not None:
        kw["max_slope"] = math.radians(opts.max_slope)
    if kw:
        rig = replace(rig, navigation=replace(nav, **kw))
    return check_sizes(rig, "command line")


def parse_sun_path(text: str, samples_per_key: int = 16) -> np.ndarray:
    """'AZ,EL;AZ,EL;...' in degrees (azimuth from +Z toward +X, elevation above the horizon),
    evenly spaced over the bake -> (K, 3) unit directions toward the sun, densified so that
    interpolating them follows the sky (azimuth and elevation are interpolated, not vectors)."""
    form = "--sun-path must look like 'AZ,EL;AZ,EL' in degrees, e.g. '90,30;270,30'"
    if not isinstance(text, str):
        raise ConfigError(form, where="--sun-path")
    if len(text) > 100_000:     # (it said the form was wrong: 20,000 good keys)
        raise ConfigError(f"--sun-path is {len(text):,} characters long; expected at most "
                          "100,000 (and 1000 keys)", where="--sun-path")
    try:
        pairs = [tuple(float(v) for v in part.split(",")) for part in text.split(";")]
    except ValueError:       # an empty key ('90,30;;270,30', '90,30;') among them
        raise ConfigError(form, where="--sun-path") from None
    if len(pairs) < 1 or any(len(p) != 2 for p in pairs):
        raise ConfigError(form, where="--sun-path")
    if len(pairs) > 1000:
        raise ConfigError(f"--sun-path has {len(pairs)} keys; expected at most 1000",
                          where="--sun-path")
    arr = np.array(pairs)
    if not np.all(np.isfinite(arr)) or np.any(np.abs(arr[:, 0]) > 3600):
        raise ConfigError("--sun-path values must be finite; azimuths in [-3600, 3600] degrees",
                          where="--sun-path")
    ang = np.radians(arr)
    if np.any(ang[:, 1] <= 0) or np.any(ang[:, 1] > math.pi / 2):
        raise ConfigError("--sun-path elevations must be in (0, 90] degrees", where="--sun-path")
    if len(ang) == 1:
        return direction_from_angles(ang[:1, 0], ang[:1, 1])
    u = np.linspace(0, len(ang) - 1, (len(ang) - 1) * samples_per_key + 1)
    az = np.interp(u, np.arange(len(ang)), ang[:, 0])
    el = np.interp(u, np.arange(len(ang)), ang[:, 1])
    return direction_from_angles(az, el)
