"""The bake pipeline, step by step. Read this first.

    Step 1  load the environment           environment.load_environment
    Step 2  build the navigation surface   navmesh.build (or the on-disk cache)
    Step 3  build the rig                  rig.build_rig
    Step 4  simulate                       sim.loop.simulate -> Trajectory
                                           (--creatures N: sim.loop.simulate_crowd -> N)
    Step 5  pose                           clip.build_clip   -> Clip (one per creature)
    Step 6  measure                        metrics.spine_metrics, surface_metrics, leg_metrics
                                           (a crowd: metrics.crowd_metrics; a lone creature:
                                           beside step 7)
    Step 7  reduce keys                    export.reduce.reduce_clip (world-space tolerance;
                                           a lone creature: reduce_plan, its 30 s pieces on
                                           parallel.fork_map_beside, ReducePlan.finish)
    Step 8  export                         export.gltf / export.usd / export.report
                                           (/ export.preview with --preview)

Frames: the environment is loaded into a local frame (world = env.origin + local, see
environment.load.choose_origin), and everything from step 2 to step 6 works in it. User inputs
given in world coordinates (BakeConfig.start, prey_positions) are moved into it before step 2;
the writers and the report move positions back to world.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from baker import memory
from baker.config import BakeConfig, validate_bake
from baker.context import Context
from baker.parallel import available_cpus, fork_map, fork_map_beside
from baker.streams import Streams

log = logging.getLogger(__name__)

#: [BL] a limb's bone is judged clear of the environment up to this far from its end (its foot
#: stands on a surface): inspect.judge reads the files the same way
LIMB_END_GAP = 0.005


@dataclass(frozen=True)
class BakeResult:
    """What a bake produced.

    outputs    : format -> path written
    report     : the JSON report as a dict
    trajectory : the simulation's Trajectory, in the environment's local frame (creature 0's)
    clip       : the exported Clip (root joint relative to clip.placement, world; creature 0's)
    origin     : (3,) float64, metres, world position of the local frame (env.origin):
                 world = origin + trajectory position
    trajectories, clips : every creature's (--creatures N), creature 0 first
    """

    outputs: dict[str, Path]
    report: dict
    trajectory: object
    clip: object
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    trajectories: tuple = ()
    clips: tuple = ()




def in_local_frame(cfg: BakeConfig, origin: np.ndarray) -> BakeConfig:
    """`cfg` with its world positions (start, prey_positions; metres) moved into the
    environment's local frame (minus origin (3,) float64, metres)."""
    o = np.asarray(origin, dtype=np.float64)
    if not np.any(o != 0):
        return cfg
    local = (lambda p: tuple(float(x) for x in np.asarray(p, dtype=np.float64) - o))
    return replace(cfg, start=None if cfg.start is None else local(cfg.start),
                   prey_positions=tuple(local(p) for p in cfg.prey_positions))


def navigation_surface(cfg: BakeConfig, env):
    """(surface, from cache): the whole level's, or (nav_build "lazy", or "auto" on a level of
    more than LAZY_ABOVE_COLUMNS columns) a LazyNav whose first window is centred on the start
    (or the level's centre) and holds the wander radius, the prey range and the body."""
    from baker.navmesh.cache import load_or_build
    from baker.navmesh.lazy import LAZY_ABOVE_COLUMNS, LazyNav, full_columns

    agent = cfg.rig.navigation
    mode = cfg.nav_build
    if mode == "auto":
        mode = "lazy" if full_columns(env, agent.cell_size) > LAZY_ABOVE_COLUMNS else "full"
    if mode == "full":
        return load_or_build(env, agent, cfg.nav_cache_dir)
    lo, hi = env.bounds
    centre = np.asarray(cfg.start, dtype=np.float64) if cfg.start is not None else 0.5 * (lo + hi)
    rig = cfg.rig
    half = (rig.wander.radius + 2.0 * rig.behaviour.detection_range + rig.body.length
            + 4.0 * agent.radius)
    # refuse now, not after the first window, a bake whose window cannot grow once (twice the
    # side, within the level) inside the memory budget
    from baker.navmesh import budget

    span = np.minimum(4.0 * half, (hi - lo)[[0, 2]])
    cols = [max(1, math.ceil(min(float(s) / agent.cell_size, 1e12))) for s in span]
    budget.check(cols[0], cols[1], agent.cell_size, len(env.mesh.faces), where=env.source,
                 area=float(span[0]) * float(span[1]))
    nav = LazyNav(env, agent, cfg.nav_cache_dir, centre, half)
    return nav, nav.cache_hits == 1


def bake(cfg: BakeConfig, ctx: Context | None = None) -> BakeResult:
    """Run steps 1-7 on `cfg`. A bake whose estimated memory is over cfg.max_memory_mb (or most
    of the memory the process may use) is refused before it starts (baker.memory), and so is
    every navigation build (the whole level, or each lazy window) estimated over
    cfg.max_memory_mb (navmesh.budget)."""
    from baker.navmesh.budget import memory_limit
    from baker.signals import deferred

    # Imports are not interrupted half way (some libraries swallow the exception and fail
    # later): a signal during them is raised once they are done.
    with deferred():
        _import_stages()
    with memory_limit(cfg.max_memory_mb):
        return _bake(cfg, ctx)


def _bake(cfg: BakeConfig, ctx: Context | None) -> BakeResult:
    from baker.environment import load_environment
    from baker.export import report as report_mod
    from baker.atomic import OutputSet, check_not_inputs, check_outputs
    from baker.navmesh import debug as nav_debug
    from baker.rig import build_rig

    cfg = validate_bake(cfg)
    workers = cfg.workers or available_cpus()
    # a bake estimated to run out of memory part way is refused now (baker.memory)
    memory.check(cfg.creatures, cfg.seconds, cfg.fps, workers, cfg.max_memory_mb)
    if cfg.preview:
        from baker.export.preview import check_dependencies

        check_dependencies("--preview")
    ctx = ctx or Context()
    paths = cfg.output_paths()
    check_outputs(paths)
    check_not_inputs(paths, {"environment": Path(cfg.environment)})

    # Step 1: the environment, in metres, +Y up, with the sun.
    with ctx.stage("load"):
        env = load_environment(cfg.environment, sun_override=cfg.sun_direction,
                               up_axis=cfg.up_axis, units=cfg.units)

    # From here on, positions are in the environment's local frame.
    run_cfg = in_local_frame(cfg, env.origin)

    # Step 2: the navigation surface for this rig's agent size (cached by content + params).
    with ctx.stage("navmesh"):
        nav, cache_hit = navigation_surface(run_cfg, env)
    ctx.notes["navmesh_cache_hit"] = cache_hit

    # Step 3: skeleton and skinned mesh.
    with ctx.stage("rig"):
        base_rig = build_rig(cfg.rig)

    # Step 4: behaviour, agent, head and body, at the fixed simulation rate (--creatures N:
    # all of them at once, keeping apart; creature 0 is the lone creature's).
    with ctx.stage("simulate"):
        trajs = simulate_creatures(run_cfg, env, nav, ctx, workers)
    traj = trajs[0]

    # Step 5: joint-local transforms at the export fps, relative to a placement near the path,
    # on a skeleton with a `root` joint when root motion is asked for; one clip per creature
    # (a crowd's others are posed where they are reduced, step 7, on the worker processes).
    with ctx.stage("pose"):
        clip, rig, root_motion = posed_clip(cfg, traj, base_rig, env)

    # Step 6: motion-quality metrics (independent ray casts against the environment), per
    # creature, and how a crowd's creatures keep apart: a crowd's now, a lone creature's
    # beside step 7 (in the reduce stage's time: in this process while the pieces of its clip
    # are reduced on others, or on a thread beside its reduction).
    def measured():
        return measure_creatures(cfg, trajs, env, nav, workers)

    if len(trajs) > 1:
        with ctx.stage("metrics"):
            motions, crowd = measured()

    # Step 7: keyframe reduction: each channel keeps the keys that hold every joint within
    # cfg.tolerance body lengths of its unreduced world position (planted feet do not slide).
    # Per-behaviour clips (--clips) are creature 0's.
    events = events_of(cfg, traj, env.origin)
    clip = replace(clip, events=events(0, clip.n_frames))
    segments = behaviour_clips(clip, traj.events, cfg.fps, events) if cfg.clips else ()
    with ctx.stage("reduce"):
        ((clip, segments, animation, _), *rest), beside = reduce_creatures(
            cfg, (base_rig, rig), env, trajs, clip, segments, workers,
            beside=measured if len(trajs) == 1 else None)
    others = [(c, a) for c, _, a, _ in rest]
    if len(trajs) == 1:
        motions, crowd = beside
    motion = motions[0]

    # Step 8: files, all or nothing: each is written to a temporary beside its target and
    # they are renamed together at the end (atomic.OutputSet); a failure or a signal before
    # that leaves the previous outputs as they were.
    extras = report_mod.extras(cfg, traj, env.origin)
    if clip.keys is not None:        # --tolerance 0 writes the files exactly as before
        extras["animation"] = animation
    if len(trajs) > 1:
        extras["creatures"] = report_mod.creature_entries(cfg, trajs, env.origin)
    debug_meshes = ()
    if cfg.debug_navmesh:
        v, f = nav_debug.walkable_mesh(nav)
        debug_meshes = (("navmesh", v, f, (0.1, 0.6, 1.0, 0.5)),)
    scene = dict(extras=extras, debug_meshes=debug_meshes, props=prey_props(cfg.rig, traj),
                 extra_clips=segments, root_motion=root_motion)
    if len(trajs) > 1:
        scene.update(crowd=[c for c, _ in others], crowd_root_motion=[m for *_, m in rest])
    with OutputSet(paths) as out:
        glb = write_scene(cfg, paths, out, env, rig, clip, scene, ctx, workers)
        # --preview: the map and the contact sheet, drawn from the GLB's bytes, committed with
        # the other files
        if cfg.preview:
            from baker.export.preview import preview_images

            with ctx.stage("preview"):
                for key, data in preview_images(glb, name=paths["glb"].stem).items():
                    out.write_bytes(key, data)
        written = {k: p for k, p in paths.items() if k != "json"}
        written["json"] = paths["json"]
        rep = report_mod.build_report(cfg, env, nav, traj, motion, ctx, written)
        rep["animation"] = animation
        if len(trajs) > 1:
            rep["creatures"] = report_mod.creature_entries(
                cfg, trajs, env.origin, motions=motions,
                animations=[animation] + [a for _, a in others])
            rep["crowd"] = crowd
        out.write_bytes("json", report_mod.to_json_bytes(rep))
        out.commit()
    return BakeResult(outputs=written, report=rep, trajectory=traj, clip=clip, origin=env.origin,
                      trajectories=tuple(trajs), clips=(clip,) + tuple(c for c, _ in others))


def simulate_creatures(cfg: BakeConfig, env, nav, ctx: Context,
                       workers: int = 1) -> list:
    """The trajectories of cfg.creatures creatures (sim.loop.simulate for one, run together by
    sim.loop.simulate_crowd for more, solved on up to `workers` processes), in the
    environment's local frame."""
    from baker.sim.loop import simulate, simulate_crowd

    if cfg.creatures == 1:
        return [simulate(cfg, env, nav, Streams(cfg.seed), ctx)]
    return simulate_crowd(cfg, env, nav, cfg.seed, cfg.creatures, ctx, workers)


def measure(cfg: BakeConfig, traj, env, nav) -> dict:
    """One creature's motion-quality metrics (the report's `metrics`): spine, surface, legs
    and behaviour (baker.metrics)."""
    from baker import metrics

    rig = cfg.rig
    motion = metrics.spine_metrics(
        traj, env.rays, spacing=rig.body.spacing, clearance=rig.body.clearance,
        max_slope=rig.navigation.max_slope, body_length=rig.body.length)
    motion.update(metrics.surface_metrics(traj, nav, clearance=rig.body.clearance))
    if rig.legs.enabled:
        motion["legs"] = metrics.leg_metrics(
            traj, env.rays, rig.legs, spacing=rig.body.spacing, body_length=rig.body.length,
            lag_setting_deg=360.0 * rig.legs.waves / (rig.body.segments - 1),
            max_speed=rig.locomotion.max_speed)
    motion["behaviour"] = metrics.behaviour_metrics(traj, env.rays, fps=cfg.fps,
                                                    clearance=rig.body.clearance)
    return motion


def measure_creatures(cfg: BakeConfig, trajs, env, nav, workers: int = 1) -> tuple:
    """(measure of every creature, crowd_report): a crowd's report is one more call of the
    fork_map, the first, beside the creatures' (the same bits as one after the other)."""
    n = len(trajs)
    if n < 2:
        return [measure(cfg, t, env, nav) for t in trajs], None
    out = fork_map(lambda i: crowd_report(cfg, trajs) if i == 0 else
                   measure(cfg, trajs[i - 1], env, nav), n + 1, workers)
    return out[1:], out[0]


def crowd_report(cfg: BakeConfig, trajs) -> dict | None:
    """The report's `crowd` section (metrics.crowd_metrics, capsules of the rig's body radius,
    its widest half-width), or None for a lone creature."""
    if len(trajs) < 2:
        return None
    from baker import metrics

    return metrics.crowd_metrics(trajs, cfg.rig.legs, body_radius(cfg.rig))


def body_radius(rig_cfg) -> float:
    """[m] the rig's body radius: its widest half-width (BodyConfig.width_profile)."""
    return float(max(rig_cfg.body.width_profile))


def reduce_creatures(cfg: BakeConfig, rigs: tuple, env, trajs, clip, segments: tuple,
                     workers: int = 1, beside=None) -> tuple:
    """(reduce_clips of every creature, beside's value): (reduced clip, reduced per-behaviour
    clips, the report's `animation` section, root motion) each, on up to `workers` processes
    (baker.parallel.fork_map, the same bits as one). rigs: (the base rig, creature 0's posed
    rig). Creature 0 keeps its clip `clip` as it is and the per-behaviour `segments` (its root
    motion: None, the caller has it); a crowd's further creatures are posed here (posed_clip:
    no unreduced clip of theirs is kept), with their own events (events_of), no node tracks
    (the prey and the sun ride on creature 0's clip) and no per-behaviour clips.

    A lone creature's clip is reduced in pieces (reduce_clips' `split`: the same pieces
    whatever `workers`), the pieces on the worker processes, and `beside` (None, or a callable:
    its metrics) runs in this process meanwhile (parallel.fork_map_beside)."""
    base_rig, rig = rigs
    if len(trajs) == 1:
        out, value = reduce_clips(cfg, rig, trajs[0], clip, segments, env, workers=workers,
                                  beside=beside, split=True)
        return [(*out, None)], value

    def one(i: int):
        if i == 0:
            return (*reduce_clips(cfg, rig, trajs[0], clip, segments, env)[0], None)
        own, _, motion = posed_clip(cfg, trajs[i], base_rig, env)
        own = replace(own, tracks=(),
                      events=events_of(cfg, trajs[i], env.origin)(0, own.n_frames))
        return (*reduce_clips(cfg, rig, trajs[i], own, (), env)[0], motion)

    return fork_map(one, len(trajs), workers), (beside() if beside is not None else None)


def write_scene(cfg: BakeConfig, paths: dict, out, env, rig, clip, scene: dict, ctx,
                workers: int = 1):
    """Step 8's GLB and USD files into the OutputSet `out`. Returns the GLB's bytes for
    --preview (else None). A crowd's files are written side by side on up to `workers`
    processes (baker.parallel.fork_map: the same bytes)."""
    keys = [k for k in ("glb", "usd", "usda") if k in paths]
    temps = {k: out.temp(k) for k in keys}       # made here: the commit renames them

    def one(i: int) -> None:
        from baker.export.gltf import build_glb
        from baker.export.usd import build_stage, save_stage

        key = keys[i]
        if key == "glb":
            out.write_bytes("glb", build_glb(env, rig, clip, **scene))
        else:
            save_stage(build_stage(env, rig, clip, fps=cfg.fps, **scene), temps[key], paths[key])

    with ctx.stage("export"):
        fork_map(one, len(keys), workers if scene.get("crowd") else 1)
    return temps["glb"].read_bytes() if cfg.preview and "glb" in temps else None


def posed_clip(cfg: BakeConfig, traj, rig, env):
    """(clip, rig, root motion or None): the trajectory as a clip named `bake`, re-expressed
    for cfg.root_motion (rootmotion.apply_root_motion) over the ground under the body."""
    from baker.clip import build_clip
    from baker.rootmotion import apply_root_motion

    clip = build_clip(traj, rig, name="bake", origin=env.origin)
    shift = clip.placement - np.asarray(env.origin, dtype=np.float64)
    lift = float(cfg.rig.body.clearance)

    def ground(points: np.ndarray) -> np.ndarray:
        hits = env.rays.cast_down(points + shift, lift, max_distance=lift + cfg.rig.body.length)
        return np.where(hits.hit, hits.points[:, 1] - shift[1], np.nan)

    return apply_root_motion(clip, rig, cfg.root_motion, ground)


def warm_up() -> None:
    """Import every stage's modules now (numpy, scipy, trimesh, embree, pygltflib, pxr: a
    second or two), so that a worker process is ready before its first bake."""
    from baker.signals import deferred

    with deferred():
        _import_stages()


def _import_stages() -> None:
    """Import every stage's modules (and so numpy, scipy, trimesh, embree, pygltflib, pxr)."""
    import baker.clip, baker.environment, baker.export.gltf, baker.export.report  # noqa: F401
    import baker.export.usd, baker.metrics, baker.navmesh.cache, baker.navmesh.debug  # noqa: F401
    import baker.navmesh.lazy, baker.rig, baker.sim.loop  # noqa: F401


def reduce_clips(cfg: BakeConfig, rig, traj, clip, segments: tuple, env=None, workers: int = 1,
                 beside=None, split: bool = False):
    """Keyframe reduction of the bake's clip and its per-behaviour segments (export.reduce),
    within cfg.tolerance body lengths, the walking feet held planted where the gait plants them,
    and the limbs' joints held closer where a bone passes within the tolerance of `env`.
    Returns ((clip, segments, the report's `animation` section), beside's value).

    split : the clip is refined in pieces (export.reduce.reduce_plan), on up to `workers`
            processes, while `beside` (a callable or None) runs in this one
            (parallel.fork_map_beside)"""
    from baker.export.reduce import reduce_clip, reduce_plan, reduction_stats
    from baker.rig.limbs import leg_layout

    skel = rig.skeleton
    tol = cfg.tolerance * cfg.rig.body.length
    planted = None
    if traj.foot_contacts is not None and cfg.rig.legs.enabled:
        planted = np.zeros((clip.n_frames, skel.n_joints), dtype=bool)
        feet = [skel.index(n) for n in leg_layout(cfg.rig).foot_names]
        planted[:, feet] = np.asarray(traj.foot_contacts, dtype=bool)
    tight = limbs_near(cfg, skel, traj, env, tol)
    crowded = feet_crowded(cfg, skel, clip, tol)
    if crowded is not None:
        tight = crowded if tight is None else tight | crowded
    kw = dict(rest=(skel.rest_translations, skel.rest_rotations),
              short_rotations=cfg.rotations == "short")
    plan = reduce_plan(clip, skel.parents, tol, contacts=planted, tight=tight, split=split, **kw)
    if plan is None:        # --tolerance 0
        reduced, value = replace(clip, keys=None), (beside() if beside is not None else None)
    else:
        pieces, value = fork_map_beside(plan.piece, plan.pieces, workers, beside)
        reduced = plan.finish(pieces)
    for _ in range(GRAZE_ROUNDS if plan is not None else 0):
        # a limb bone the reduced pose moves into the environment: its joints held tight there
        grazed = limbs_grazed(cfg, skel, traj, env, clip, reduced)
        if grazed is None:
            break
        tight = grazed if tight is None else tight | grazed
        plan = reduce_plan(clip, skel.parents, tol, contacts=planted, tight=tight, split=split,
                           **kw)
        reduced = plan.finish(fork_map(plan.piece, plan.pieces, workers))
    animation = {"tolerance_bl": cfg.tolerance, **reduction_stats(clip, reduced)}
    ranges = {name: (f0, f1) for f0, f1, name in behaviour_ranges(clip.n_frames, traj.events,
                                                                   cfg.fps)}
    out = []
    for seg in segments:
        f0, f1 = ranges[seg.name]
        out.append(reduce_clip(seg, skel.parents, tol, **kw,
                               contacts=None if planted is None else planted[f0:f1],
                               tight=None if tight is None else tight[f0:f1]))
    if segments:
        animation["segment_clips"] = [{"name": a.name, **reduction_stats(b, a)}
                                      for b, a in zip(segments, out)]
    return (reduced, tuple(out), animation), value


#: [segment spacings] neighbouring feet keep this far apart in the files (inspect.LIMITS)
FEET_GAP = 0.2


def feet_crowded(cfg: BakeConfig, skel, clip, tol: float):
    """(F, J) bool or None: the frames at which a walking foot of the clip comes within
    FEET_GAP spacings plus two tolerances of its neighbour's on its side (the next segment's),
    marked on both foot end joints, so that the keyframe reduction holds them within its tight
    share of the tolerance there: each foot may move by the tolerance, and two neighbours
    simulated 0.21 spacing apart (swing HARD_GAP) came 0.195 apart in a reduced file."""
    from baker.rig.limbs import leg_layout

    if tol <= 0 or not cfg.rig.legs.enabled:
        return None
    feet = np.array([skel.index(n) for n in leg_layout(cfg.rig).foot_names], dtype=np.int64)
    if len(feet) < 3:
        return None
    world, _ = clip.world(skel.parents)
    p = world[:, feet]                                   # (F, L, 3): L_01, R_01, L_02, ...
    near = (np.linalg.norm(p[:, 2:] - p[:, :-2], axis=2)
            < FEET_GAP * cfg.rig.body.spacing + 2.0 * tol)       # leg l and l + 2: one side
    out = np.zeros((clip.n_frames, skel.n_joints), dtype=bool)
    out[:, feet[:-2]] |= near
    out[:, feet[2:]] |= near
    return out if out.any() else None


def limbs_near(cfg: BakeConfig, skel, traj, env, tol: float):
    """(F, J) bool or None: the frames at which a leg, ultimate-leg or antenna bone of the
    simulation (metrics.limb_bones) passes within `tol` of the environment
    (export.reduce.bones_near), marked on both of its joints; for clips played in the world
    (not --root-motion in-place)."""
    from baker.export.reduce import bones_near
    from baker.metrics import limb_bones

    if env is None or tol <= 0 or not cfg.rig.legs.enabled or cfg.root_motion == "in-place":
        return None
    starts, ends, names = limb_bones(traj, cfg.rig.legs)
    # the rays reach 2 tolerances past the part of the bone that is judged (all but its last
    # LIMB_END_GAP), as the reduced pose may move the bone's end by up to the tolerance (a
    # swinging foot grazing the ground just inside the judged part was moved into it)
    hit = bones_near(starts, ends, env.rays, tol,
                     end_gap=max(LIMB_END_GAP * cfg.rig.body.length - 2.0 * tol, 0.0))
    return _marked(hit, *_bone_joints(skel, names), skel.n_joints)


def _bone_joints(skel, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) joint indices of metrics.limb_bones' bones: a bone is named by its start
    joint; an upper bone ends at its tip joint, a tip bone at its foot end joint, an antenna
    bone at its joint's child (the next antenna joint, or its tip)."""
    first = [skel.index(n) for n in names]
    last = [int(np.flatnonzero(skel.parents == j)[0]) if n.startswith("antenna_")
            else skel.index(n[: -len("upper")] + "tip" if n.endswith("_upper")
                            else n[: -len("tip")] + "foot") for n, j in zip(names, first)]
    return np.asarray(first, dtype=np.int64), np.asarray(last, dtype=np.int64)


def _marked(hit: np.ndarray, first: np.ndarray, last: np.ndarray, joints: int) -> np.ndarray:
    """(F, J) bool: both joints of each (frame, bone) of `hit` (F, B)."""
    near = np.zeros((len(hit), joints), dtype=bool)
    f, b = np.nonzero(hit)
    near[f, first[b]] = True
    near[f, last[b]] = True
    return near


#: reductions done again at most, each holding the joints of the limb bones the last one moved
#: into the environment within its tight share of the tolerance (limbs_grazed)
GRAZE_ROUNDS = 2


def limbs_grazed(cfg: BakeConfig, skel, traj, env, clip, reduced):
    """(F, J) bool or None: the frames at which a leg, ultimate-leg or antenna bone as the
    reduced clip plays it (export.reduce.played_joints) passes through the environment where the
    simulation's bone does not, marked on both of its joints (None: nowhere). The bone is
    judged as inspect judges a file: one ray along it, all but its last LIMB_END_GAP.
    limbs_near's offset rays sample the tolerance round a bone and can miss an edge between
    them (a swinging tip bone 0.07 mm past a leaf's edge, moved 0.15 mm into it). As
    limbs_near, for clips played in the world: an in-place clip's joints move in its root's
    frame, which turns with the walk."""
    from baker.export.reduce import played_joints
    from baker.metrics import limb_bones
    from baker.rig.skeleton import forward_kinematics

    if env is None or reduced.keys is None or not cfg.rig.legs.enabled \
            or cfg.root_motion == "in-place":
        return None
    starts, ends, names = limb_bones(traj, cfg.rig.legs)
    if not names:
        return None
    first, last = _bone_joints(skel, names)
    t, q, _ = played_joints(reduced)
    moved = (forward_kinematics(skel.parents, t, q)[0]
             - forward_kinematics(skel.parents, clip.translations, clip.rotations)[0])
    gap = LIMB_END_GAP * cfg.rig.body.length

    def through(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        v = b - a
        reach = np.maximum(np.linalg.norm(v, axis=-1) - gap, 0.0)
        return env.rays.occluded(a.reshape(-1, 3), v.reshape(-1, 3),
                                 reach.reshape(-1)).reshape(reach.shape)

    hit = through(starts + moved[:, first], ends + moved[:, last])
    if not hit.any():
        return None
    hit &= ~through(starts, ends)
    return _marked(hit, first, last, skel.n_joints) if hit.any() else None


def prey_props(rig_cfg, traj) -> tuple:
    """(name, vertices, faces, rgba) of every prey capsule in the trajectory."""
    from baker.rig.props import capsule_mesh

    if not traj.prey_names:
        return ()
    v, f = capsule_mesh(rig_cfg.prey.length, rig_cfg.prey.radius)
    rgba = tuple(rig_cfg.prey.color) + (1.0,)
    return tuple((name, v, f, rgba) for name in traj.prey_names)


def behaviour_clips(clip, timeline, fps: int, events=None) -> tuple:
    """One clip per timeline segment, named state_NN, each starting at time 0 and including
    the frame at its end time (so consecutive clips share their boundary pose).
    events : callable (first frame, frames) -> the segment's events dict (see events_of)"""
    out = []
    for f0, f1, name in behaviour_ranges(clip.n_frames, timeline, fps):
        seg = clip.segment(f0, f1, name)
        out.append(seg if events is None else replace(seg, events=events(f0, f1 - f0)))
    return tuple(out)


def behaviour_ranges(n_frames: int, timeline, fps: int) -> list[tuple[int, int, str]]:
    """(first frame, end frame (exclusive), name) of each behaviour_clips segment."""
    out = []
    for i, e in enumerate(timeline):
        f0 = int(round(e["start"] * fps))
        f1 = min(int(round(e["end"] * fps)) + 1, n_frames)
        if f1 - f0 >= 2:
            out.append((f0, f1, f"{e['state']}_{i:02d}"))
    return out


def events_of(cfg: BakeConfig, traj, origin):
    """A function (first frame, frames) -> the events dict (export.events.clip_events) of
    that part of the bake: foot contacts of the walking legs and behaviour changes."""
    from baker.export.events import clip_events
    from baker.export.report import world_events
    from baker.rig.limbs import leg_layout

    contacts = traj.foot_contacts
    feet = leg_layout(cfg.rig).foot_names if contacts is not None else ()
    timeline = world_events(traj.events, origin)
    return lambda f0, frames: clip_events(cfg.fps, frames, contacts=contacts, feet=feet,
                                          timeline=timeline, f0=f0)
