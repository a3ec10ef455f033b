"""Command-line interface. Commands only build a config and call the pipeline."""

from __future__ import annotations

import errno
import logging
import math
import os
import sys
import time
import warnings
from pathlib import Path

import click

from baker.errors import EXIT_USAGE, BakerError, ConfigError, format_error, short_path

# The heavy modules (baker.config and with it numpy and pydantic; scipy, trimesh, pxr) are
# imported inside the commands, so `--help` and option errors come before them (issue 15).


def _default_rig() -> Path:
    from baker.config import DEFAULT_RIG

    return DEFAULT_RIG


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "baker" / "navmesh"


def parse_vec3(text: str | None, what: str):
    if text is None:
        return None
    form = f"{what} must be three comma-separated numbers, e.g. 0.3,1,0.2"
    try:
        vals = tuple(float(x) for x in text.replace(" ", "").split(","))
    except ValueError:
        raise ConfigError(form, where=what) from None
    if len(vals) != 3:
        raise ConfigError(form, where=what)
    return vals


def max_memory_option(f):
    return click.option(
        "--max-memory", type=float, default=None, metavar="MB",
        help="Refuse a navigation build, or a bake (its creatures and frames), estimated to "
             "need more memory than this, in MB [default: for a navigation build half, for a "
             "bake 80% of the memory this process may use: the RAM, or less under ulimit -v "
             "or a container's limit].")(f)


def rig_options(f):
    """--scale and the navigation agent overrides, shared by `bake` and `navmesh`
    (passed on to config.override_rig)."""
    opts = [
        click.option("--scale", type=float, default=None, metavar="FACTOR",
                     help="Scale the rig uniformly (sizes, speeds, navigation agent), "
                          "e.g. 8 for a 2 m giant centipede."),
        click.option("--agent-radius", type=float, default=None, metavar="M",
                     help="Navigation agent radius in metres (erosion) [default: from the rig]."),
        click.option("--agent-height", type=float, default=None, metavar="M",
                     help="Free height needed above walkable surface, metres [default: from the rig]."),
        click.option("--step-height", type=float, default=None, metavar="M",
                     help="Largest riser the agent climbs, metres [default: from the rig]."),
        click.option("--max-slope", "max_slope_deg", type=float, default=None, metavar="DEG",
                     help="Steepest walkable slope in degrees [default: from the rig, 60]."),
        click.option("--cell-size", type=float, default=None, metavar="M",
                     help="Navigation grid cell size in metres [default: from the rig]."),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


#: --up, of `bake` and `navmesh`: the level's up axis
up_option = click.option(
    "--up", type=click.Choice(["y", "z"]), default=None,
    help="The level's up axis, for a file that says otherwise or nothing: OBJ, PLY and STL are "
         "read +Y up unless told z (3ds Max, Unreal and CAD exports are +Z up); glTF is +Y up "
         "by definition; USD says its own (upAxis), which this overrides. [default: the "
         "file's own]")


#: --units, of `bake` and `navmesh`: the level's unit
units_option = click.option(
    "--units", type=click.Choice(["m", "cm", "mm", "km", "in", "ft"]), default=None,
    help="The level's unit, for a file that says otherwise or nothing: OBJ, PLY and STL are "
         "read in metres unless told (Unreal exports are in cm); glTF is in metres by "
         "definition; USD says its own (metersPerUnit), which this overrides. [default: the "
         "file's own]")


def check_numba_threads() -> None:
    """NUMBA_NUM_THREADS, which numba reads when baker's kernels are first imported, must be a
    whole number of at least 1: 0 was a ValueError traceback, a word a warning of many lines
    (numba's own traceback among them) before the bake went on."""
    text = os.environ.get("NUMBA_NUM_THREADS")
    if text is None:
        return
    try:
        ok = int(text) >= 1
    except ValueError:
        ok = False
    if not ok:
        raise ConfigError(f"NUMBA_NUM_THREADS = {text[:40]!r}: expected a whole number of at "
                          "least 1, or leave it unset", where="environment variable")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="baker")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose: int):
    """baker: bake a procedural centipede walking over an environment into GLB and USD."""
    check_numba_threads()
    level = logging.WARNING - 10 * min(verbose, 2)
    logging.getLogger().setLevel(level)
    if verbose:  # asked for: logs go out as they come (not held back until the end)
        _HELD.release(live=True)


