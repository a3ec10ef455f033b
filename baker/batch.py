"""Batch bakes: a jobs file -> one bake per job on a local process pool or a Dask scheduler ->
DIR/manifest.json. Read `run` first; it is written as steps.

    Step 1  read and check the whole jobs file            load_plan -> Plan (a BakeConfig per job)
    Step 2  key every job, skip those up to date          job_key, Manifest.up_to_date
    Step 3  build each navigation surface once            NavTask, through the navigation cache
    Step 4  bake the other jobs, each isolated            JobTask on LocalPool or DaskPool
    Step 5  record every outcome as it comes              Manifest.write (atomic, after each job)

The jobs file (TOML):

    [defaults]                 # any `bake` option, under its name with underscores
    seconds = 2
    format = "glb"

    [[job]]
    name = "forest"            # output names: DIR/<name>.glb, .usd, .json
    environment = "levels/forest.glb"     # relative to the jobs file
    seed = 3

    [[job]]
    name = "sweep"             # a matrix: one job per combination, named sweep-cave-seed0-hunt...
    [job.matrix]
    environment = ["levels/cave.obj", "levels/forest.glb"]
    seed = [0, 1, 2]
    behaviour = ["wander", "hunt"]

A name may instead be a template of the job's keys, `"{environment}-s{seed}"` (an environment
or rig stands for its file name without extension). Every error of the file is found before any
work starts and reported together (JobsFileError), each naming the job and the key.

A job's key is the sha256 of everything its outputs depend on: the environment file's bytes
(and those of the files beside it that a .gltf, .obj or .usda names), the resolved rig, the
options and the baker version. A job whose manifest entry has the same key and whose outputs
are still there, unchanged, is skipped. The manifest is rewritten atomically after each job, so
a killed batch loses at most its running jobs; run again, it does only what is missing.

Failures stay with their job: a bad file, an exception in the bake or a timeout (--job-timeout:
checked at every stage and every 10 simulated seconds inside the bake; a job still running a
grace period later is stopped from outside) fails that job and the others go on. A worker that
dies (a crash, a lost Dask worker) is an infrastructure failure: its task runs again, up to
--retries times.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import logging
import os
import re
import socket
import string
import sys
import threading
import time
import traceback
import uuid
from collections import deque
from contextlib import contextmanager, suppress
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path

import baker
from baker import signals
from baker.atomic import (atomic_write_bytes, check_not_inputs, check_outputs,
                          check_writable)
from baker.config import (DEFAULT_ENVIRONMENT, DEFAULT_RIG, BakeConfig, load_rig_config,
                          override_rig, read_toml_file, validate_bake)
from baker.errors import (BakerError, ConfigError, JobsFileError, format_error,
                          short_path)

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
#: Held (flock) for the whole run, so two batches never write into one folder at once.
LOCK_FILE = ".baker-batch.lock"
#: the largest jobs file read (a matrix of MAX_JOBS jobs fits in a few kB)
MAX_JOBS_FILE_BYTES = 16 << 20
#: the largest previous manifest read (MAX_JOBS entries of a few kB each); a larger file is
#: not one a batch wrote, and its jobs are baked again
MAX_MANIFEST_BYTES = 256 << 20
#: The most jobs one file may expand to, and the most errors listed.
MAX_JOBS = 10_000
MAX_ERRORS = 100

#: Job keys: `bake`'s options under their names with underscores -> what a value must be: a
#: kind ("path", "number", "int", "bool", "str", "vec3") or the allowed strings.
#: tests/unit/test_batch_jobs.py checks this against the `bake` command's options.
OPTIONS: dict[str, object] = {
    "environment": "path", "seconds": "number", "fps": "int", "seed": "int", "rig": "path",
    "format": ("glb", "usd", "both"), "usda": "bool", "sun": "vec3", "debug_navmesh": "bool",
    "nav_build": ("auto", "full", "lazy"), "behaviour": ("auto", "wander", "shade", "hunt"),
    "prey": "int", "creatures": "int", "cobra": ("auto", "always", "never"), "sun_path": "str", "clips": "bool",
    "root_motion": ("world", "root", "in-place"), "max_memory": "number", "scale": "number",
    "agent_radius": "number", "agent_height": "number", "step_height": "number",
    "max_slope": "number", "cell_size": "number", "tolerance": "number",
    "rotations": ("short", "float"), "preview": "bool", "up": ("y", "z"),
    "units": ("m", "cm", "mm", "km", "in", "ft"),
}
#: `bake` options that are one per batch: `baker batch`'s own options set them.
BATCH_LEVEL = {"out": "--out", "cache_dir": "--cache-dir", "no_cache": "--cache-dir",
               "cache_max": "--cache-max", "workers": "--workers"}
#: job key -> BakeConfig field, where the option is copied as it is
_FIELDS = {"seconds": "seconds", "fps": "fps", "seed": "seed", "prey": "prey",
           "creatures": "creatures",
           "behaviour": "behaviour", "cobra": "cobra", "sun_path": "sun_path", "clips": "clips",
           "root_motion": "root_motion", "nav_build": "nav_build",
           "debug_navmesh": "debug_navmesh", "max_memory": "max_memory_mb",
           "tolerance": "tolerance", "rotations": "rotations", "preview": "preview",
           "up": "up_axis", "units": "units"}
#: keys checked by trying them alone on a default BakeConfig (validate_bake's own rules)
_BAKE_RULES = {"fps": "fps", "sun": "sun_direction", "sun_path": "sun_path", "tolerance": "tolerance"}
_RIG_OVERRIDES = ("scale", "agent_radius", "agent_height", "step_height", "max_slope",
                  "cell_size")
#: BakeConfig fields that change no output byte (where files go, the cache, a memory refusal,
#: the processes a crowd's bake shares its work among)
_NOT_IN_KEY = {"environment", "rig", "out", "nav_cache_dir", "max_memory_mb", "workers"}
#: text formats whose files may name other files beside them (hashed into the key too)
_NAMES_FILES = {".gltf", ".obj", ".usda", ".mtl"}
_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")
_DONE = ("baked", "skipped")


# =========================================================================== step 1: jobs file
@dataclass(frozen=True)
class Job:
    """One bake of the batch.

    name  : output file stem (DIR/<name>.*), unique
    cfg   : the checked BakeConfig (absolute paths; out = DIR/<name>)
    key   : hex sha256 of what the outputs depend on (job_key)
    nav   : index of its navigation group in Plan.nav_groups
    """

    name: str
    cfg: BakeConfig
    key: str
    nav: int


@dataclass(frozen=True)
class Plan:
    """A checked jobs file: its jobs in file order, and one representative BakeConfig per
    navigation group (jobs that share an environment, agent and build mode)."""

    jobs_file: Path
    out: Path
    jobs: tuple[Job, ...]
    nav_groups: tuple[BakeConfig, ...]


class _Problems:
    """Every error of a jobs file, each naming the job and the key."""

    def __init__(self):
        self.items: list[str] = []

    def add(self, where: str, text: str) -> None:
        self.items.append(f"{where}: {text}")

    def raise_if_any(self, path: Path) -> None:
        n = len(self.items)
        if not n:
            return
        shown = [f"({i}) {t}" for i, t in enumerate(self.items[:MAX_ERRORS], 1)]
        more = f"; and {n - MAX_ERRORS} more" if n > MAX_ERRORS else ""
        head = "1 error" if n == 1 else f"{n} errors"
        raise JobsFileError(f"jobs file has {head}: " + "; ".join(shown) + more, where=str(path))


def _did_you_mean(key: str, choices) -> str:
    import difflib

    close = difflib.get_close_matches(str(key), list(choices), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "a table"
    s = json.dumps(v) if isinstance(v, (str, list)) else repr(v)
    return s if len(s) < 60 else s[:57] + "..."


def _check_value(key: str, value, base: Path):
    """(value as the bake takes it, None) or (None, what is wrong) for one job key."""
    kind = OPTIONS[key]
    bad = f"{key} = {_show(value)}: expected "
    if isinstance(kind, tuple):
        return (value, None) if isinstance(value, str) and value in kind \
            else (None, bad + f"one of {', '.join(kind)}")
    if kind == "bool":
        return (value, None) if isinstance(value, bool) else (None, bad + "true or false")
    if kind == "str":
        return _check_rules(key, value) if isinstance(value, str) else (None, bad + "a string")
    if kind == "path":
        return _check_path(key, value, base)
    if kind == "vec3":
        if isinstance(value, str):
            try:
                value = [float(x) for x in value.replace(" ", "").split(",")]
            except ValueError:
                return None, bad + "three numbers x,y,z"
        if not isinstance(value, list) or len(value) != 3:
            return None, bad + "three numbers [x, y, z]"
        value = tuple(float(x) if isinstance(x, int) and not isinstance(x, bool) else x
                      for x in value)
    elif kind == "number" and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)            # TOML's `seconds = 2` is a number too
    return _check_rules(key, value)


def _check_rules(key: str, value):
    """A value against its declared range (schema.Options), then validate_bake's rules."""
    from baker.schema import Options, validate_options

    try:
        if key in Options.model_fields:
            validate_options(**{key: value})
        if key in _BAKE_RULES:
            validate_bake(replace(BakeConfig(), **{_BAKE_RULES[key]: value}))
    except ConfigError as e:
        return None, _as_key(e.what, key)
    return value, None


