"""Pictures of a bake, from its GLB alone: a top-down map (preview_map), a contact sheet of
frames rendered by Embree ray casting (render), and optionally an animated GIF.

    write_preview("outputs/centipede.glb")   # outputs/centipede_map.png, centipede_sheet.png
    preview_images(glb_bytes, gif=True)      # {"map": png, "sheet": png, "gif": gif} bytes

`baker preview FILE.glb` and `baker bake --preview` call these. The map needs matplotlib (the
`preview` extra); the frames need only Embree and Pillow. All files are written together or
not at all (atomic.OutputSet). The same GLB gives the same bytes.
"""

from __future__ import annotations

import importlib.util
import io
import logging
import os
from pathlib import Path

import numpy as np

from baker.config import PREVIEW_SUFFIXES
from baker.errors import ConfigError

log = logging.getLogger(__name__)

#: contact sheet: frames (default and bounds) and the size of each frame in pixels
SHEET_FRAMES, SHEET_MIN, SHEET_MAX = 9, 6, 12
TILE = (640, 360)
#: animated GIF: frame size, most frames, playback speed (x real time)
GIF_SIZE, GIF_MAX_FRAMES, GIF_SPEED = (320, 180), 300, 2.0
MATPLOTLIB_MISSING = "the preview's map needs matplotlib: pip install 'baker[preview]'"


def check_dependencies(where: str = "baker preview") -> None:
    """ConfigError (one line) when matplotlib, which draws the map, is not installed."""
    if importlib.util.find_spec("matplotlib") is None:
        raise ConfigError(MATPLOTLIB_MISSING, where=where)


def check_frames(frames: int) -> int:
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) \
            or not SHEET_MIN <= frames <= SHEET_MAX:
        raise ConfigError(f"--frames must be an integer from {SHEET_MIN} to {SHEET_MAX} "
                          f"(got {frames})", where="--frames")
    return int(frames)


def preview_paths(prefix: Path, gif: bool = False) -> dict[str, Path]:
    """{"map", "sheet"[, "gif"]: path}: PREFIX_map.png, PREFIX_sheet.png, PREFIX.gif."""
    prefix = Path(prefix)
    keys = ("map", "sheet", "gif") if gif else ("map", "sheet")
    return {k: prefix.with_name(prefix.name + PREVIEW_SUFFIXES[k]) for k in keys}


def resolve_prefix(glb: Path, out: Path | str | None) -> Path:
    """The pictures' path prefix: beside the GLB (its path less the suffix) by default; an
    existing folder or a value ending in a separator means <folder>/<GLB stem>."""
    from baker.atomic import is_folder, is_special
    from baker.errors import ExportError

    glb = Path(glb)
    if out is None:
        return glb.with_suffix("")
    text = os.fspath(out)
    if text.endswith(os.sep) or is_folder(Path(text)):
        return Path(text) / glb.stem
    if is_special(Path(text)):    # (--out /dev/null wrote /dev/null_map.png beside the device)
        raise ExportError(f"--out {text!r} is a device, pipe or socket, not a path: give a "
                          "folder or a path prefix, e.g. outputs/centipede", where="--out")
    return Path(text)


# ---------------------------------------------------------------- frames


def sheet_frames(scene, count: int = SHEET_FRAMES) -> np.ndarray:
    """(count,) sorted distinct frames: the middles of `count` equal slices of the bake, moved
    so that every behaviour state of the timeline appears when there are enough frames (a
    state without a frame takes the frame nearest its longest segment's middle, from a state
    that has more than one)."""
    n = scene.n_frames
    frames = np.round((np.arange(count) + 0.5) / count * (n - 1)).astype(np.int64)
    if len(scene.states) and count <= n:
        longest: dict[str, tuple[float, int]] = {}
        for t0, t1, s in scene.segments:
            mid = int(round((t0 + t1) / 2.0 * scene.fps))
            if t1 - t0 > longest.get(s, (-1.0, 0))[0]:
                longest[s] = (t1 - t0, min(max(mid, 0), n - 1))
        for s, (_, mid) in longest.items():
            shown = scene.state[frames]
            k = scene.states.index(s)
            if np.any(shown == k):
                continue
            counts = np.bincount(shown[shown >= 0], minlength=len(scene.states))
            spare = [i for i in range(count) if shown[i] < 0 or counts[shown[i]] > 1]
            if spare and mid not in frames:
                frames[min(spare, key=lambda i: (abs(int(frames[i]) - mid), i))] = mid
    return np.sort(frames)