@cli.command()
@click.argument("environment", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--seconds", type=float, default=60.0, show_default=True, help="Simulated duration.")
@click.option("--fps", type=int, default=30, show_default=True,
              help="Export frame rate; must divide the 240 Hz simulation rate.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=_default_rig, show_default="rigs/scolopendra.toml", help="Rig definition (TOML).")
@click.option("--out", type=click.Path(), default="outputs/centipede", show_default=True,
              help="Output path without extension (a .glb, .usd or .json ending is dropped); "
                   "a folder (or a path ending in /) writes <folder>/centipede.*.")
@click.option("--format", "fmt", type=click.Choice(["glb", "usd", "both"]), default="both",
              show_default=True, help="Which animation files to write (the JSON report is always written).")
@click.option("--usda", is_flag=True, help="Write the USD as ASCII (.usda) instead of crate (.usd).")
@click.option("--sun", default=None, metavar="X,Y,Z",
              help="Direction toward the sun, fixed; overrides the environment's light "
                   "(and its motion).")
@click.option("--debug-navmesh", is_flag=True, help="Add the walkable surface as an extra mesh layer.")
@up_option
@units_option
@click.option("--cache-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Navigation cache folder [default: ~/.cache/baker/navmesh].")
@click.option("--no-cache", is_flag=True, help="Always rebuild the navigation surface.")
@click.option("--cache-max", type=float, default=None, metavar="MB",
              help="Bound of the navigation cache folder in MB; least recently used entries "
                   "are evicted [default: 1024].")
@click.option("--nav-build", type=click.Choice(["auto", "full", "lazy"]), default="auto",
              show_default=True,
              help="Build the navigation surface for the whole level, or lazily in windows "
                   "around where the creatures go (auto: lazily on levels over 6 million columns).")
@click.option("--behaviour", type=click.Choice(["auto", "wander", "shade", "hunt"]), default="auto",
              show_default=True, help="auto lets the brain choose; the others force one drive.")
@click.option("--prey", type=int, default=2, show_default=True, help="Number of prey capsules (0-16).")
@click.option("--creatures", type=int, default=1, show_default=True,
              help="Number of centipedes baked together (1-1000): each its own skinned "
                   "skeleton, sharing one mesh, keeping apart from the others.")
@click.option("--workers", type=int, default=None, metavar="N",
              help="Processes that share a crowd's per-creature work (body and legs, metrics, "
                   "keyframe reduction); the files are the same bytes whatever N "
                   "[default: the CPUs this process may use; 1 on macOS and Windows].")
@click.option("--cobra", type=click.Choice(["auto", "always", "never"]), default="auto",
              show_default=True, help="Cobra mode (front third raised).")
@click.option("--sun-path", default=None, metavar="AZ,EL;AZ,EL",
              help="Move the sun over the bake: azimuth,elevation keys in degrees, evenly "
                   "spaced (one key: a fixed sun). [default: the environment's light, turning "
                   "about the vertical when the file says so: the bundled showcase's turns "
                   "0.5 deg/s]")
@click.option("--clips", is_flag=True,
              help="Also write one animation per behaviour segment (glTF animations, USD SkelAnimations).")
@click.option("--root-motion", type=click.Choice(["world", "root", "in-place"]), default="world",
              show_default=True,
              help="world: joints in world space. root: add a `root` joint on the ground under the "
                   "body that carries its horizontal motion and yaw, for engines' root motion. "
                   "in-place: the same with the root held still; the removed motion is the "
                   "`root_motion` animation.")
@click.option("--tolerance", type=float, default=0.001, show_default=True, metavar="BL",
              help="Keyframe reduction: drop the keys that interpolation reproduces, keeping "
                   "every joint within this world-space distance of the unreduced pose, in body "
                   "lengths (0.001 = 0.1% of the body length); 0 keeps every key.")
@click.option("--rotations", type=click.Choice(["short", "float"]), default="short",
              show_default=True,
              help="Rotation keys of a reduced clip: 16-bit normalized integers (half the size; "
                   "the rounding counts toward --tolerance) or 32-bit floats.")
@click.option("--preview", is_flag=True,
              help="Also draw the bake's pictures from its GLB: <out>_map.png (top-down map) and "
                   "<out>_sheet.png (contact sheet); needs baker[preview] (matplotlib).")
@max_memory_option
@rig_options
def bake(environment, seconds, fps, seed, rig_path, out, fmt, usda, sun, debug_navmesh,
         up, units, cache_dir, no_cache, cache_max, nav_build, behaviour, prey, creatures, workers, cobra,
         sun_path, clips, root_motion, tolerance, rotations, preview, max_memory,
         **rig_overrides):
    """Bake a centipede on ENVIRONMENT (glTF/GLB, OBJ, PLY, STL or USD).

    With no ENVIRONMENT, the bundled showcase (environments/showcase.glb) is used: with no
    option at all, a 60 s bake with 2 prey under the showcase's slowly turning sun, in which
    the centipede wanders, seeks and rests in shade, rears up (cobra), hunts and feeds."""
    from baker.config import BakeConfig, validate_bake

    t0 = time.perf_counter()
    usd_fmt = "usda" if usda else "usd"
    formats = {"glb": ("glb",), "usd": (usd_fmt,), "both": ("glb", usd_fmt)}[fmt]
    # every option is checked before the rig and the level are read
    validate_memory(max_memory, cache_max)
    sun_direction = parse_vec3(sun, "--sun")
    validate_bake(BakeConfig(seconds=seconds, fps=fps, seed=seed, formats=formats,
                             sun_direction=sun_direction, behaviour=behaviour,
                             prey=prey, creatures=creatures, workers=workers, cobra=cobra,
                             sun_path=sun_path, nav_build=nav_build,
                             tolerance=tolerance, rotations=rotations, preview=preview))
    if preview:
        from baker.export.preview import check_dependencies

        check_dependencies("--preview")
    check_rig_overrides(rig_overrides)
    from baker.atomic import check_not_inputs, check_outputs, resolve_out
    from baker.config import DEFAULT_ENVIRONMENT, load_rig_config, override_rig
    from baker.navmesh.cache import NavCache
    from baker.pipeline import bake as run_bake

    cfg = BakeConfig(
        environment=environment or DEFAULT_ENVIRONMENT,
        seconds=seconds, fps=fps, seed=seed,
        rig=override_rig(load_rig_config(rig_path), **rig_overrides), out=resolve_out(out),
        formats=formats, sun_direction=sun_direction, debug_navmesh=debug_navmesh,
        up_axis=up, units=units, nav_cache_dir=None if no_cache else NavCache.of(cache_dir or default_cache_dir(), cache_max),
        nav_build=nav_build, behaviour=behaviour, prey=prey, creatures=creatures,
        workers=workers, cobra=cobra, sun_path=sun_path, clips=clips,
        root_motion=root_motion, max_memory_mb=max_memory, tolerance=tolerance,
        rotations=rotations, preview=preview,
    )
    check_outputs(cfg.output_paths())
    # (--rig r.json or r.usd with --out r: the bake was written over the rig it read)
    check_not_inputs(cfg.output_paths(), {"environment": Path(cfg.environment),
                                          "rig": Path(rig_path)})
    result = with_progress(run_bake, cfg)
    m = result.report["metrics"]
    files = ", ".join(str(p) for p in result.outputs.values())
    crowd = result.report.get("creatures") or ()
    if crowd:                        # --creatures N: the distance every creature walked
        walked = sum(c["metrics"]["distance_walked_m"] for c in crowd)
        bls = sum(c["metrics"]["distance_walked_body_lengths"] for c in crowd)
        what = f"{len(crowd)} creatures x {m['frames']} frames, walked {walked:.2f} m in all"
    else:
        walked, bls = m["distance_walked_m"], m["distance_walked_body_lengths"]
        what = f"{m['frames']} frames, walked {walked:.2f} m"
    click.echo(f"baked {what} ({bls:.1f} body lengths) -> {files} "
               f"in {time.perf_counter() - t0:.2f} s")


@cli.command()
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=_default_rig, show_default="rigs/scolopendra.toml", help="Rig definition (TOML).")
@click.option("--out", type=click.Path(), default="outputs", show_default=True,
              help="Output folder (created if needed): writes cycles.glb, cycles.usd and "
                   "cycles.json in it.")
@click.option("--speeds", default=None, metavar="WALK,RUN",
              help="Walk and run speeds in body lengths per second (walk 0.2-2, run 0.2-3) "
                   "[default: the rig's max speed and max speed x onslaught speed: 0.8,1.6]. "
                   "The turns walk at the walk speed.")
@click.option("--fps", type=int, default=30, show_default=True,
              help="Export frame rate; must divide the 240 Hz simulation rate.")
def cycles(rig_path, out, speeds, fps):
    """Write a library of locomotion clips on flat ground, in root-motion layout.

    Loops (each repeats exactly; names end in _loop, which Godot imports as looping):
    walk_loop, run_loop, turn_left_walk_loop, turn_right_walk_loop, idle_loop. One-shots that
    start and end in idle_loop's first pose: cobra_rear, warning, strike.

    Root motion: every clip is in `root` mode. A top joint `root` on the ground under the
    body's centre carries the horizontal motion and the yaw, starting at the origin facing +Z;
    the rest of the skeleton moves relative to it (Unreal's root bone, Unity's Animator root
    motion, Godot's root_motion_track = "Skeleton3D:root")."""
    from baker.config import load_rig_config
    from baker.cycles import CyclesConfig, bake_cycles, validate_cycles

    t0 = time.perf_counter()
    out = Path(_given_out(out, "a folder, e.g. outputs"))
    walk, run = parse_speeds(speeds)
    validate_cycles(CyclesConfig(out=out, fps=fps, walk_speed=walk, run_speed=run))
    if Path(out).exists() and not Path(out).is_dir():
        raise ConfigError("--out must be a folder (it names a file)", where=str(out))
    cfg = CyclesConfig(rig=load_rig_config(rig_path), out=out, fps=fps, walk_speed=walk,
                       run_speed=run)
    from baker.atomic import check_not_inputs

    # (--rig cycles.json in the --out folder: the summary was written over the rig read)
    check_not_inputs(cfg.output_paths(), {"rig": Path(rig_path)})
    result = with_progress(bake_cycles, cfg)
    clips = result.summary["clips"]
    loops = [c for c in clips if c["loop"]]
    click.echo(f"wrote {len(clips)} clips ({len(loops)} loops, largest seam error "
               f"{max(c['seam_error_m'] for c in loops):.1e} m, velocity mismatch "
               f"{max(c['velocity_mismatch'] for c in loops):.1e}) -> "
               f"{', '.join(str(p) for p in result.outputs.values())} in "
               f"{time.perf_counter() - t0:.2f} s")


def parse_speeds(text: str | None) -> tuple[float | None, float | None]:
    """--speeds WALK,RUN (body lengths per second) -> (walk, run); None: the defaults."""
    if text is None:
        return None, None
    form = "--speeds must be two numbers WALK,RUN in body lengths per second, e.g. 0.8,1.6"
    try:
        vals = tuple(float(x) for x in text.replace(" ", "").split(","))
    except ValueError:
        raise ConfigError(form, where="--speeds") from None
    if len(vals) != 2:
        raise ConfigError(form, where="--speeds")
    if vals[0] > vals[1]:
        raise ConfigError(f"--speeds: the walk ({vals[0]:g}) is faster than the run "
                          f"({vals[1]:g}); give WALK,RUN with WALK at most RUN", where="--speeds")
    return vals


def _given_out(out, example: str):
    """--out as given; an empty one is refused (it named the current folder)."""
    if out is not None and not str(out).strip():
        raise ConfigError(f"--out is empty: give {example}", where="--out")
    return out


@cli.command()
@click.argument("environment", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=_default_rig, show_default="rigs/scolopendra.toml",
              help="Rig whose navigation agent sizes are used.")
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Draw a top-down map of the walkable area (coloured by component) to this PNG.")
@click.option("--from", "path_from", default=None, metavar="X,Y,Z",
              help="Find a path from this point (with --to); drawn on the --png map.")
@click.option("--to", "path_to", default=None, metavar="X,Y,Z", help="Path goal (with --from).")
@up_option
@units_option
@click.option("--cache-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Navigation cache folder [default: ~/.cache/baker/navmesh].")
@click.option("--no-cache", is_flag=True, help="Build without reading or writing the cache.")
@click.option("--cache-max", type=float, default=None, metavar="MB",
              help="Bound of the navigation cache folder in MB; least recently used entries "
                   "are evicted [default: 1024].")
@max_memory_option
@rig_options
def navmesh(environment, rig_path, png, path_from, path_to, up, units, cache_dir, no_cache,
            cache_max, max_memory,
            **rig_overrides):
    """Build (or load from the cache) the navigation surface of ENVIRONMENT and report on it.

    The surface is cached where `baker bake` looks for it, so a later bake skips the build."""
    from baker.config import load_rig_config, override_rig
    from baker.schema import check_point

    validate_memory(max_memory, cache_max)
    p_from, p_to = parse_vec3(path_from, "--from"), parse_vec3(path_to, "--to")
    check_point(p_from, "--from")
    check_point(p_to, "--to")
    check_rig_overrides(rig_overrides)
    from baker.navmesh.cache import NavCache
    from baker.navmesh.report import format_report, run

    rig = override_rig(load_rig_config(rig_path), **rig_overrides)
    report = run(environment, rig.navigation,
                 None if no_cache else NavCache.of(cache_dir or default_cache_dir(), cache_max),
                 png=png, path_from=p_from, path_to=p_to, max_memory_mb=max_memory,
                 up_axis=up, units=units)
    click.echo(format_report(report))


@cli.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--no-validate", is_flag=True,
              help="Skip the validator (Khronos glTF-Validator for a GLB, UsdValidation for a USD).")
