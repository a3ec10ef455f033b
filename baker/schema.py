"""Declared schema of rig files and of the CLI's numeric options (pydantic v2).

Each field is declared once, with its type, range, unit and meaning (`key(...)`). The same
declarations validate a rig file (`validate_rig_table`), the options (`validate_options`),
and render the README's tables (`markdown_table`). Values are validated in the units the
user writes: rig lengths in body lengths [BL], angles in degrees; `config.load_rig_config`
converts them (`convert`: BL x body length, deg -> rad).

Errors become one ConfigError naming the file (or option), the key, what was given and what
is expected; an unknown key gets a "did you mean" hint.
"""

from __future__ import annotations

import difflib
import math
from typing import Annotated, Any, get_args, get_origin

from pydantic import AllowInfNan, BaseModel, ConfigDict, Field, Strict, ValidationError
from pydantic.fields import FieldInfo

from baker.errors import ConfigError

# --------------------------------------------------------------------------- declarations


def key(unit: str = "", doc: str = "", *, ge=None, gt=None, le=None, lt=None,
        min_len=None, max_len=None, default=None, **kw) -> Any:
    """A declared field: unit ("BL", "m", "s", "deg", "Hz", "BL/s", ...; "" for none), a
    one-line meaning, and bounds. Optional: a missing key keeps the rig's built-in default."""
    return Field(default=default, ge=ge, gt=gt, le=le, lt=lt, min_length=min_len,
                 max_length=max_len, description=doc, json_schema_extra={"unit": unit}, **kw)


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# strict scalars: "1" is not a number and true is not 1 (a TOML file says what it means)
Num = Annotated[float, Strict(), AllowInfNan(False)]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]
RGB = tuple[Num, Num, Num]


class BodyTable(_Table):
    length: Num = key("m", "head tip to last trunk joint", gt=0, le=1000, default=...)
    segments: Int = key("", "head + trunk segments", ge=3, le=255, default=...)
    width_profile: list[Num] | None = key(
        "BL", "half-width of each segment, head to tail (one value per segment)",
        min_len=3, max_len=255)
    height_ratio: Num | None = key("", "cross-section height / width", gt=0, le=10)
    clearance: Num | None = key("BL", "centre line above the surface below", ge=0, le=10)
    leg_stub_length: Num | None = key("BL", "static leg stubs on the mesh", ge=0, le=10)


class ColorsTable(_Table):
    body: RGB | None = key("linear RGB", "body colour, each channel in [0, 1]")
    legs: RGB | None = key("linear RGB", "leg colour, each channel in [0, 1]")


class LocomotionTable(_Table):
    max_speed: Num | None = key("BL/s", "cruising speed of the navigation agent", gt=0, le=100)
    acceleration: Num | None = key("BL/s^2", "agent acceleration", gt=0, le=1000)
    stopping_distance: Num | None = key("BL", "slow down within this distance of the target",
                                          ge=0, le=100)
    head_turn_rate: Num | None = key("rad/s", "slither angular frequency at max speed",
                                       ge=0, le=100)
    slither_amplitude: Num | None = key("deg", "heading swing at max speed", ge=0, le=90)
    rough_speed: Num | None = key("", "speed factor on or near risers", gt=0, le=1)


class WanderTable(_Table):
    interval: Num | None = key("s", "time between new targets", gt=0, le=3600)
    radius: Num | None = key("BL", "targets drawn within this radius of the head", gt=0, le=1e4)
    keep_target: Num | None = key("s", "a target not yet reached is kept this long at most",
                                  ge=0, le=3600)
    journey_rise: Num | None = key("BL", "a target this far above or below the head, its path "
                                   "over a layer this far below, is on another floor (a journey)",
                                   gt=0, le=1e4)
    journey_time: Num | None = key("s", "a journey goes on through the d10's rolls this long "
                                   "at most", ge=0, le=3600)


