"""Three-way parity: three.js (GLTFLoader + AnimationMixer), usd-core (UsdSkel) and Blender
(importing the GLB, and importing the USD) put every joint of a bake at the same world
position, within 1e-4 m, at sampled times on and between frames.

Each case is one `baker` command line and the clip to play; adding a bake option set (a root
motion mode, a keyframe tolerance, a cycle) is one line in CASES. usd-core is the reference
every other tool is compared with; the Blender test also compares the tools with each other.
The three.js test skips only when node/npm are missing (and fails in CI); the Blender test
skips without BAKER_BLENDER_PYTHON (a Python with bpy).
"""

from __future__ import annotations

import itertools
import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from baker.cli import main
from glb_read import Glb
from parity import (aligned, blender_positions, blender_python, three_positions,
                    usd_positions, usd_with_clip)

#: metres: the largest joint position difference allowed between two tools
TOLERANCE_M = 1e-4
#: where in the clip to sample, as fractions of its duration (a frame time is hit exactly only
#: at 0 and 1; the others fall between frames, where each tool interpolates on its own)
FRACTIONS = (0.0, 0.123, 0.37, 0.5, 0.81, 1.0)


@dataclass(frozen=True)
class Case:
    """id: the test id; argv: the `baker` command line, with {out} (a fresh folder) and
    {cache} (the session's navigation cache); clip: the animation to play, by name or by index
    in the GLB's animations; stem: the output files' name in {out} (<stem>.glb, <stem>.usd[a])."""

    id: str
    argv: str
    clip: str | int = "bake"
    stem: str = "c"


CASES = [
    Case("world", "bake --seconds 6 --seed 1 --out {out}/c --cache-dir {cache}"),
    Case("world_behaviour_clip",
         "bake --seconds 10 --clips --usda --out {out}/c --cache-dir {cache}", clip=-1),
    Case("root", "bake --seconds 6 --seed 4 --prey 1 --root-motion root --out {out}/c "
                 "--cache-dir {cache}"),
    Case("in_place", "bake --seconds 6 --seed 5 --root-motion in-place --out {out}/c "
                     "--cache-dir {cache}"),
    Case("in_place_behaviour_clip", "bake --seconds 8 --seed 6 --clips --root-motion in-place "
                                    "--out {out}/c --cache-dir {cache}", clip=1),
    Case("cycle_turn", "cycles --out {out}", clip="turn_left_walk_loop", stem="cycles"),
    Case("cycle_strike", "cycles --out {out}", clip="strike", stem="cycles"),
]


@pytest.fixture(scope="module")
def baked(tmp_path_factory, nav_cache_dir):
    """case -> (glb, usd, clip name, times in seconds); each command line is run once."""
    done: dict[str, tuple] = {}
    runs: dict[str, Path] = {}

    def get(case: Case):
        if case.id not in done:
            if case.argv not in runs:
                runs[case.argv] = out = tmp_path_factory.mktemp(case.id)
                argv = [a.format(out=out, cache=nav_cache_dir) for a in shlex.split(case.argv)]
                assert main(argv) == 0, argv
            out = runs[case.argv]
            glb = out / f"{case.stem}.glb"
            usd = next(p for p in (out / f"{case.stem}.usd", out / f"{case.stem}.usda")
                       if p.exists())
            g = Glb(glb.read_bytes())
            anims = g.doc["animations"]
            anim = anims[case.clip] if isinstance(case.clip, int) else next(
                a for a in anims if a["name"] == case.clip)
            duration = max(float(g.accessor(s["input"]).max()) for s in anim["samplers"])
            done[case.id] = (glb, usd, anim["name"], [f * duration for f in FRACTIONS])
        return done[case.id]

    return get


def positions(glb: Path, usd: Path, clip: str, times, tools, work: Path) -> dict:
    """{tool: (T, J, 3) world positions in usd-core's joint order} for "usd" and each of
    `tools` ("three", "blender_glb", "blender_usd"), for `clip` at `times` (seconds)."""
    clip_usd = usd_with_clip(usd, clip, work / f"{usd.stem}_{clip}.usda")
    names, ref = usd_positions(clip_usd, times)
    fps = int(Glb(glb.read_bytes()).doc["scenes"][0]["extras"]["fps"])
    probes = {
        "three": lambda: three_positions(glb, clip, times),
        "blender_glb": lambda: blender_positions(blender_python(), glb, fps, times, clip=clip),
        "blender_usd": lambda: blender_positions(blender_python(), clip_usd, fps, times),
    }
    out = {"usd": ref}
    for tool in tools:
        got_names, got = probes[tool]()
        assert sorted(got_names) == sorted(names), tool      # every joint, end joints included
        out[tool] = aligned(got_names, got, names)
    return out


def max_differences(pos: dict) -> dict[str, float]:
    """{"a-b": largest joint distance in metres over joints and times} for every pair."""
    return {f"{a}-{b}": float(np.linalg.norm(pos[a] - pos[b], axis=-1).max())
            for a, b in itertools.combinations(pos, 2)}


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_three_matches_usd(case, baked, tmp_path):
    glb, usd, clip, times = baked(case)
    assert len(times) >= 5
    pos = positions(glb, usd, clip, times, ("three",), tmp_path)
    diff = max_differences(pos)
    assert diff["usd-three"] <= TOLERANCE_M, diff
    # the clip moves: the comparison is not between two rest poses
    assert np.linalg.norm(pos["usd"][-1] - pos["usd"][0], axis=-1).max() > 0.01


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_blender_matches_usd_and_three(case, baked, tmp_path):
    blender_python()
    glb, usd, clip, times = baked(case)
    tools = ["blender_glb", "blender_usd"]
    try:
        from validator import ensure_node

        ensure_node("the three.js probe")
        tools.append("three")
    except pytest.skip.Exception:
        pass
    diff = max_differences(positions(glb, usd, clip, times, tools, tmp_path))
    assert max(diff.values()) <= TOLERANCE_M, diff


def test_three_and_blender_show_the_scene_extras(baked, tmp_path):
    """The bake's metadata is where users look: three.js `gltf.scene.userData`, Blender's
    scene custom properties (neither surfaces `asset.extras`)."""
    import json
    import subprocess

    from parity import THREE_PROBE, TOOLS, blender_probe
    from validator import ensure_node

    glb, _, _, _ = baked(CASES[0])
    node = ensure_node("the three.js probe")
    r = subprocess.run([node, str(THREE_PROBE), str(glb), "bake", "0"], cwd=TOOLS,
                       capture_output=True, text=True, timeout=600)
    user = json.loads(r.stdout)["userData"]
    assert user["seed"] == 1 and user["fps"] == 30 and user["timeline"]
    try:
        exe = blender_python()
    except pytest.skip.Exception:
        return
    props = blender_probe(exe, glb, 30, "0")["scene_properties"]
    assert {"seed", "fps", "timeline", "foot_contacts"} <= set(props)