@click.option("--judge", is_flag=True,
              help="Also judge a GLB's motion against the quality limits (skate, penetration, "
                   "rotation, spacing, ...) from the files alone; exit 1 when one fails.")
def inspect(file, as_json, no_validate, judge):
    """Summarize a file baker wrote: a GLB or USD (skeleton, clips with durations, key counts
    and loop flags, size breakdown, validator result, embedded metadata) or a bake's JSON report.

    The Khronos glTF-Validator runs when node and the gltf-validator npm package are installed
    (npm install -g gltf-validator, or BAKER_GLTF_VALIDATOR=<its folder>). --judge reads every
    creature of a GLB (and the bake's USD beside it, compared joint by joint) and judges it as
    benchmarks/quality_sweep.py does."""
    from baker.inspect_file import (format_judged, format_report, inspect_file, judge_file,
                                    report_json)

    report = inspect_file(file, validate=not no_validate)
    judged = judge_file(file) if judge else None
    if as_json:
        if judged is not None:
            report["judged"] = judged
        click.echo(report_json(report))
    else:
        click.echo(format_report(report) + ("\n" + format_judged(judged) if judged else ""))
    return 1 if judged and any(j["failures"] for j in judged) else 0


def with_progress(run, cfg):
    """run(cfg, ctx=...) with a terminal progress display, closed whatever happens."""
    from baker.context import Context, TerminalProgress

    progress = TerminalProgress()
    try:
        return run(cfg, ctx=Context(progress=progress))
    finally:
        progress.close()