class NavigationTable(_Table):
    agent_radius: Num | None = key("BL", "navigation agent radius (erosion)", gt=0, le=100)
    agent_height: Num | None = key("BL", "free space needed above a walkable sample",
                                     gt=0, le=100)
    step_height: Num | None = key("BL", "largest riser climbed", ge=0, le=100)
    max_slope: Num | None = key("deg", "steepest walkable slope", gt=0, lt=90)
    cell_size: Num | None = key("BL", "navigation grid cell size", gt=0, le=100)


class LegsTable(_Table):
    enabled: Bool | None = key("", "false: spine only, static leg stubs")
    upper_length: Num | None = key("BL", "hip -> knee bone", gt=0, le=10)
    tip_length: Num | None = key("BL", "knee -> foot bone", gt=0, le=10)
    hip_width: Num | None = key("", "hip offset as a fraction of the half-width", ge=0, le=1.5)
    reach: Num | None = key("BL", "neutral foot distance from the centre line", gt=0, le=10)
    knee_out: Num | None = key("", "knee pole = up + knee_out * outward", ge=0, le=100)
    duty: Num | None = key("", "fraction of a step cycle a foot is planted", gt=0, lt=1)
    waves: Num | None = key("", "gait waves along the body", gt=0, le=100)
    stride_min: Num | None = key("BL", "body travel per step cycle when slow", gt=0, le=10)
    stride_max: Num | None = key("BL", "body travel per step cycle at max speed (>= stride_min)",
                                   gt=0, le=10)
    lift: Num | None = key("BL", "swing height", ge=0, le=10)
    settle_time: Num | None = key("s", "longest swing", gt=0, le=60)
    max_swing_rate: Num | None = key("deg/s", "fastest leg sweep", gt=0, le=1e5)
    radius: Num | None = key("BL", "leg tube radius at the hip", gt=0, le=1)
    ultimate_upper: Num | None = key("BL", "ultimate leg upper bone", gt=0, le=10)
    ultimate_tip: Num | None = key("BL", "ultimate leg tip bone", gt=0, le=10)
    ultimate_raise: Num | None = key("deg", "ultimate legs' pitch above the body axis",
                                       ge=0, le=90)
    ultimate_spread: Num | None = key("deg", "ultimate legs' spread from the body axis",
                                        ge=0, le=90)
    ultimate_warning_raise: Num | None = key("deg", "raise in the warning posture", ge=0, lt=90)
    antenna_length: Num | None = key("BL", "each of the two antenna joints", gt=0, le=10)
    antenna_sweep: Num | None = key("deg", "antenna sweep amplitude", ge=0, le=90)
    antenna_rate: Num | None = key("Hz", "antenna sweep frequency", ge=0, le=100)
    forcipule_length: Num | None = key("BL", "each forcipule bone", gt=0, le=10)


class BehaviourTable(_Table):
    decision_interval: Num | None = key("s", "how often the d10 is rolled", gt=0, le=3600)
    shade_roll_max: Int | None = key("", "rolls 0..9 at or below this go to shade", ge=0, le=9)
    shade_min_spots: Int | None = key("", "known shade spots needed before seeking shade",
                                      ge=1, le=1000)
    shade_memory_interval: Num | None = key("s", "at most one new shade spot this often",
                                              gt=0, le=3600)
    shade_spot_spacing: Num | None = key("BL", "remembered spots at least this far apart",
                                           gt=0, le=1e4)
    shade_sense_radius: Num | None = key("BL", "shade noticed this far around the head",
                                           ge=0, le=1e4)
    perception_rate: Num | None = key("Hz", "shade, prey and obstacle checks", gt=0, le=240)
    detection_range: Num | None = key("BL", "prey closer than this starts a hunt", gt=0, le=1e4)
    strike_range: Num | None = key("BL", "head to prey surface for a capture", gt=0, le=100)
    onslaught_speed: Num | None = key("", "speed multiplier while hunting", ge=1, le=100)
    onslaught_turn_rate: Num | None = key("", "slither turn-rate multiplier while hunting",
                                            ge=1, le=100)
    strike_time: Num | None = key("s", "the bite", gt=0, le=3600)
    feed_time: Num | None = key("s", "holding and eating the prey", gt=0, le=3600)
    scout_time: Num | None = key("s", "cobra look when prey is first detected", ge=0, le=3600)
    warning_time: Num | None = key("s", "Posture 1 when its shade is lost", ge=0, le=3600)
    sated_time: Num | None = key("s", "after a meal: prey ignored, every roll goes to shade",
                                 ge=0, le=3600)