def _as_key(text: str, key: str) -> str:
    """A CLI message ("--max-slope = 95: ...") in terms of the job key ("max_slope = 95: ...")."""
    return text.replace("--" + key.replace("_", "-"), key)


def absolute_path(value, base: Path | None = None) -> Path:
    """`value` as an absolute path: '~' expanded, relative to `base` (else the working folder),
    symbolic links resolved. ValueError naming what is wrong for a path no file can have: a NUL
    character, a '~user' with no home folder, a loop of symbolic links (pathlib raises
    RuntimeError for the last two, which read as a bug)."""
    text = os.fspath(value)
    if "\0" in text:
        raise ValueError("a path cannot hold a NUL character")
    p = Path(text)
    try:
        p = p.expanduser()
    except RuntimeError:
        raise ValueError(f"'{text.split(os.sep)[0][:60]}' names no user's home folder") from None
    try:
        return (p if p.is_absolute() or base is None else base / p).resolve()
    except (RuntimeError, OSError) as e:      # a symbolic link loop (OSError ELOOP in 3.13)
        raise ValueError(f"cannot resolve the path: {e}") from None


def _check_path(key: str, value, base: Path):
    if not isinstance(value, str) or not value.strip():
        return None, f"{key} = {_show(value)}: expected a file path"
    try:
        p = absolute_path(value, base)
    except ValueError as e:
        return None, f"{key} = {_show(value)}: {e}"
    if not p.is_file():
        return None, f"{key}: {'not a file' if p.exists() else 'file not found'}: {p}"
    if key == "rig":
        try:
            _rig_config(p)
        except ConfigError as e:
            return None, f"rig: {e}"
    if key == "environment":
        from baker.environment.load import SUPPORTED_EXTS

        if p.suffix.lower() not in SUPPORTED_EXTS:
            return None, (f"environment: unsupported format '{p.suffix or '(none)'}' ({p.name}); "
                          f"expected one of {', '.join(sorted(SUPPORTED_EXTS))}")
    return p, None


def _check_table(table, label: str, base: Path, problems: _Problems, *, job: bool):
    """(options, matrix) of a [defaults] table or a [[job]] entry, bad values left out."""
    opts, matrix = {}, {}
    if not isinstance(table, dict):
        problems.add(label, f"expected a table (got {_show(table)})")
        return opts, matrix
    allowed = set(OPTIONS) | ({"name", "matrix"} if job else set())
    for key, value in table.items():
        if key in BATCH_LEVEL:
            problems.add(label, f"{key} is one per batch: use `baker batch {BATCH_LEVEL[key]}`")
        elif key not in allowed:
            extra = "; name and matrix belong in a [[job]]" if key in ("name", "matrix") else ""
            problems.add(label, f"unknown key '{key}'{_did_you_mean(key, allowed)}{extra}")
        elif key == "name":
            if not isinstance(value, str):
                problems.add(label, f"name = {_show(value)}: expected a string")
        elif key == "matrix":
            matrix = _check_matrix(value, label, base, problems)
        else:
            v, err = _check_value(key, value, base)
            if err:
                problems.add(label, err)
            else:
                opts[key] = v
    return opts, matrix


def _check_matrix(value, label: str, base: Path, problems: _Problems) -> dict:
    if not isinstance(value, dict) or not value:
        problems.add(label, "matrix must be a table of lists, e.g. seed = [0, 1, 2]")
        return {}
    out = {}
    for key, items in value.items():
        if key not in OPTIONS:
            problems.add(label, f"unknown key 'matrix.{key}'{_did_you_mean(key, OPTIONS)}")
            continue
        if not isinstance(items, list) or not items:
            problems.add(label, f"matrix.{key} = {_show(items)}: expected a non-empty list")
            continue
        good = []
        for i, item in enumerate(items):
            v, err = _check_value(key, item, base)
            if err:
                problems.add(label, f"matrix.{key}[{i}]: {err}")
            else:
                good.append(v)
        if len(good) == len(items):
            out[key] = good
    return out


def _display(v) -> str:
    """A value as it appears in a job's name: a file's stem, a number, a word."""
    if isinstance(v, Path):
        return v.stem
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return f"{v:g}"
    if isinstance(v, tuple):
        return "_".join(f"{x:g}" for x in v)
    return str(v)