def check_rig_overrides(rig_overrides: dict) -> None:
    """The rig options' values (schema.Options), checked before the rig file is read."""
    from baker.config import RigConfig, override_rig

    override_rig(RigConfig(), **rig_overrides)


def validate_memory(max_memory, cache_max=None) -> None:
    """--max-memory and --cache-max (schema.Options), checked before anything is read."""
    from baker.schema import validate_options

    validate_options(max_memory=max_memory, cache_max=cache_max)


@cli.command()
@click.argument("jobs_file", metavar="JOBS.toml", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Output folder: <job name>.glb/.usd/.json per job and manifest.json "
                   "[default: outputs/<jobs file name>].")
@click.option("--workers", type=click.IntRange(1, 1024), default=None, metavar="N",
              help="Local worker processes [default: the core count].")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the jobs on this Dask scheduler (tcp://host:8786) instead of a local "
                   "pool; needs baker[dask] and paths shared by every worker.")
@click.option("--force", is_flag=True,
              help="Bake every job, even those whose outputs are up to date.")
@click.option("--job-timeout", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="S", help="Fail a job that runs longer than S seconds [default: no limit].")
@click.option("--retries", type=click.IntRange(0, 100), default=1, show_default=True,
              metavar="N", help="Run a task again, up to N times, when its worker died (a crash, "
                                "a lost Dask worker); a job that fails is not run again.")