class CobraTable(_Table):
    height: Num | None = key("BL", "lift at the head", ge=0, le=10)
    curve: list[tuple[Num, Num]] | None = key(
        "", "[[u, lift], ...] points in [0, 1], u increasing", min_len=2, max_len=256)
    ramp_time: Num | None = key("s", "time to rise or settle", gt=0, le=60)
    obstacle_probe: Num | None = key("BL", "look-ahead for obstacles worth rearing at",
                                       gt=0, le=100)
    ceiling_margin: Num | None = key("BL", "kept free above every raised joint", ge=0, le=10)


class PreyTable(_Table):
    length: Num | None = key("BL", "capsule length", gt=0, le=100)
    radius: Num | None = key("BL", "capsule radius", gt=0, le=100)
    wander_speed: Num | None = key("BL/s", "speed while wandering", gt=0, le=1000)
    flee_speed: Num | None = key("BL/s", "burst speed while fleeing", gt=0, le=1000)
    tired_speed: Num | None = key("BL/s", "after the burst is spent", gt=0, le=1000)
    stamina: Num | None = key("s", "of burst", gt=0, le=3600)
    recovery: Num | None = key("1/s", "stamina regained per second when not fleeing",
                                 ge=0, le=1000)
    flee_trigger: Num | None = key("BL", "a centipede closer than this makes it flee",
                                     gt=0, le=1e4)
    acceleration: Num | None = key("BL/s^2", "capsule acceleration", gt=0, le=1e4)
    cover_trigger: Num | None = key("", "flee_trigger multiplier while the prey is in shade "
                                    "(it keeps still under cover)", gt=0, le=1)
    color: RGB | None = key("linear RGB", "capsule colour, each channel in [0, 1]")


class RigFile(_Table):
    """A rig file's top level: a name and one table per section."""

    name: Str | None = key("", "rig name (defaults to the file name)", min_len=1, max_len=63)
    body: BodyTable = key("", "required", default=...)
    colors: ColorsTable | None = key()
    locomotion: LocomotionTable | None = key()
    wander: WanderTable | None = key()
    navigation: NavigationTable | None = key()
    legs: LegsTable | None = key()
    behaviour: BehaviourTable | None = key()
    cobra: CobraTable | None = key()
    prey: PreyTable | None = key()