def _job_name(entry: dict, index: int, combo: dict, opts: dict) -> str:
    """The name given, filled in when it is a template ("{environment}-s{seed}"), else followed
    by the matrix values ("sweep-forest-seed0-hunt": numbers after their key); an entry without
    a name is "job<index>"."""
    name = entry.get("name") if isinstance(entry.get("name"), str) else f"job{index}"
    if "{" in name:
        values = {k: _display(v) for k, v in opts.items()}
        values.setdefault("environment", DEFAULT_ENVIRONMENT.stem)
        out = []
        for text, field_name, spec, conversion in string.Formatter().parse(name):
            out.append(text)
            if field_name is None:
                continue
            if not field_name.isidentifier() or spec or conversion:
                # no format specs, conversions, attributes or indices: "{seed:>3000000000}"
                # would pad a name to 3 GB
                raise ValueError(f"'{{{field_name}{'!' + conversion if conversion else ''}"
                                 f"{':' + spec if spec else ''}}}' is not a plain {{key}} field")
            out.append(values[field_name])
        return "".join(out)
    parts = [(k if isinstance(v, (int, float, tuple)) and not isinstance(v, bool) else "")
             + _display(v) for k, v in combo.items()]
    return "-".join([name] + parts)


def _sanitize(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def job_config(opts: dict, out: Path, cache=None) -> BakeConfig:
    """The BakeConfig of a job's checked options, built as `baker bake` builds it from the
    same options. ConfigError (one line) when they do not fit together."""
    usd = "usda" if opts.get("usda") else "usd"
    formats = {"glb": ("glb",), "usd": (usd,), "both": ("glb", usd)}[opts.get("format", "both")]
    overrides = {("max_slope_deg" if k == "max_slope" else k): opts.get(k) for k in _RIG_OVERRIDES}
    rig = override_rig(_rig_config(opts.get("rig", DEFAULT_RIG)), **overrides)
    kw = {f: opts[k] for k, f in _FIELDS.items() if k in opts}
    if "sun" in opts:
        kw["sun_direction"] = tuple(opts["sun"])
    # one process per job: the batch's workers already bake side by side
    cfg = BakeConfig(environment=Path(opts.get("environment", DEFAULT_ENVIRONMENT)), rig=rig,
                     out=out, formats=formats, nav_cache_dir=cache, workers=1, **kw)
    return validate_bake(cfg)


_RIGS: dict[Path, object] = {}


def rig_file(rig) -> Path:
    """The file a job's rig was read from (RigConfig.source: relative to the project's folder
    for a bundled rig, else absolute: batch resolves every path)."""
    from baker.config import REPO_ROOT

    source = Path(rig.source)
    return source if source.is_absolute() else REPO_ROOT / source


def _rig_config(path: Path):
    """load_rig_config, once per file and process."""
    path = Path(path)
    if path not in _RIGS:
        _RIGS[path] = load_rig_config(path)
    return _RIGS[path]


def _entries(doc: dict, problems: _Problems) -> list:
    for key in doc:
        if key not in ("defaults", "job"):
            hint = _did_you_mean(key, ["defaults", "job"])
            problems.add("jobs file", f"unknown table '{key}'{hint}; expected [defaults] and "
                                      "[[job]] entries")
    jobs = doc.get("job")
    if jobs is None:
        problems.add("jobs file", "no [[job]] entries")
        return []
    if not isinstance(jobs, list):
        problems.add("jobs file", "job must be an array of tables: write [[job]], not [job]")
        return []
    return jobs


def _expand(entries, defaults, base, out, cache, problems):
    """(name, label, BakeConfig) of every job the entries expand to."""
    made = []
    for i, entry in enumerate(entries, 1):
        label = (f"job '{short_path(entry['name'])}'" if isinstance(entry, dict)
                 and isinstance(entry.get("name"), str) else f"job #{i}")
        before = len(problems.items)
        opts, matrix = _check_table(entry, label, base, problems, job=True)
        if len(problems.items) > before:
            continue            # its errors are listed; expanding it would only repeat them
        count = 1
        for items in matrix.values():
            count *= len(items)
        if len(made) + count > MAX_JOBS:
            problems.add(label, f"the file expands to more than {MAX_JOBS} jobs")
            return made
        for values in itertools.product(*matrix.values()):
            combo = dict(zip(matrix, values))
            merged = {**defaults, **opts, **combo}
            try:
                name = _job_name(entry if isinstance(entry, dict) else {}, i, combo, merged)
            except KeyError as e:
                problems.add(label, f"name template: '{e.args[0]}' is not a job key")
                break
            except (ValueError, IndexError) as e:
                problems.add(label, f"name template: {e}")
                break
            name = _sanitize(name)
            try:
                cfg = job_config(merged, out / name, cache)
            except ConfigError as e:
                where = f" ({e.where})" if e.where and e.where not in ("command line",) else ""
                problems.add(f"job '{name}'", _as_key(e.what, _key_of(e)) + where)
                continue
            made.append((name, label, cfg))
    return made


def _key_of(e: ConfigError) -> str:
    w = str(e.where or "")
    return w[2:].replace("-", "_") if w.startswith("--") else ""


def load_plan(jobs_file, out, cache=None) -> Plan:
    """Read and check the whole jobs file (Step 1). JobsFileError lists every error, each
    naming its job and key; nothing is run before the file is clean.

    jobs_file : the TOML file; relative paths in it are relative to its folder
    out       : the output folder (absolute or relative to the working directory)
    cache     : the navigation cache (a NavCache, a folder or None)
    """
    path = Path(jobs_file)
    doc = read_toml_file(path, "jobs", max_bytes=MAX_JOBS_FILE_BYTES)
    base = path.resolve().parent
    try:
        out = absolute_path(out)
    except ValueError as e:
        raise ConfigError(f"--out {short_path(str(out))}: {e}", where="--out") from None
    problems = _Problems()
    defaults, _ = _check_table(doc.get("defaults", {}), "[defaults]", base, problems, job=False)
    made = _expand(_entries(doc, problems), defaults, base, out, cache, problems)
    seen: dict[str, str] = {}
    for name, label, _ in made:
        if not _NAME.match(name):   # (a name of a million characters was shown whole)
            problems.add(label, f"name '{short_path(name)}' ({len(name):,} characters): "
                                "expected letters, digits, _ . - (at most 100, not starting "
                                "with . or -)")
        elif name.casefold() == Path(MANIFEST).stem:
            problems.add(label, f"name '{name}' is taken by the batch's {MANIFEST}")
        elif name.casefold() in seen:
            problems.add(label, f"name '{name}' is used twice (also by {seen[name.casefold()]}); "
                                "give each [[job]] its own name")
        seen.setdefault(name.casefold(), label)
    problems.raise_if_any(path)
    return _plan(path, out, made)


def _plan(path: Path, out: Path, made) -> Plan:
    digests: dict[Path, str] = {}
    groups: dict[str, int] = {}
    reps: list[BakeConfig] = []
    jobs = []
    for name, _, cfg in made:
        env = Path(cfg.environment)
        if env not in digests:
            try:
                digests[env] = environment_digest(env)
            except OSError as e:
                raise ConfigError(f"cannot read environment: {e.strerror or e}",
                                  where=str(env)) from None
        g = nav_group(cfg)
        if g not in groups:
            groups[g] = len(reps)
            reps.append(cfg)
        jobs.append(Job(name=name, cfg=cfg, key=job_key(cfg, digests[env]), nav=groups[g]))
    return Plan(jobs_file=path.resolve(), out=out, jobs=tuple(jobs), nav_groups=tuple(reps))


# =========================================================================== step 2: keys
def _plain(obj):
    """JSON-able plain values (dataclasses, tuples, paths)."""
    if is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _plain(getattr(obj, f.name)) for f in fields(obj)}
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, Path):
        return obj.as_posix()
    return obj