def _label(img, text: str, color, size: int):
    from PIL import ImageDraw, ImageFont

    draw = ImageDraw.Draw(img, "RGBA")
    font = ImageFont.load_default(size=size)
    x0, y0, x1, y1 = draw.textbbox((0, 0), text, font=font)
    pad = max(size // 3, 2)
    sw = size                                   # the state's colour swatch
    draw.rectangle((0, 0, sw + 3 * pad + x1 - x0, y1 - y0 + 2 * pad + 1), fill=(0, 0, 0, 150))
    draw.rectangle((pad, pad, pad + sw - 1, pad + y1 - y0), fill=color)
    draw.text((sw + 2 * pad - x0, pad - y0), text, fill=(255, 255, 255), font=font)


def _state_rgb(scene, f: int):
    from baker.export.preview_map import state_color

    s = scene.state[f]
    hexa = state_color(scene.states[s], scene.states) if s >= 0 else "#000000"
    return tuple(int(hexa[i:i + 2], 16) for i in (1, 3, 5))


def _frame_text(scene, f: int, number: int | None = None) -> str:
    s = scene.state[f]
    name = scene.states[s] if s >= 0 else ""
    head = f"{number}  " if number is not None else ""
    return f"{head}{f / scene.fps:5.1f} s  {name}"


def render_sheet(scene, env, frames, tile=TILE):
    """(PIL image of the contact sheet, [render.Frame], [render.Camera]): `frames` rendered
    tile[0] x tile[1] each, numbered, three per row (four from 10 frames up)."""
    from PIL import Image

    from baker.export.render import follow_cameras, render_frame

    cams = follow_cameras(scene, frames, env)
    shots = [render_frame(scene, int(f), c, tile[0], tile[1], env) for f, c in zip(frames, cams)]
    cols = 3 if len(frames) <= 9 else 4
    rows = -(-len(frames) // cols)
    gap = 6
    sheet = Image.new("RGB", (cols * tile[0] + (cols - 1) * gap,
                              rows * tile[1] + (rows - 1) * gap), (24, 24, 24))
    for k, (f, shot) in enumerate(zip(frames, shots)):
        img = Image.fromarray(shot.rgb)
        _label(img, _frame_text(scene, int(f), k + 1), _state_rgb(scene, int(f)), 16)
        sheet.paste(img, ((k % cols) * (tile[0] + gap), (k // cols) * (tile[1] + gap)))
    return sheet, shots, cams


def png_bytes(img) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def gif_bytes(scene, env, size=GIF_SIZE) -> bytes:
    """The whole bake as an animated GIF: a frame every `step` bake frames (at most
    GIF_MAX_FRAMES), played GIF_SPEED times faster than real time, one shared palette."""
    from PIL import Image

    from baker.export.render import follow_cameras, render_frame

    step = max(1, -(-scene.n_frames // GIF_MAX_FRAMES))
    frames = np.arange(0, scene.n_frames, step)
    cams = follow_cameras(scene, frames, env)
    images = []
    for f, cam in zip(frames, cams):
        img = Image.fromarray(render_frame(scene, int(f), cam, size[0], size[1], env).rgb)
        _label(img, _frame_text(scene, int(f)), _state_rgb(scene, int(f)), 11)
        images.append(img)
    sample = images[:: max(1, len(images) // 16)]
    mosaic = Image.new("RGB", (size[0], size[1] * len(sample)))
    for k, img in enumerate(sample):
        mosaic.paste(img, (0, k * size[1]))
    palette = mosaic.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    pal = [img.quantize(palette=palette, dither=Image.Dither.NONE) for img in images]
    ms = max(20, int(round(1000.0 * step / scene.fps / GIF_SPEED / 10.0)) * 10)
    buf = io.BytesIO()
    pal[0].save(buf, format="GIF", save_all=True, append_images=pal[1:], duration=ms, loop=0,
                optimize=False, disposal=1)
    return buf.getvalue()


# ---------------------------------------------------------------- the pictures


def preview_images(source, frames: int = SHEET_FRAMES, gif: bool = False,
                   name: str | None = None) -> dict[str, bytes]:
    """{"map", "sheet"[, "gif"]: file bytes} of a bake's GLB (a path or its bytes).
    InspectError (one line) for a file that is not a bake; ConfigError for bad options or a
    missing matplotlib."""
    from baker.export.preview_map import draw_map
    from baker.export.preview_scene import load_bake
    from baker.export.render import environment_caster

    frames = check_frames(frames)
    check_dependencies()
    scene = load_bake(source, name=name)
    env = environment_caster(scene)
    chosen = sheet_frames(scene, frames)
    sheet, _, _ = render_sheet(scene, env, chosen)
    out = {"map": draw_map(scene, env, chosen), "sheet": png_bytes(sheet)}
    if gif:
        out["gif"] = gif_bytes(scene, env)
    return out


def write_preview(glb: Path | str, out: Path | str | None = None, frames: int = SHEET_FRAMES,
                  gif: bool = False) -> dict[str, Path]:
    """Write the pictures of a GLB (see preview_paths, resolve_prefix), all or none.
    Returns {"map", "sheet"[, "gif"]: path}."""
    from baker.atomic import OutputSet, check_not_inputs, check_outputs

    frames = check_frames(frames)
    check_dependencies()
    paths = preview_paths(resolve_prefix(Path(glb), out), gif)
    check_outputs(paths)
    check_not_inputs(paths, {"GLB": Path(glb)})     # (a GLB named x_map.png, --out x: over it)
    images = preview_images(Path(glb), frames=frames, gif=gif)
    with OutputSet(paths) as files:
        for key, data in images.items():
            files.write_bytes(key, data)
        return files.commit()