@click.option("--cache-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Navigation cache folder, shared by every job and worker "
                   "[default: ~/.cache/baker/navmesh].")
@click.option("--cache-max", type=float, default=None, metavar="MB",
              help="Bound of the navigation cache folder in MB [default: 1024].")
@click.pass_context
def batch(ctx, jobs_file, out_dir, workers, scheduler, force, job_timeout, retries, cache_dir,
          cache_max):
    """Bake every job of JOBS.toml: [defaults] and [[job]] entries with `bake`'s options, lists
    expanded by [job.matrix]. Up-to-date outputs are skipped; a failing job does not stop the
    others (exit code 1 when any failed). See DIR/manifest.json."""
    from baker import batch as batch_mod
    from baker.navmesh.cache import NavCache

    validate_memory(None, cache_max)
    # an empty --out is refused, as bake's is (the jobs were baked into the working folder)
    out_dir = _given_out(out_dir, "a folder, e.g. outputs/jobs")
    out_dir = None if out_dir is None else Path(out_dir)
    if job_timeout is not None and math.isnan(job_timeout):     # FloatRange lets NaN through
        raise ConfigError("--job-timeout must be a number of seconds > 0 (got nan)",
                          where="--job-timeout")
    summary = batch_mod.run(jobs_file, out=out_dir, workers=workers, scheduler=scheduler,
                            force=force, job_timeout=job_timeout, retries=retries,
                            cache=NavCache.of(cache_dir or default_cache_dir(), cache_max))
    click.echo(summary.line)
    if summary.failed:
        ctx.exit(1)