def environment_digest(path) -> str:
    """sha256 of an environment file's bytes, and of the files in its folder that it names
    (a .gltf's buffers and images, an .obj's .mtl and what that names, a .usda's layers)."""
    h = hashlib.sha256()
    todo, seen = [Path(path)], set()
    while todo:
        p = todo.pop(0)
        if p in seen:
            continue
        seen.add(p)
        h.update(p.name.encode() + b"\0" if len(seen) > 1 else b"")
        others = [q for q in sorted(p.parent.iterdir()) if q.is_file() and q not in seen] \
            if p.suffix.lower() in _NAMES_FILES else []
        named = _hash_file(h, p, [q.name.encode() for q in others])
        todo += [q for q in others if q.name.encode() in named]
    return h.hexdigest()


def _hash_file(h, path: Path, names: list[bytes], chunk: int = 1 << 24) -> set[bytes]:
    """Feed the file's size (8 bytes) and bytes to `h`, in chunks (a .gltf's 3 GB buffer was
    read whole into memory); the `names` found in its bytes."""
    found: set[bytes] = set()
    keep = max(map(len, names), default=1) - 1
    tail = b""
    with open(path, "rb") as f:
        h.update(os.fstat(f.fileno()).st_size.to_bytes(8, "little"))
        while data := f.read(chunk):
            h.update(data)
            if names:
                window = tail + data
                found.update(n for n in names if n not in found and n in window)
                tail = window[len(window) - keep:] if keep else b""
    return found


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """Hex sha256 of the baker package's own source files (their paths and bytes): a change to
    the code, released or not, makes every job's key new."""
    h = hashlib.sha256()
    root = Path(baker.__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def job_key(cfg: BakeConfig, env_digest: str) -> str:
    """Hex sha256 of what a job's outputs depend on: the environment's bytes (env_digest),
    the resolved rig, every option that changes an output byte, the baker version and the
    digest of its source code (code_digest)."""
    options = {f.name: getattr(cfg, f.name) for f in fields(cfg) if f.name not in _NOT_IN_KEY}
    doc = {"baker": baker.__version__, "code": code_digest(), "environment": env_digest,
           "rig": _plain(cfg.rig), "options": _plain(options)}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def nav_group(cfg: BakeConfig) -> str:
    """Jobs with the same group share one navigation surface: same environment read the same
    way (up axis, units), agent, build mode, and (for a lazy build's first window) the same
    start and window sizes."""
    r = cfg.rig
    return json.dumps(_plain([cfg.environment, cfg.up_axis, cfg.units, asdict(r.navigation),
                              cfg.nav_build, cfg.start, r.wander.radius,
                              r.behaviour.detection_range, r.body.length, cfg.max_memory_mb]))


def file_record(path: Path) -> dict:
    """What the manifest keeps of an output: its name, sha256, size and modification time."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    st = os.stat(path)
    return {"path": Path(path).name, "sha256": h.hexdigest(), "bytes": st.st_size,
            "mtime_ns": st.st_mtime_ns}


# =========================================================================== steps 3-4: tasks
class JobTimeout(BakerError):
    """A task ran past --job-timeout."""


@dataclass(frozen=True)
class NavTask:
    """Build (or load) the navigation surface of group `group` into the cache."""

    group: int
    cfg: BakeConfig
    timeout: float | None = None

    @property
    def label(self) -> str:
        return f"navigation {Path(self.cfg.environment).name}"

    @property
    def ident(self) -> str:
        return f"navigation:{self.group}"


@dataclass(frozen=True)
class JobTask:
    """Bake one job."""

    name: str
    cfg: BakeConfig
    timeout: float | None = None

    @property
    def label(self) -> str:
        return self.name

    @property
    def ident(self) -> str:
        return self.name


@dataclass
class Outcome:
    """What a task sent back. infra: the task did not run to an answer (its worker died or
    was lost), so running it again may succeed."""

    ok: bool
    wall_s: float = 0.0
    worker: str = ""
    error: str | None = None
    traceback: str | None = None
    outputs: dict = field(default_factory=dict)
    metrics: dict | None = None
    cache_hit: bool | None = None
    log: list = field(default_factory=list)
    infra: bool = False


def _worker_name() -> str:
    """The Dask worker's address inside a Dask worker, else host:pid."""
    dist = sys.modules.get("distributed")       # imported in a Dask worker, not in a pool's
    try:
        return dist.get_worker().address
    except (AttributeError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


class _LogCapture(logging.Handler):
    """Warnings and errors logged by this thread while a task runs (for the manifest)."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.thread = threading.get_ident()
        self.lines: list[str] = []

    def emit(self, record):
        if record.thread == self.thread and len(self.lines) < 50:
            self.lines.append(f"{record.levelname} {record.name}: {record.getMessage()}")

    @contextmanager
    def active(self):
        root = logging.getLogger()
        root.addHandler(self)
        try:
            yield self
        finally:
            root.removeHandler(self)


def _deadline(timeout: float | None):
    """A Context progress callback that raises JobTimeout once `timeout` seconds are gone."""
    if timeout is None:
        return None
    end = time.monotonic() + timeout

    def check(stage: str, fraction: float) -> None:
        if time.monotonic() > end:
            raise JobTimeout(f"timed out after {timeout:g} s (--job-timeout), in {stage}")
    return check


def run_task(task) -> Outcome:
    """Run a NavTask or JobTask where it lands (a pool process or a Dask worker). Failures are
    returned, not raised; only a signal (Interrupted) goes through."""
    t0 = time.perf_counter()
    capture = _LogCapture()
    try:
        with capture.active():
            out = _run_nav(task) if isinstance(task, NavTask) else _run_job(task)
    except BakerError as e:
        out = Outcome(ok=False, error=format_error(e).removeprefix("Error: "))
    except Exception as e:      # a bug or a crash in the bake: this job fails, the rest go on
        out = Outcome(ok=False, error=f"{type(e).__name__}: {e}",
                      traceback="".join(traceback.format_exception(e, limit=-12)))
    out.wall_s = round(time.perf_counter() - t0, 3)
    out.worker = _worker_name()
    out.log = capture.lines
    return out


def _run_nav(task: NavTask) -> Outcome:
    from baker.environment import load_environment
    from baker.navmesh.budget import memory_limit
    from baker.pipeline import in_local_frame, navigation_surface

    check = _deadline(task.timeout)
    cfg = task.cfg
    env = load_environment(cfg.environment, sun_override=cfg.sun_direction,
                           up_axis=cfg.up_axis, units=cfg.units)
    if check:
        check("navmesh", 0.0)
    with memory_limit(cfg.max_memory_mb):
        _, hit = navigation_surface(in_local_frame(cfg, env.origin), env)
    return Outcome(ok=True, cache_hit=bool(hit))


def _run_job(task: JobTask) -> Outcome:
    from baker.context import Context
    from baker.pipeline import bake

    result = bake(task.cfg, ctx=Context(progress=_deadline(task.timeout)))
    outputs = {fmt: file_record(p) for fmt, p in result.outputs.items()}
    return Outcome(ok=True, outputs=outputs, metrics=metrics_summary(result.report),
                   cache_hit=result.report.get("navmesh_cache_hit"))


#: report metrics kept in the manifest: (section or None, key)
SUMMARY_METRICS = (
    (None, "frames"), (None, "distance_walked_m"), (None, "spacing_error_max"),
    (None, "max_joint_rotation_per_frame_deg"), (None, "frames_on_unwalkable_slope"),
    (None, "trunk_inside_geometry"), (None, "head_off_walkable_frames"),
    (None, "spine_jump_frames"), (None, "clearance_violations"), ("legs", "skate_median_pct_bl"),
    ("legs", "foot_penetration_max_pct_bl"), ("legs", "leg_bone_hits"),
    ("behaviour", "state_seconds"), ("behaviour", "captures"),
)


def metrics_summary(report: dict) -> dict:
    """The quality metrics summary of a bake's report (SUMMARY_METRICS that it has)."""
    m = report.get("metrics") or {}
    out = {}
    for section, key in SUMMARY_METRICS:
        src = m if section is None else (m.get(section) or {})
        if key in src:
            out[key if section is None else f"{section}.{key}"] = src[key]
    return out


# --------------------------------------------------------------------------- local pool
def _worker_main(conn) -> None:
    """A pool process: run the tasks it is sent until it gets None. SIGINT/SIGTERM unwind the
    running bake (its temporaries deleted, baker/signals.py) and end the process."""
    signals.install()
    try:
        from baker.pipeline import warm_up

        warm_up()       # while the first task is on its way
        while True:
            task = conn.recv()
            if task is None:
                return
            conn.send(run_task(task))
    except (signals.Interrupted, EOFError, OSError, KeyboardInterrupt):
        return


class _Proc:
    def __init__(self, ctx):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child,), daemon=True,
                                name="baker-batch-worker")
        self.proc.start()
        child.close()
        self.handle: int | None = None


