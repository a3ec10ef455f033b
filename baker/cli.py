"""Command-line interface. Commands only build a config and call the pipeline."""

from __future__ import annotations

import logging
import os
import sys
import time
from pathlib import Path

import click

from baker.config import DEFAULT_ENVIRONMENT, DEFAULT_RIG, BakeConfig, load_rig_config
from baker.errors import BakerError, ConfigError


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "baker" / "navmesh"


def parse_vec3(text: str | None, what: str):
    if text is None:
        return None
    try:
        vals = tuple(float(x) for x in text.replace(" ", "").split(","))
    except ValueError:
        raise ConfigError(f"{what} must be three comma-separated numbers, e.g. 0.3,1,0.2") from None
    if len(vals) != 3:
        raise ConfigError(f"{what} must be three comma-separated numbers, e.g. 0.3,1,0.2")
    return vals


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="baker")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose: int):
    """baker: bake a procedural centipede walking over an environment into GLB and USD."""
    level = logging.WARNING - 10 * min(verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")


@cli.command()
@click.argument("environment", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--seconds", type=float, default=20.0, show_default=True, help="Simulated duration.")
@click.option("--fps", type=int, default=30, show_default=True,
              help="Export frame rate; must divide the 240 Hz simulation rate.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=DEFAULT_RIG, show_default="rigs/scolopendra.toml", help="Rig definition (TOML).")
@click.option("--out", type=click.Path(path_type=Path), default=Path("outputs/centipede"),
              show_default=True, help="Output path without extension.")
@click.option("--format", "fmt", type=click.Choice(["glb", "usd", "both"]), default="both",
              show_default=True, help="Which animation files to write (the JSON report is always written).")
@click.option("--usda", is_flag=True, help="Write the USD as ASCII (.usda) instead of crate (.usd).")
@click.option("--sun", default=None, metavar="X,Y,Z",
              help="Direction toward the sun; overrides the environment's light.")
@click.option("--debug-navmesh", is_flag=True, help="Add the walkable surface as an extra mesh layer.")
@click.option("--cache-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Navigation cache folder [default: ~/.cache/baker/navmesh].")
@click.option("--no-cache", is_flag=True, help="Always rebuild the navigation surface.")
def bake(environment, seconds, fps, seed, rig_path, out, fmt, usda, sun, debug_navmesh,
         cache_dir, no_cache):
    """Bake a centipede on ENVIRONMENT (glTF/GLB, OBJ, PLY, STL or USD).

    With no ENVIRONMENT, the bundled rainforest floor is used."""
    from baker.context import Context, TerminalProgress
    from baker.pipeline import bake as run_bake

    t0 = time.perf_counter()
    usd_fmt = "usda" if usda else "usd"
    formats = {"glb": ("glb",), "usd": (usd_fmt,), "both": ("glb", usd_fmt)}[fmt]
    cfg = BakeConfig(
        environment=environment or DEFAULT_ENVIRONMENT,
        seconds=seconds, fps=fps, seed=seed, rig=load_rig_config(rig_path), out=out,
        formats=formats, sun_direction=parse_vec3(sun, "--sun"), debug_navmesh=debug_navmesh,
        nav_cache_dir=None if no_cache else (cache_dir or default_cache_dir()),
    )
    progress = TerminalProgress()
    try:
        result = run_bake(cfg, ctx=Context(progress=progress))
    finally:
        progress.close()
    m = result.report["metrics"]
    files = ", ".join(str(p) for p in result.outputs.values())
    click.echo(f"baked {m['frames']} frames, walked {m['distance_walked_m']:.2f} m "
               f"({m['distance_walked_body_lengths']:.1f} body lengths) -> {files} "
               f"in {time.perf_counter() - t0:.2f} s")


def main(argv=None) -> int:
    """Entry point: user errors become one line on stderr and exit code 2."""
    try:
        cli.main(args=argv, prog_name="baker", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("error: aborted", err=True)
        return 2
    except click.ClickException as e:
        click.echo(f"error: {e.format_message()}", err=True)
        return 2
    except BakerError as e:
        click.echo(f"error: {str(e).splitlines()[0] if str(e) else type(e).__name__}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("error: interrupted", err=True)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
