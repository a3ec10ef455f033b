"""Regenerate the README's pictures of the default bake: docs/preview_map.png and
docs/preview_sheet.png.

Bakes `baker bake` with no options (the default scene, seconds, seed, prey and sun, whatever
they are in the current code: the showcase's minute with 2 prey) into a temporary folder,
then draws its map and contact sheet
with `baker preview`'s code. The sheet is stored with a 256-colour palette to keep it small
(< 400 kB); otherwise both are the pictures `baker preview` writes. Run from the repo root:

    python docs/make_pictures.py
"""

from __future__ import annotations

import io
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

from baker.atomic import atomic_write_bytes
from baker.export.preview import preview_images

DOCS = Path(__file__).resolve().parent
LIMIT = 400 * 1024


def small_png(png: bytes) -> bytes:
    """The same picture with a 256-colour palette (median cut, no dithering: deterministic)."""
    img = Image.open(io.BytesIO(png)).convert("RGB")
    pal = img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    pal.save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "centipede"
        subprocess.run([sys.executable, "-m", "baker", "bake", "--format", "glb",
                        "--out", str(out)], check=True)
        pictures = preview_images(out.with_suffix(".glb"))
    files = {DOCS / "preview_map.png": pictures["map"],
             DOCS / "preview_sheet.png": small_png(pictures["sheet"])}
    for path, data in files.items():
        if len(data) > LIMIT:
            raise SystemExit(f"{path.name} is {len(data) / 1024:.0f} kB, over the "
                             f"{LIMIT // 1024} kB the README allows")
        atomic_write_bytes(path, data)
        print(f"wrote {path.relative_to(DOCS.parent)} ({len(data) / 1024:.0f} kB)")


if __name__ == "__main__":
    main()