class LocalPool:
    """`workers` processes on this machine (spawned: a fresh interpreter each, all started
    with the first task, each importing the bake's modules at once), one task at a time each.
    A process that dies is replaced; its task alone is reported lost.

    Not concurrent.futures.ProcessPoolExecutor: there a dead worker breaks the whole pool (every
    pending task fails), and one worker can be neither stopped (a task past its timeout) nor sent
    SIGTERM (a clean stop) without its private attributes."""

    kind = "local"

    def __init__(self, workers: int):
        import multiprocessing

        self.size = max(1, int(workers))
        self._ctx = multiprocessing.get_context("spawn")
        self.procs: list[_Proc] = []
        self._ids = itertools.count(1)

    def describe(self) -> str:
        return f"{self.size} local worker{'s' * (self.size != 1)}"

    def slots(self) -> int:
        return self.size - sum(p.handle is not None for p in self.procs)

    def submit(self, task) -> int:
        for p in [p for p in self.procs if p.handle is None and not p.proc.is_alive()]:
            self._drop(p)
        while len(self.procs) < self.size:     # all at once: they warm up side by side
            self.procs.append(_Proc(self._ctx))
        proc = next((p for p in self.procs if p.handle is None), None)
        for _ in range(2):
            if proc is None:
                proc = _Proc(self._ctx)
                self.procs.append(proc)
            try:
                proc.conn.send(task)
                break
            except OSError:             # it died since: a fresh one
                self._drop(proc)
                proc = None
        else:
            raise OSError("cannot start a worker process")
        proc.handle = next(self._ids)
        return proc.handle

    def wait(self, timeout: float) -> list[tuple[int, Outcome]]:
        from multiprocessing.connection import wait

        busy = [p for p in self.procs if p.handle is not None]
        if not busy:
            time.sleep(min(timeout, 0.05))
            return []
        ready = set(wait([p.conn for p in busy] + [p.proc.sentinel for p in busy], timeout))
        done = []
        for p in busy:
            if p.conn in ready or p.proc.sentinel in ready:
                done.append((p.handle, self._collect(p)))
        return done

    def _collect(self, p: _Proc) -> Outcome:
        try:
            if p.conn.poll():
                out = p.conn.recv()
                p.handle = None
                return out
        except (EOFError, OSError):
            pass
        p.proc.join(5)
        self._drop(p)
        return Outcome(ok=False, infra=True, error=f"worker process {p.proc.pid} died "
                                                   f"(exit code {p.proc.exitcode})")

    def _drop(self, p: _Proc) -> None:
        p.conn.close()
        self.procs.remove(p)

    def abandon(self, handle: int) -> None:
        """Stop the process running `handle` (a task past its timeout)."""
        for p in list(self.procs):
            if p.handle == handle:
                p.proc.kill()
                p.proc.join(10)
                self._drop(p)

    def close(self, interrupted: bool = False) -> None:
        """Stop every process: politely when the batch ended, with SIGTERM (their bakes
        delete their temporaries) when it was interrupted."""
        import signal

        for p in self.procs:
            try:
                if interrupted and p.proc.is_alive():
                    os.kill(p.proc.pid, signal.SIGTERM)
                else:
                    p.conn.send(None)
            except (OSError, ValueError):
                pass
        for p in self.procs:
            p.proc.join(30)
            if p.proc.is_alive():
                p.proc.kill()
                p.proc.join(5)
            p.conn.close()
        self.procs.clear()


