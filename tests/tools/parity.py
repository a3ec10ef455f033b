"""Every joint's world position at given times, as each tool a user might load a bake with sees
it: three.js (GLTFLoader + AnimationMixer, tests/tools/three_probe.mjs), usd-core (UsdSkel),
and Blender importing the GLB or the USD (tests/tools/blender_probe.py, with bpy).

Each probe returns (joint names, (T, J, 3) float64 metres, world, +Y up): Blender's Z-up
positions are turned back to +Y up here. Times are seconds from the clip's start.

    three_positions(glb, "bake", times)
    usd_positions(usd, times)                       # the bound SkelAnimation
    usd_positions(usd_with_clip(usd, "wander_00", out), times)
    blender_positions(exe, glb_or_usd, fps, times, clip="wander_00")
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

TOOLS = Path(__file__).resolve().parent
THREE_PROBE = TOOLS / "three_probe.mjs"
BLENDER_PROBE = TOOLS / "blender_probe.py"
#: where baker writes the creature in a USD file
SKELETON = "/World/Centipede/Skeleton"
CLIPS = "/World/Centipede/Clips"


def _times_arg(times) -> str:
    return ",".join(repr(float(t)) for t in times)


def three_positions(glb: Path, clip: str, times) -> tuple[list[str], np.ndarray]:
    """three.js: GLTFLoader.parse the GLB, play `clip` once on an AnimationMixer, and read
    every bone's getWorldPosition at each time. Skips when node/npm are missing."""
    from validator import ensure_node

    node = ensure_node("the three.js probe")
    r = subprocess.run([node, str(THREE_PROBE), str(Path(glb).resolve()), clip, _times_arg(times)],
                       cwd=TOOLS, capture_output=True, text=True, timeout=600,
                       env={**os.environ, "NODE_NO_WARNINGS": "1"})
    if r.returncode != 0:
        raise RuntimeError(f"three_probe failed ({r.returncode}):\n{r.stderr[-3000:]}")
    d = json.loads(r.stdout)
    return d["bones"], np.asarray(d["positions"], dtype=np.float64)


def usd_positions(usd: Path, times) -> tuple[list[str], np.ndarray]:
    """usd-core: SkeletonQuery.ComputeJointWorldTransforms of the first Skeleton (posed by its
    bound animation, composed with its ancestors' transforms) at time code t * fps."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(usd))
    skel_prim = stage.GetPrimAtPath(SKELETON)
    root = UsdSkel.Root.Find(skel_prim)
    cache = UsdSkel.Cache()
    cache.Populate(root, Usd.TraverseInstanceProxies())
    query = cache.GetSkelQuery(UsdSkel.Skeleton(skel_prim))
    names = [str(j).rsplit("/", 1)[-1] for j in query.GetJointOrder()]
    fps = stage.GetTimeCodesPerSecond()
    xf = UsdGeom.XformCache()
    out = np.empty((len(times), len(names), 3))
    for k, t in enumerate(times):
        xf.SetTime(Usd.TimeCode(float(t) * fps))
        m = np.array(query.ComputeJointWorldTransforms(xf, False))      # row vectors
        out[k] = m[:, 3, :3]
    return names, out


def usd_with_clip(usd: Path, clip: str, out: Path) -> Path:
    """A small layer over `usd` (as a sublayer) whose Skeleton plays the SkelAnimation
    Clips/<clip> instead of the bound one, with the stage metadata and the time range of that
    clip: how a USD user picks a clip, and the only way Blender's USD importer (which reads the
    bound animation) sees it. Returns `usd` itself when `clip` is the bound animation."""
    from pxr import Sdf, Usd, UsdGeom, UsdSkel

    base = Usd.Stage.Open(str(usd))
    bound = UsdSkel.BindingAPI(base.GetPrimAtPath(SKELETON)).GetAnimationSourceRel().GetTargets()
    anim = base.GetPrimAtPath(f"{CLIPS}/{clip}")
    if not anim:
        if bound and bound[0].name == clip or clip == "bake":
            return Path(usd)
        raise KeyError(f"{usd} has no clip {clip!r}")
    codes = UsdSkel.Animation(anim).GetTranslationsAttr().GetTimeSamples()
    stage = Usd.Stage.CreateNew(str(out))
    stage.GetRootLayer().subLayerPaths.append(os.path.relpath(usd, Path(out).parent))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.GetStageUpAxis(base))
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.GetStageMetersPerUnit(base))
    stage.SetTimeCodesPerSecond(base.GetTimeCodesPerSecond())
    stage.SetFramesPerSecond(base.GetFramesPerSecond())
    stage.SetStartTimeCode(codes[0])
    stage.SetEndTimeCode(codes[-1])
    stage.SetDefaultPrim(stage.OverridePrim("/World"))
    skel = stage.OverridePrim(SKELETON)
    UsdSkel.BindingAPI(skel).CreateAnimationSourceRel().SetTargets([Sdf.Path(f"{CLIPS}/{clip}")])
    stage.GetRootLayer().Save()
    return Path(out)


def blender_python() -> str:
    """BAKER_BLENDER_PYTHON (a Python with bpy); skips the test without it."""
    exe = os.environ.get("BAKER_BLENDER_PYTHON", "")
    if not exe or not shutil.which(exe):
        pytest.skip("set BAKER_BLENDER_PYTHON to a Python with bpy to run the Blender checks")
    return exe


def blender_probe(exe: str, path: Path, fps: int, *args: str) -> dict:
    r = subprocess.run([exe, str(BLENDER_PROBE), str(path), str(fps), *args],
                       capture_output=True, text=True, timeout=600)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("PROBE_JSON ")]
    if not lines:
        raise RuntimeError(f"Blender probe failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return json.loads(lines[-1][len("PROBE_JSON "):])


def blender_positions(exe: str, path: Path, fps: int, times,
                      clip: str | None = None) -> tuple[list[str], np.ndarray]:
    """Blender: import the GLB or USD (scene fps = `fps`), play `clip` (a GLB's animation; for a
    USD pass a usd_with_clip layer instead), and read every pose bone's head in world space at
    frame t * fps (between frames as a subframe); converted from Blender's Z-up to +Y up."""
    args = ["--times", _times_arg(times)] + (["--clip", clip] if clip is not None else [])
    d = blender_probe(exe, Path(path), fps, *args)
    z_up = np.asarray(d["samples"], dtype=np.float64)                  # (T, J, 3)
    return d["bones"], np.stack([z_up[..., 0], z_up[..., 2], -z_up[..., 1]], axis=-1)


def aligned(names: list[str], positions: np.ndarray, order: list[str]) -> np.ndarray:
    """positions (T, J, 3) over `names`, reordered to `order` (every name must be there)."""
    index = {n: k for k, n in enumerate(names)}
    missing = [n for n in order if n not in index]
    if missing:
        raise KeyError(f"joints missing: {missing[:5]} ({len(missing)})")
    return positions[:, [index[n] for n in order]]