@cli.command()
@click.argument("file", metavar="FILE.glb", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(), default=None, metavar="PNG_PREFIX",
              help="Path prefix of the pictures: PREFIX_map.png, PREFIX_sheet.png (and "
                   "PREFIX.gif); a folder writes <folder>/<FILE's stem>_map.png, ... "
                   "[default: beside FILE].")
@click.option("--gif", is_flag=True,
              help="Also write an animated GIF of the whole bake (320x180, twice real time).")
@click.option("--frames", type=int, default=9, show_default=True,
              help="Frames on the contact sheet, 6 to 12.")
def preview(file, out, gif, frames):
    """Draw the pictures of a bake from its GLB: a top-down map (walkable area, shade at the
    start and at the end, the trail coloured by behaviour, foot contacts, prey paths, the
    behaviour timeline) and a contact sheet of frames ray-cast on the CPU (Embree) from a
    three-quarter view following the creature, with the sun's shadows; --gif adds an
    animation. Needs baker[preview] (matplotlib)."""
    from baker.export.preview import write_preview

    t0 = time.perf_counter()
    out = _given_out(out, "a path prefix for the pictures, e.g. outputs/centipede")
    written = write_preview(file, out, frames=frames, gif=gif)
    click.echo(f"wrote {', '.join(str(p) for p in written.values())} in "
               f"{time.perf_counter() - t0:.2f} s")


class _HeldLog(logging.Handler):
    """Holds log records and Python warnings while a command runs: on success they are printed
    (in order) when it ends; a rejected input prints only its one error line."""

    def __init__(self):
        super().__init__(level=logging.NOTSET)
        self.records: list = []
        self.live: logging.Handler | None = None

    def emit(self, record):
        if self.live is not None:
            self.live.handle(record)
        else:
            self.records.append(record)

    def release(self, live: bool = False):
        out = logging.StreamHandler(sys.stderr)
        out.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
        for r in self.records:
            out.handle(r)
        self.records.clear()
        if live:
            self.live = out

    def drop(self):
        self.records.clear()


_HELD = _HeldLog()