# --------------------------------------------------------------------------- Dask
#: the transports a Dask scheduler on another machine (or process) is reached by
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def _address_checked(address: str) -> None:
    """ConfigError for a scheduler address Dask cannot parse (no port, not a number, no host),
    before a Client is made: a Client that fails on its address leaves a half-made object whose
    clean-up stalls and prints a traceback as the process ends."""
    if not address.strip():
        raise ConfigError("--scheduler needs a Dask scheduler's address, e.g. tcp://host:8786",
                          where="--scheduler")
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        raise ConfigError("--scheduler needs Dask: pip install 'baker[dask]'",
                          where="--scheduler") from None

    try:
        scheme, loc = parse_address(address)
        if scheme not in _SCHEMES:  # inproc:// (this process's own) left a half-made Client
            raise ValueError(f"'{scheme}://' is not a network transport; use one of "
                             f"{', '.join(s + '://' for s in _SCHEMES)}")
        host, _ = parse_host_port(loc)
        if not host or any(c.isspace() for c in host):
            raise ValueError(f"no host in {loc!r}")
        _host_name_checked(host)
    except ValueError as e:
        raise ConfigError(f"not a Dask scheduler address: {short_path(address)} ({e}); "
                          "expected tcp://HOST:PORT", where="--scheduler") from None
    _transport_checked(scheme)


def _host_name_checked(host: str) -> None:
    """ValueError for a host name the resolver cannot be asked about (a label over 63
    characters or empty, a name over 253): Dask's Client raised UnicodeError from the idna
    codec half made, and its clean-up stalled 40 s and printed a traceback at exit."""
    if ":" in host:                     # an IPv6 address (its brackets taken off)
        return
    try:
        name = host.encode("idna")
    except UnicodeError:
        raise ValueError(f"'{short_path(host)}' is not a host name (each dot-separated label "
                         "1 to 63 characters)") from None
    if len(name.rstrip(b".")) > 253:
        raise ValueError(f"the host name is {len(name)} characters; at most 253")


def _transport_checked(scheme: str) -> None:
    """ConfigError for a transport this installation cannot use: ucx:// without its package
    (Dask's connector raised TypeError inside the Client), tls:// without Dask's TLS
    configuration (TypeError: 'TLS expects a ssl_context'); both left a half-made Client."""
    from distributed.comm.registry import get_backend

    try:
        get_backend(scheme).get_connector()
    except Exception as e:      # (ImportError, TypeError: whatever the backend's import says)
        raise ConfigError(f"the {scheme}:// transport cannot be used here ({type(e).__name__}: "
                          f"{str(e).splitlines()[0] if str(e) else ''}); use tcp://HOST:PORT",
                          where="--scheduler") from None
    if scheme == "tls":
        from distributed.security import Security

        if Security().get_connection_args("client").get("ssl_context") is None:
            raise ConfigError("tls:// needs Dask's TLS configuration (distributed.comm.tls: "
                              "ca-file, client cert and key); none is set", where="--scheduler")


