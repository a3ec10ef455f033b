"""Locomotion cycles (`baker cycles`): a clip library on flat ground, read it step by step.

    Step 1  a flat plane built in code, walkable everywhere, and its navigation surface
    Step 2  the rig
    Step 3  loops: walk, run, turn left and right at walk speed (plan_loop, then simulate)
    Step 4  idle (a loop) and the one-shots cobra_rear, warning and strike (blended from idle)
    Step 5  export: one GLB and one USD holding every clip, plus a JSON summary (OutputSet)

The creature is the bake's: the same agent, head, body and legs (sim.loop.simulate), driven by a
scripted intent (behaviour.script.ScriptedIntent) instead of the brain. Clips are written in
`root` mode (rootmotion.apply_root_motion): a `root` joint on the ground under the body's centre
carries the horizontal motion and the yaw, starting at the origin facing +Z, and every other
joint moves relative to it.

Exact loops. In a steady walk the slither phase advances with the distance the head walks and
the gait phase with the head's arc along its trail, so both are periodic in time. A loop window
of N frames holds n slither periods and m gait cycles exactly: the head's turn rate (slither
frequency) and the stride are nudged (by at most NUDGE_TOL, 1%) so that both fit, the antennae's
and ultimate legs' sways are rounded to whole cycles in the window, and the window is cut after a
warm-up (WARMUP) and before a cool-down (COOLDOWN) so no start or end effect reaches it. The tiny
residual left at the seam is distributed over the clip (looping.close_loop) and reported.
"""

from __future__ import annotations

from dataclasses import dataclass

from baker.context import Context
from baker.cycles.maker import ClipMaker
from baker.cycles.spec import (TURN_RADIUS, CyclesConfig, flat_environment, ground_extent,
                               loop_specs, sim_extent, validate_cycles)


@dataclass(frozen=True)
class CyclesResult:
    """outputs: format -> path; summary: the JSON summary; clips: the written clips (root
    mode); rig: the rooted rig they drive; references: loop name -> the simulation's frames
    -1 .. N+1 around its window (what the seam's velocities are compared with)."""

    outputs: dict
    summary: dict
    clips: tuple
    rig: object
    references: dict


def bake_cycles(cfg: CyclesConfig, ctx: Context | None = None) -> CyclesResult:
    """Steps 1-5 (see the module docstring)."""
    from baker.atomic import OutputSet, check_outputs, check_writable
    from baker.export.gltf import build_glb
    from baker.export.usd import build_stage, save_stage
    from baker.navmesh.build import build
    from baker.rig import build_rig

    cfg = validate_cycles(cfg)
    ctx = ctx or Context()
    paths = cfg.output_paths()
    check_writable(cfg.out)
    check_outputs(paths)
    specs = loop_specs(cfg)

    # Step 1: flat ground, walkable everywhere, large enough for every clip's path.
    with ctx.stage("navmesh"):
        env = flat_environment(sim_extent(cfg, specs))
        nav = build(env, cfg.rig.navigation)
    # Step 2: the rig (the cycles nudge the slither and stride, never the skeleton).
    with ctx.stage("rig"):
        rig = build_rig(cfg.rig)
    maker = ClipMaker(cfg, env, nav, rig, ctx)
    # Step 3: the locomotion loops.
    with ctx.stage("simulate"):
        made = [maker.loop(s) for s in specs]
        # Step 4: idle, and the one-shots that start and end in its pose.
        made += maker.idle_family()
    clips = tuple(c for c, _ in made)
    summary = cycles_summary(cfg, [m for _, m in made])
    rooted = maker.rooted_rig
    # Step 5: every clip in one GLB and one USD (a small ground plane under them), all or
    # nothing.
    ground = flat_environment(ground_extent(clips), name="ground")
    import baker

    walk, run = cfg.speeds()
    extras = {"generator": f"baker {baker.__version__} cycles", "fps": cfg.fps,
              "root_motion": "root", "rig": cfg.rig.name,
              "cycles": {"clips": [c.name for c in clips],
                         "speeds_bl_per_s": {"walk": walk, "run": run},
                         "turn_radius_bl": TURN_RADIUS}}
    with OutputSet(paths) as out:
        with ctx.stage("export"):
            out.write_bytes("glb", build_glb(ground, rooted, clips[0], extras=extras,
                                             extra_clips=clips[1:]))
            stage = build_stage(ground, rooted, clips[0], fps=cfg.fps, extras=extras,
                                extra_clips=clips[1:])
            save_stage(stage, out.temp("usd"), paths["usd"])
        out.write_bytes("json", summary_bytes(summary))
        out.commit()
    return CyclesResult(outputs=paths, summary=summary, clips=clips, rig=rooted,
                        references=maker.references)


def summary_bytes(summary: dict) -> bytes:
    import json

    from baker.export import jsonable

    return (json.dumps(jsonable(summary), indent=2, allow_nan=False) + "\n").encode("utf-8")


def cycles_summary(cfg: CyclesConfig, measures: list[dict]) -> dict:
    walk, run = cfg.speeds()
    return {"rig": cfg.rig.name, "fps": cfg.fps, "root_motion": "root",
            "speeds_bl_per_s": {"walk": walk, "run": run},
            "turn_radius_bl": TURN_RADIUS, "body_length_m": cfg.rig.body.length,
            "definitions": {
                "seam_error_m": "max over joints of |p[N] - p[0]|, p = positions seen from the "
                                "root joint, keys 0..N (key N closes the loop)",
                "velocity_mismatch": "max over joints of |v_end - v_start| / the fastest joint "
                                     "speed there, v_start = p[1] - p[0], v_end = p[N] - p[N-1]; "
                                     "the root's own step (in its frame) compared alike",
                "residual_m": "seam error of the simulation before the residual was "
                              "distributed over the clip"},
            "clips": measures}