class Options(_Table):
    """The CLI's numeric options (`baker bake`, `baker navmesh`). Keys are option names."""

    seconds: Num | None = key("s", "simulated duration", gt=0, le=3600)
    fps: Int | None = key("Hz", "export frame rate; divides the 240 Hz simulation rate",
                          ge=1, le=240)
    seed: Int | None = key("", "random seed", ge=0, le=2**63 - 1)
    prey: Int | None = key("", "prey capsules", ge=0, le=16)
    creatures: Int | None = key("", "centipedes baked together (a crowd)", ge=1, le=1000)
    workers: Int | None = key("", "processes sharing a crowd's per-creature stages", ge=1,
                              le=1024)
    scale: Num | None = key("", "uniform rig scale", ge=1e-3, le=1e3)
    agent_radius: Num | None = key("m", "navigation agent radius", gt=0, le=1e3)
    agent_height: Num | None = key("m", "free height above walkable surface", gt=0, le=1e3)
    step_height: Num | None = key("m", "largest riser climbed", ge=0, le=1e3)
    max_slope: Num | None = key("deg", "steepest walkable slope", gt=0, lt=90)
    cell_size: Num | None = key("m", "navigation grid cell size", gt=0, le=1e3)
    max_memory: Num | None = key("MB", "largest navigation build and bake allowed", gt=0, le=1e9)
    cache_max: Num | None = key("MB", "bound of the navigation cache folder", ge=0, le=1e9)
    tolerance: Num | None = key("BL", "keyframe reduction: largest joint position error "
                                "(0.001 = 0.1% of the body length; 0 keeps every key)",
                                ge=0, le=0.1)
    sun: tuple[Num, Num, Num] | None = key(
        "", "direction toward the sun, y > 0, each component within +-1e6")
    coordinate: tuple[Num, Num, Num] | None = key(
        "m", "a point x,y,z (`navmesh --from`, `--to`), each within +-1e9 m")


_COLOR_KEYS = {"body", "legs", "color"}


# --------------------------------------------------------------------------- checks
def _base(t):
    """The declared type without Optional and Annotated wrappers."""
    while True:
        if get_origin(t) is Annotated:
            t = get_args(t)[0]
            continue
        args = [a for a in get_args(t) if a is not type(None)]
        if get_origin(t) not in (list, tuple) and len(args) == 1 and len(get_args(t)) == 2:
            t = args[0]
            continue
        return t


def _model_of(f: FieldInfo):
    t = _base(f.annotation)
    return t if isinstance(t, type) and issubclass(t, BaseModel) else None


#: rig-file section name -> its table model
SECTIONS = {n: _model_of(f) for n, f in RigFile.model_fields.items() if n != "name"}


def _expected(info: FieldInfo) -> str:
    """'a number in (0, 100] BL' from a declaration."""
    t = _base(info.annotation)
    name = getattr(t, "__name__", str(t))
    origin = get_origin(t)
    if t is bool:
        kind = "true or false"
    elif t is int:
        kind = "an integer"
    elif t is float:
        kind = "a finite number"
    elif t is str:
        kind = "a string"
    elif origin is list and _base(get_args(t)[0]) is float:
        kind = "an array of finite numbers"
    elif origin is list:
        kind = "an array of [u, lift] pairs"
    elif origin is tuple:
        kind = f"an array of {len(get_args(t))} finite numbers"
    elif isinstance(t, type) and issubclass(t, BaseModel):
        kind = "a table"
    else:  # pragma: no cover - every declared type is handled above
        kind = name
    lo = hi = None
    lo_incl = hi_incl = True
    n_lo = n_hi = None
    for m in info.metadata:
        for attr, incl, side in (("ge", True, "lo"), ("gt", False, "lo"),
                                 ("le", True, "hi"), ("lt", False, "hi")):
            v = getattr(m, attr, None)
            if v is not None:
                if side == "lo":
                    lo, lo_incl = v, incl
                else:
                    hi, hi_incl = v, incl
        if getattr(m, "min_length", None) is not None:
            n_lo = m.min_length
        if getattr(m, "max_length", None) is not None:
            n_hi = m.max_length
    rng = ""
    if lo is not None or hi is not None:
        def num(x):
            return str(x) if isinstance(x, int) else f"{x:g}"
        a = ("[" if lo_incl else "(") + (num(lo) if lo is not None else "-inf")
        b = (num(hi) if hi is not None else "inf") + ("]" if hi_incl else ")")
        rng = f" in {a}, {b}"
    if n_lo is not None or n_hi is not None:
        rng += f" of {n_lo}..{n_hi} items"
    unit = (info.json_schema_extra or {}).get("unit", "")
    if unit == "linear RGB":
        rng = " each in [0, 1]"
    return kind + rng + (f" [{unit}]" if unit and unit != "linear RGB" else "")