class DaskPool:
    """The same tasks on a running Dask scheduler (`dask scheduler`, `dask worker`), through
    dask.distributed.Client. At most one task per worker thread is in flight, so a task's
    timeout counts from when it starts. Paths must mean the same files on every worker."""

    kind = "dask"

    def __init__(self, address: str, connect_timeout: float = 20.0):
        _address_checked(address)                   # Dask installed, the address parsed
        from distributed import Client

        try:
            self.client = Client(address, timeout=f"{connect_timeout}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as e:
            raise ConfigError(f"cannot reach the Dask scheduler at {short_path(address)}: "
                              f"{short_path(str(e), 200)}", where="--scheduler") from None
        try:
            self.client.wait_for_workers(1, timeout=60)
        except (TimeoutError, OSError):
            self.client.close()
            raise ConfigError(f"no Dask worker is connected to {address}",
                              where="--scheduler") from None
        self.address = address
        self.futures: dict[int, object] = {}
        self._ids = itertools.count(1)
        self._threads = (0, 0.0)

    def describe(self) -> str:
        return f"Dask scheduler {self.address} ({self._total()} worker threads)"

    def _total(self) -> int:
        n, when = self._threads
        if time.monotonic() - when > 2.0:
            try:
                n = sum(self.client.nthreads().values())
            except (OSError, TimeoutError):
                pass
            self._threads = (n, time.monotonic())
        return n

    def slots(self) -> int:
        return self._total() - len(self.futures)

    def submit(self, task) -> int:
        h = next(self._ids)
        key = f"baker-{_sanitize(task.label)}-{uuid.uuid4().hex[:8]}"
        self.futures[h] = self.client.submit(run_task, task, key=key, pure=False, retries=0)
        return h

    def wait(self, timeout: float) -> list[tuple[int, Outcome]]:
        end = time.monotonic() + timeout
        while True:     # the client's own thread updates each future's state
            done = [h for h, f in self.futures.items() if f.done()]
            if done or time.monotonic() >= end:
                return [(h, self._collect(self.futures.pop(h))) for h in done]
            time.sleep(0.05)

    @staticmethod
    def _collect(f) -> Outcome:
        try:
            out = f.result()
        except BaseException as e:      # lost worker, cancelled, connection: run it again
            if isinstance(e, (KeyboardInterrupt, signals.Interrupted)):
                raise
            return Outcome(ok=False, infra=True, error=f"Dask: {type(e).__name__}: {e}")
        finally:
            f.release()
        return out

    def abandon(self, handle: int) -> None:
        """Stop waiting for `handle` (Dask cannot stop a running task's thread; the bake's own
        deadline check ends it)."""
        f = self.futures.pop(handle, None)
        if f is not None:
            f.cancel()

    def close(self, interrupted: bool = False) -> None:
        if self.futures:
            self.client.cancel(list(self.futures.values()))
            self.futures.clear()
        self.client.close()


# =========================================================================== step 5: manifest
class Manifest:
    """DIR/manifest.json: per job its key, status (pending, baked, skipped, failed), outputs
    with their sha256, wall time, worker, attempts, error and quality metrics summary; per
    navigation group its environment, cache hit and time. Rewritten atomically."""

    def __init__(self, plan: Plan):
        self.plan = plan
        self.path = plan.out / MANIFEST
        self.previous = self._read_previous()
        self.jobs: dict[str, dict] = {}
        self.navigation: list[dict] = [
            {"environment": str(c.environment), "status": "not needed"} for c in plan.nav_groups]

    def _read_previous(self) -> dict:
        if not self.path.is_file():     # none yet, or no file (a FIFO's read waited for ever)
            return {}
        try:
            if self.path.stat().st_size > MAX_MANIFEST_BYTES:   # not one a batch wrote
                return {}
            doc = json.loads(self.path.read_text())
            jobs = doc.get("jobs", {})
            return jobs if isinstance(jobs, dict) else {}
        except (OSError, ValueError, AttributeError, RecursionError):
            return {}       # (JSON nested 100,000 deep was a RecursionError traceback)

    def up_to_date(self, job: Job) -> dict | None:
        """The previous entry when the job's outputs are there with the same key, unchanged
        (same size, and the same modification time or sha256)."""
        prev = self.previous.get(job.name)
        if not isinstance(prev, dict) or prev.get("key") != job.key \
                or prev.get("status") not in _DONE:
            return None
        outputs = prev.get("outputs")
        paths = job.cfg.output_paths()
        if not isinstance(outputs, dict) or set(outputs) != set(paths):
            return None
        for fmt, p in paths.items():
            rec = outputs[fmt]
            if not isinstance(rec, dict) or rec.get("path") != p.name:
                return None
            try:
                st = os.stat(p)
                if st.st_size != rec.get("bytes") or (
                        st.st_mtime_ns != rec.get("mtime_ns")
                        and file_record(p)["sha256"] != rec.get("sha256")):
                    return None
            except OSError:
                return None
        return prev

    def pending(self, job: Job) -> dict:
        return {"key": job.key, "status": "pending", "environment": str(job.cfg.environment),
                "outputs": {}, "wall_s": None, "worker": None, "attempts": 0, "error": None,
                "metrics": None}

    def summary(self) -> dict:
        counts = {s: 0 for s in ("baked", "skipped", "failed", "pending")}
        for e in self.jobs.values():
            counts[e["status"]] = counts.get(e["status"], 0) + 1
        return {"jobs": len(self.jobs), **counts}

    def write(self) -> None:
        doc = {"baker_version": baker.__version__, "jobs_file": str(self.plan.jobs_file),
               "out": str(self.plan.out), "summary": self.summary(),
               "navigation": self.navigation, "jobs": self.jobs}
        atomic_write_bytes(self.path, (json.dumps(_plain(doc), indent=2) + "\n").encode())


# --------------------------------------------------------------------------- progress
class Progress:
    """A bar (tqdm) with done, failed, skipped and the ETA on a terminal; one plain line per
    event when stderr is not a terminal (piped, CI logs)."""

    def __init__(self, total: int, skipped: int, stream=None):
        self.stream = stream or sys.stderr
        self.counts = {"baked": 0, "failed": 0, "skipped": skipped}
        self.total = total
        self.bar = None
        if getattr(self.stream, "isatty", lambda: False)() and total:
            try:
                from tqdm import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self.bar = tqdm(total=total, file=self.stream, unit="bake", dynamic_ncols=True,
                                desc="batch", leave=False)
                self._postfix()

    def _postfix(self) -> None:
        self.bar.set_postfix_str(", ".join(f"{k} {v}" for k, v in self.counts.items()))

    def line(self, text: str) -> None:
        if self.bar is not None:
            self.bar.write(text, file=self.stream)
        else:
            self.stream.write(text + "\n")
            self.stream.flush()

    def job(self, name: str, entry: dict) -> None:
        status = entry["status"]
        self.counts[status] = self.counts.get(status, 0) + 1
        n = self.counts["baked"] + self.counts["failed"]
        if self.bar is not None:
            self.bar.update(1)
            self._postfix()
            if status == "failed":
                self.line(f"failed {name}: {entry['error']}")
            return
        width = len(str(self.total))
        what = f"{entry['wall_s']:.2f} s on {entry['worker']}" if status == "baked" \
            else entry["error"]
        self.line(f"[{n:>{width}}/{self.total}] {status} {name}: {what}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


# =========================================================================== the run
@dataclass(frozen=True)
class Summary:
    """How a batch ended."""

    jobs: int
    baked: int
    skipped: int
    failed: int
    pending: int
    wall_s: float
    manifest: Path

    @property
    def line(self) -> str:
        return (f"batch: {self.jobs} jobs, {self.baked} baked, {self.skipped} up to date, "
                f"{self.failed} failed in {self.wall_s:.1f} s -> {self.manifest}")


class _Run:
    """Steps 3-5: navigation tasks first; a group's jobs once its surface is in the cache;
    each outcome into the manifest as it comes."""

    def __init__(self, plan: Plan, manifest: Manifest, pool, progress: Progress,
                 todo: list[Job], timeout: float | None, retries: int):
        self.plan, self.manifest, self.pool, self.progress = plan, manifest, pool, progress
        self.timeout, self.retries = timeout, retries
        self.waiting: dict[int, list[Job]] = {}
        for job in todo:
            self.waiting.setdefault(job.nav, []).append(job)
        cfgs = plan.nav_groups
        self.queue = deque(NavTask(g, cfgs[g], timeout) for g in sorted(self.waiting)) \
            if _has_cache(plan) else deque(JobTask(j.name, j.cfg, timeout) for j in todo)
        self.running: dict[int, tuple[object, float]] = {}
        self.attempts: dict[str, int] = {}

    def loop(self) -> None:
        while self.queue or self.running:
            while self.queue and self.pool.slots() > 0:
                task = self.queue.popleft()
                self.attempts[task.ident] = self.attempts.get(task.ident, 0) + 1
                self.running[self.pool.submit(task)] = (task, time.monotonic())
            for handle, outcome in self.pool.wait(self._wait_s()):
                task, _ = self.running.pop(handle)
                self._finish(task, outcome)
            self._stop_overdue()

    def _grace(self) -> float:
        return max(10.0, 0.25 * self.timeout)

    def _wait_s(self) -> float:
        if self.timeout is None or not self.running:
            return 1.0
        first = min(t for _, t in self.running.values()) + self.timeout + self._grace()
        return max(0.05, min(1.0, first - time.monotonic()))

    def _stop_overdue(self) -> None:
        if self.timeout is None:
            return
        now = time.monotonic()
        for handle, (task, t0) in list(self.running.items()):
            if now - t0 > self.timeout + self._grace():
                self.pool.abandon(handle)
                del self.running[handle]
                self._finish(task, Outcome(ok=False, wall_s=round(now - t0, 3), error=(
                    f"timed out after {self.timeout:g} s (--job-timeout); stopped")))

    def _finish(self, task, out: Outcome) -> None:
        n = self.attempts.get(task.ident, 1)
        if out.infra and n <= self.retries:
            self.progress.line(f"retrying {task.label} ({out.error})")
            self.queue.appendleft(task)
            return
        if isinstance(task, NavTask):
            self._nav_done(task, out, n)
        else:
            self._job_done(task.name, out, n)

    def _nav_done(self, task: NavTask, out: Outcome, attempts: int) -> None:
        self.manifest.navigation[task.group] = {
            "environment": str(task.cfg.environment), "status": "ready" if out.ok else "failed",
            "cache_hit": out.cache_hit, "wall_s": out.wall_s, "worker": out.worker,
            "attempts": attempts, "error": out.error, "log": out.log}
        jobs = self.waiting.pop(task.group, [])
        if out.ok:
            self.queue.extend(JobTask(j.name, j.cfg, self.timeout) for j in jobs)
            self.progress.line(f"navigation ready for {Path(task.cfg.environment).name} "
                               f"({'from the cache' if out.cache_hit else 'built'}, "
                               f"{out.wall_s:.2f} s)")
            return
        failed = Outcome(ok=False, worker=out.worker, traceback=out.traceback,
                         error=f"navigation surface: {out.error}")
        for j in jobs:
            self._job_done(j.name, failed, 0)

    def _job_done(self, name: str, out: Outcome, attempts: int) -> None:
        entry = dict(self.manifest.jobs[name])
        entry.update(status="baked" if out.ok else "failed", outputs=out.outputs,
                     wall_s=out.wall_s, worker=out.worker, attempts=attempts, error=out.error,
                     metrics=out.metrics, navmesh_cache_hit=out.cache_hit)
        if out.traceback:
            entry["traceback"] = out.traceback
        if out.log:
            entry["log"] = out.log
        self.manifest.jobs[name] = entry
        self.manifest.write()
        self.progress.job(name, entry)


def _has_cache(plan: Plan) -> bool:
    return any(c.nav_cache_dir is not None for c in plan.nav_groups)


@contextmanager
def _batch_lock(out: Path):
    """Hold `out`'s lock file for the batch, and remove it after: it is unlinked while still
    locked, and a batch that locks a file another has just unlinked (the path no longer
    names its file) opens the path again."""
    path = out / LOCK_FILE
    fd = _locked(path, out)
    try:
        yield
    finally:
        with suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _locked(path: Path, out: Path) -> int:
    """A descriptor of the lock file at path, exclusively locked (unlocked on a file system
    without locks); ConfigError when another batch holds it."""
    import fcntl

    while True:
        try:    # (a folder or a link in its place raised IsADirectoryError, ELOOP: a traceback)
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o666)
        except OSError as e:
            raise ConfigError(f"cannot open the batch's lock file {path}: {e.strerror or e} "
                              "(a file baker makes there; remove what is in its place)",
                              where="--out") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise ConfigError(f"another `baker batch` is writing into {out}",
                              where="--out") from None
        except OSError:
            return fd           # a file system without locks: go on unlocked
        try:
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)            # unlinked by the batch that held it: take the new file