def _too_long(e: OSError) -> ConfigError:
    """The user error for a path the file system refuses as too long (ENAMETOOLONG: one name
    over NAME_MAX, or the whole path over PATH_MAX), from whichever command met it."""
    name = os.fsdecode(e.filename) if e.filename is not None else ""
    worst = max(name.split(os.sep), key=lambda part: len(os.fsencode(part)), default="")
    return ConfigError(f"path is too long for the file system ({len(os.fsencode(name))} bytes, "
                       f"its longest name {len(os.fsencode(worst))}): {short_path(name)}",
                       where="path")


def _stdout_failed(e: OSError) -> bool:
    """Whether `e` came from writing to standard output (click.echo: the summary, a report,
    --help) on a full disk or a closed pipe; stdout is then pointed at os.devnull, so that
    nothing more fails on it (the interpreter's own flush at exit among it)."""
    tb = e.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    if tb is None or tb.tb_frame.f_code.co_name != "echo" \
            or tb.tb_frame.f_globals.get("__name__") != "click.utils":
        return False
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
        os.close(fd)
    except (OSError, ValueError, AttributeError):
        pass
    return True


def run_command(argv=None) -> int:
    """Run the click command; user errors become one line `Error: <what> (<where>)` on stderr
    and EXIT_USAGE. Logs and warnings of a run are held and printed only if it succeeds."""
    root = logging.getLogger()
    old_level = root.level
    _HELD.records.clear()
    _HELD.live = None
    root.addHandler(_HELD)
    held_warnings = []
    error = None
    code = 0
    try:
        with warnings.catch_warnings(record=True) as held_warnings:
            try:
                code = cli.main(args=argv, prog_name="baker", standalone_mode=False)
            except click.exceptions.Exit as e:
                return int(e.exit_code or 0)
            except click.exceptions.NoArgsIsHelpError as e:  # bare `baker`: the help, as click
                click.echo(e.ctx.get_help() if e.ctx else "")
                return EXIT_USAGE
            except click.ClickException as e:
                error = format_error(ConfigError(e.format_message(), where="command line"))
            except BakerError as e:
                error = format_error(e)
            except OSError as e:
                if e.errno == errno.ENAMETOOLONG:
                    error = format_error(_too_long(e))
                elif e.filename is None and _stdout_failed(e):
                    # a full disk or a closed pipe behind stdout (the summary, --help)
                    error = format_error(ConfigError(
                        f"cannot write to standard output ({e.strerror or e})", where="stdout"))
                elif e.errno in (errno.EACCES, errno.EPERM) and e.filename is not None:
                    # a file, or a folder on its way, this user may not read, search or write
                    error = format_error(ConfigError(
                        f"permission denied: {short_path(os.fsdecode(e.filename))}",
                        where="path"))
                elif e.errno in (errno.ENOENT, errno.ENOTDIR) and e.filename is not None:
                    # a file checked, then gone (or its folder replaced) before it was read
                    error = format_error(ConfigError(
                        f"{e.strerror or 'no such file'}: {short_path(os.fsdecode(e.filename))}"
                        " (removed or replaced while baker ran)", where="path"))
                else:
                    raise
            except MemoryError as e:    # the input asks for more than the machine gives
                error = format_error(ConfigError(
                    f"out of memory ({str(e) or 'an allocation failed'}): this level, rig and "
                    "options need more memory than this process may use; use a larger "
                    "--cell-size, a rig with fewer segments, fewer creatures or a shorter bake",
                    where="memory"))
    except BaseException:       # a signal (entry.py prints its one line): nothing held is shown
        error = ""
        raise
    finally:
        root.removeHandler(_HELD)
        root.setLevel(old_level)
        if error is not None:
            _HELD.drop()
        else:
            _HELD.release()
            for w in held_warnings:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        _HELD.live = None
    if error is not None:
        sys.stderr.write(error + "\n")
        sys.stderr.flush()
        return EXIT_USAGE
    return code if isinstance(code, int) and not isinstance(code, bool) else 0  # ctx.exit(n)


def main(argv=None) -> int:
    """Entry point: see run_command."""
    try:
        return run_command(argv)
    except click.exceptions.Abort:
        click.echo("error: aborted", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("error: interrupted", err=True)
        return 130


if __name__ == "__main__":
    sys.exit(main())