def _field_info(model: type[BaseModel], loc: tuple) -> FieldInfo | None:
    info = None
    for part in loc:
        if not isinstance(part, str):
            break
        f = model.model_fields.get(part)
        if f is None:
            return info
        info = f
        if _model_of(f) is not None:
            model = _model_of(f)
    return info


def _show(v) -> str:
    if isinstance(v, str):
        return f'"{v}"' if len(v) < 40 else f'"{v[:37]}..."'
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        s = repr(v)
        return s if len(s) < 60 else s[:57] + "...]"
    return repr(v)


def _dotted(loc: tuple) -> str:
    out = ""
    for p in loc:
        out += f"[{p}]" if isinstance(p, int) else ("." if out else "") + str(p)
    return out


def _did_you_mean(model: type[BaseModel], loc: tuple) -> str:
    parent = model
    for part in loc[:-1]:
        f = parent.model_fields.get(part) if isinstance(part, str) else None
        if f is None or _model_of(f) is None:
            break
        parent = _model_of(f)
    close = difflib.get_close_matches(str(loc[-1]), list(parent.model_fields), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _lookup(data, loc):
    for p in loc:
        try:
            data = data[p]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _message(model: type[BaseModel], err: dict, label, data=None) -> str:
    loc = tuple(err["loc"])
    typ = err["type"]
    if typ == "extra_forbidden":
        what = "section" if len(loc) == 1 and model is RigFile else "key"
        return f"unknown {what} '{_dotted(loc)}'{_did_you_mean(model, loc)}"
    # a tuple/list item: report against the field, with the item's index
    field_loc = tuple(p for p in loc if isinstance(p, str))
    info = _field_info(model, field_loc)
    name = label(field_loc)
    got = err.get("input")
    if typ == "missing" and field_loc == loc:
        return f"{name} is missing; expected {_expected(info) if info else 'a value'}"
    if info is None:
        return f"{name}: {err['msg']}"
    expected = _expected(info)
    if field_loc != loc:  # an item of an array: show the whole value
        got = _lookup(data, field_loc) if data is not None else got
    if isinstance(got, dict) and typ in ("model_type", "dict_type") or (
            info is not None and expected == "a table"):
        return f"{name} must be a table (got {_show(got)})"
    return f"{name} = {_show(got)}: expected {expected}"


def _raise(model, exc: ValidationError, where: str, label, data=None) -> None:
    errs = exc.errors(include_url=False)
    # the first error in file order; a unknown key first (often the cause of the others)
    errs.sort(key=lambda e: e["type"] != "extra_forbidden")
    raise ConfigError(_message(model, errs[0], label, data), where=where) from None


def validate_rig_table(data: dict, where: str) -> RigFile:
    """A parsed rig TOML document -> RigFile, or ConfigError naming the file and key."""
    if not data:
        raise ConfigError("rig file is empty; expected at least a [body] table with length "
                          "and segments", where=where)
    try:
        rig = RigFile.model_validate(data)
    except ValidationError as e:
        _raise(RigFile, e, where, lambda loc: _dotted(loc) if loc else "the rig file", data)
    _cross_checks(rig, where)
    return rig


def _cross_checks(rig: RigFile, where: str) -> None:
    b = rig.body
    if b.width_profile is not None:
        if len(b.width_profile) != b.segments:
            raise ConfigError(f"body.width_profile has {len(b.width_profile)} values; expected "
                              f"{b.segments} (one per segment, body.segments)", where=where)
        if any(not (0 < w <= 10) for w in b.width_profile):
            raise ConfigError("body.width_profile: expected values in (0, 10] [BL]", where=where)
    for sec in ("colors", "prey"):
        t = getattr(rig, sec)
        if t is None:
            continue
        for k in _COLOR_KEYS:
            c = getattr(t, k, None)
            if c is not None and any(not (0 <= x <= 1) for x in c):
                raise ConfigError(f"{sec}.{k} = {list(c)}: expected 3 numbers each in [0, 1] "
                                  "(linear RGB)", where=where)
    lg = rig.legs
    if lg is not None and lg.stride_min is not None and lg.stride_max is not None \
            and lg.stride_max < lg.stride_min:
        raise ConfigError(f"legs.stride_max = {lg.stride_max:g}: expected >= legs.stride_min "
                          f"({lg.stride_min:g})", where=where)
    cb = rig.cobra
    if cb is not None and cb.curve is not None:
        u = [p[0] for p in cb.curve]
        if any(not (0 <= x <= 1) for p in cb.curve for x in p):
            raise ConfigError("cobra.curve: expected [u, lift] points with both in [0, 1]",
                              where=where)
        if any(b2 <= a for a, b2 in zip(u, u[1:])):
            raise ConfigError("cobra.curve: expected u (the first value of each point) to "
                              "increase", where=where)


def validate_options(where: str = "command line", **values) -> Options:
    """Check option values (None = not given) -> Options, or ConfigError naming the option."""
    given = {k: v for k, v in values.items() if v is not None}
    try:
        opts = Options.model_validate(given)
    except ValidationError as e:
        def label(loc):
            return "--" + str(loc[0]).replace("_", "-") if loc else "options"
        _raise(Options, e, where, label, given)
    if opts.sun is not None and any(abs(x) > 1e6 for x in opts.sun):
        raise ConfigError(f"--sun = {','.join(f'{x:g}' for x in opts.sun)}: expected "
                          "components with |value| <= 1e6", where=where)
    if opts.coordinate is not None and any(abs(x) > 1e9 for x in opts.coordinate):
        raise ConfigError("coordinates out of range: expected |value| <= 1e9 m", where=where)
    return opts


def check_point(value: tuple | None, option: str) -> None:
    """A point option (--from, --to, a start): three finite numbers within 1e9 m
    (Options.coordinate)."""
    if value is None:
        return
    try:
        validate_options(coordinate=tuple(value))
    except ConfigError:
        raise ConfigError(f"{option} = {','.join(f'{x:g}' for x in value)}: expected three "
                          "finite numbers each within +-1e9 [m]", where="command line") from None


# --------------------------------------------------------------------------- units
def convert(section: type[BaseModel], table: BaseModel, body_length: float) -> dict:
    """The keys given in `table`, converted to the dataclasses' units: [BL] x body_length
    (also BL/s, BL/s^2), [deg] (also deg/s) -> radians. Lists become tuples."""
    out = {}
    for name in table.model_fields_set:
        v = getattr(table, name)
        if v is None:
            continue
        unit = (section.model_fields[name].json_schema_extra or {}).get("unit", "")
        k = body_length if unit.startswith("BL") else (math.pi / 180.0 if unit.startswith("deg")
                                                      else 1.0)
        if isinstance(v, (list, tuple)):
            v = tuple(tuple(float(x) for x in r) if isinstance(r, (list, tuple)) else float(r) * k
                      for r in v)
        elif isinstance(v, float) or (isinstance(v, int) and not isinstance(v, bool) and k != 1.0):
            v = float(v) * k
        out[name] = v
    return out


# --------------------------------------------------------------------------- docs
def markdown_table(model: type[BaseModel], prefix: str = "") -> str:
    """A Markdown table of `model`'s declared keys: key | expected | meaning."""
    rows = ["| key | expected | meaning |", "|---|---|---|"]
    for name, info in model.model_fields.items():
        rows.append(f"| `{prefix}{name}` | {_expected(info)} | {info.description or ''} |")
    return "\n".join(rows)


def rig_keys_markdown() -> str:
    """Every rig-file table's keys, one Markdown table per section (for the README)."""
    parts = []
    for sec, model in SECTIONS.items():
        parts.append(f"`[{sec}]`\n\n" + markdown_table(model))
    return "\n\n".join(parts)