def local_workers(workers: int | None) -> int:
    """--workers, or the cores this process may use."""
    if workers:
        return int(workers)
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def run(jobs_file, *, out=None, workers: int | None = None, scheduler: str | None = None,
        force: bool = False, job_timeout: float | None = None, retries: int = 1, cache=None,
        stream=None) -> Summary:
    """Run a batch (Steps 1-5) and return its Summary; the manifest is DIR/manifest.json.

    out       : output folder [default: outputs/<jobs file name>]
    workers   : local pool size [default: the core count]; not with `scheduler`
    scheduler : a Dask scheduler address (tcp://host:8786) to run the jobs on
    force     : bake every job, up to date or not
    cache     : the navigation cache (NavCache, folder or None) every job and worker uses
    stream    : where progress goes [default: stderr]
    """
    t0 = time.perf_counter()
    if scheduler and workers:
        raise ConfigError("--workers sizes the local pool; with --scheduler the Dask workers "
                          "run the jobs", where="--workers")
    if scheduler is not None:
        _address_checked(scheduler)         # before the output folder is made (an empty one too)
    out = Path(out) if out is not None else Path("outputs") / Path(jobs_file).stem
    if cache is not None:       # one absolute folder, the same for every worker
        from baker.navmesh.cache import NavCache

        cache = NavCache.of(cache)
        try:
            cache = replace(cache, folder=absolute_path(cache.folder))
        except ValueError as e:
            raise ConfigError(f"--cache-dir {short_path(str(cache.folder))}: {e}",
                              where="--cache-dir") from None
    # Step 1: the whole jobs file, and every output path, checked before any work.
    plan = load_plan(jobs_file, out, cache)
    check_writable(plan.out)
    check_outputs({"manifest": plan.out / MANIFEST,     # (a FIFO there was renamed over)
                   **{f"{j.name}.{k}": p for j in plan.jobs for k, p in j.cfg.output_paths().items()}})
    for j in plan.jobs:     # (a job named after its level, --out its folder: over the level;
        # after a jobs file j.json or a rig r.json, the same: the job's JSON report over it)
        check_not_inputs(j.cfg.output_paths(), {f"job '{j.name}' environment": j.cfg.environment,
                                                f"job '{j.name}' rig": rig_file(j.cfg.rig),
                                                "jobs": plan.jobs_file})
    with _batch_lock(plan.out):
        manifest = Manifest(plan)
        # Step 2: what is up to date is skipped.
        todo = skip_up_to_date(plan, manifest, force)
        # the scheduler is reached (or refused) before anything is written
        pool = (DaskPool(scheduler) if scheduler else LocalPool(
            min(local_workers(workers), len(todo)))) if todo else None
        progress = Progress(len(todo), len(plan.jobs) - len(todo), stream)
        try:
            manifest.write()
            signals.checkpoint("batch")
            progress.line(f"batch: {len(plan.jobs)} jobs, {len(plan.jobs) - len(todo)} up to "
                          f"date" + (f", {len(todo)} to bake on {pool.describe()}" if pool else ""))
            if pool is not None:    # Steps 3-5
                _execute(plan, manifest, pool, progress, todo, job_timeout, retries)
        finally:
            progress.close()
    s = manifest.summary()
    return Summary(jobs=s["jobs"], baked=s["baked"], skipped=s["skipped"], failed=s["failed"],
                   pending=s["pending"], wall_s=time.perf_counter() - t0, manifest=manifest.path)


def skip_up_to_date(plan: Plan, manifest: Manifest, force: bool = False) -> list[Job]:
    """Step 2: the jobs to bake. An up-to-date job (Manifest.up_to_date) keeps its previous
    entry, marked skipped; the others are pending, and so is their navigation group."""
    todo = []
    for job in plan.jobs:
        prev = None if force else manifest.up_to_date(job)
        manifest.jobs[job.name] = {**prev, "status": "skipped"} if prev else manifest.pending(job)
        if prev is None:
            todo.append(job)
            manifest.navigation[job.nav]["status"] = "pending"
    return todo


def _execute(plan, manifest, pool, progress, todo, timeout, retries) -> None:
    interrupted = False
    try:
        _Run(plan, manifest, pool, progress, todo, timeout, retries).loop()
    except BaseException:       # a signal: stop the workers (their bakes clean up), keep the rest
        interrupted = True
        raise
    finally:
        with signals.deferred():
            pool.close(interrupted=interrupted)
            manifest.write()
