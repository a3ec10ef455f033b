"""The fixed-step simulation loop. Phases, in order, every step:
1. brain   — perception and decisions; a new target means a new path for the agent;
2. agent   — the navigation agent moves along its path (sim/follow.py);
3. head    — the head follows the agent on the walkable surface, with the slither; its
             position extends the trail;
4. prey    — every prey wanders or flees from the head.
After the loop, the body (with the cobra lift), the legs and the prey are placed for every
exported frame in vectorized passes.
"""

from __future__ import annotations

import logging

import numpy as np

from scipy.spatial.transform import Rotation

from baker.behaviour.brain import Brain, Senses
from baker.behaviour.perception import in_shade
from baker.behaviour.prey import HELD, HIDDEN, Prey
from baker.behaviour.sun import sun_path
from baker.config import BakeConfig, parse_sun_path
from baker.context import Context
from baker.errors import NavError
from baker.geometry import polyline
from baker.geometry.conventions import UP
from baker.geometry.transforms import frames_to_quat, quat_mul, quat_rotate
from baker.locomotion.body import body_frames, build_trail, project_to_surface
from baker.locomotion.cobra import lift_profile
from baker.locomotion.legs import hip_extent, leg_frames
from baker.sim.follow import Follower
from baker.sim.trajectory import Trajectory
from baker.streams import Streams

log = logging.getLogger(__name__)


def choose_start(nav, env, body_length: float, rng: np.random.Generator, at=None, heading=None,
                 spread: float = np.inf):
    """A walkable start point near the middle of the scene (within a fifth of its extent, at
    most `spread` metres; or the one nearest to `at`), and a
    heading (or `heading`) whose straight body line behind the head is as walkable as possible.

    returns (position (3,), heading (3,) unit horizontal)
    """
    lo, hi = env.bounds
    if at is not None:
        anchor = nav.nearest(np.asarray(at, dtype=np.float64), np.inf)
    else:  # the largest walkable component's sample closest to the middle of the scene
        centre = 0.5 * (lo + hi)
        main = np.nonzero(nav.component == 0)[0]
        d = np.linalg.norm(nav.positions[main] - centre.astype(np.float32), axis=1)
        anchor = nav.positions[main[np.argmin(d)]].astype(np.float64) if len(main) else None
    if anchor is None:
        raise NavError("environment has no walkable surface")
    extent = float(np.max(hi - lo))
    start = anchor if at is not None else nav.random_point_near(anchor, min(0.2 * extent, spread),
                                                                rng)
    if start is None:
        start = anchor
    if heading is not None:
        h = np.array([heading[0], 0.0, heading[2]], dtype=np.float64)
        return start, h / max(np.linalg.norm(h), 1e-12)
    angles = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, 16, endpoint=False)
    dirs = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1)
    d = np.linspace(0, body_length, 9)
    pts = start[None, None, :] - dirs[:, None, :] * d[None, :, None]
    ok = nav.is_walkable(pts.reshape(-1, 3)).reshape(len(dirs), len(d)).sum(axis=1)
    return start, dirs[int(np.argmax(ok))]


def simulate(cfg: BakeConfig, env, nav, streams: Streams, ctx: Context,
             intent=None) -> Trajectory:
    """Run the bake's simulation and return the creature's world frames at the export fps.

    streams : the bake's random streams (baker.streams): the start, the brain and each prey
              draw from their own, so one subsystem's draws never shift another's.

    intent : None lets the brain decide (behaviour.brain.Brain); otherwise a scripted source of
             the same drives (behaviour.script.ScriptedIntent: target or route, halt, speed and
             turn scales, cobra, warning) takes its place, and no prey are spawned. Its
             `chain_period` (seconds or None) makes the antennae and ultimate legs periodic.
    """
    rig = cfg.rig
    body, navc = rig.body, rig.navigation
    dt = 1.0 / cfg.sim_rate
    n_steps = int(round(cfg.seconds * cfg.sim_rate))
    per_frame = cfg.sim_rate // cfg.fps
    n_frames = n_steps // per_frame + 1

    start, heading = choose_start(nav, env, body.length, streams.get("start"), cfg.start, cfg.start_heading,
                                   spread=rig.wander.radius)
    follow = Follower(nav, env.rays, start, heading, rig, fps=cfg.fps)
    head = follow.head
    sun = sun_path(parse_sun_path(cfg.sun_path) if cfg.sun_path else None, env.sun.direction,
                   cfg.seconds, env.sun.azimuth_rate)
    if intent is None:
        def in_cover(t, p):
            return bool(in_shade(env.rays, p, sun.at(t), body.clearance)[0])

        preys = ([Prey(i, nav.nearest(p, np.inf), rig.prey, nav, streams.get("prey", i),
                       in_cover) for i, p in enumerate(cfg.prey_positions)]
                 if cfg.prey_positions else
                 spawn_prey(cfg.prey, start, nav, rig, streams,
                            lambda p: in_shade(env.rays, p, sun.at(0.0), body.clearance),
                            in_cover))
        brain = Brain(rig, nav, env.rays, sun, streams.get("brain"), preys, mode=cfg.behaviour,
                      cobra_mode=cfg.cobra)
    else:
        preys, brain = [], intent

    # The body starts straight behind the head.
    tail = start[None, :] - heading[None, :] * np.linspace(body.length * 1.05, 0, 22)[:, None]
    heads = np.empty((n_steps + 1, 3))
    heads[0] = start
    rec = Recorder(n_frames, len(preys))
    ramp = dt / rig.cobra.ramp_time
    cobra = brain.cobra
    rec.sample(0, brain, preys, cobra, head.phase)
    for k in range(1, n_steps + 1):
        t = (k - 1) * dt
        # 1. brain: perception, the d10, hunting; a new target means a new path
        brain.step(Senses(t, follow.position, head.heading, follow.agent.arrived))
        if brain.new_target:
            follow.go(brain.target, route=brain.route)
        elif brain.halt:
            follow.halt()
        follow.drive(brain.speed_scale, brain.stopping_distance, brain.turn_scale)
        # 2.-3. the agent walks its path and the head follows it on the walkable surface
        follow.step(dt)
        heads[k] = follow.position
        # 4. prey react to the head
        for p in preys:
            p.step(t, dt, heads[k])
        cobra += max(-ramp, min(ramp, brain.cobra - cobra))
        if k % per_frame == 0:
            rec.sample(k // per_frame, brain, preys, cobra, head.phase)
        if k % 2400 == 0:
            ctx.report_progress("simulate", k / n_steps)
    events = brain.finish(cfg.seconds)
    ctx.notes["path_replans"] = follow.replans

    # The trail: head path (preceded by the initial body line) projected onto the surface, with
    # rays searched from below the agent's free height so overhangs are never hit.
    probe = 0.5 * navc.height
    # The head's heights are already on its layer; the initial body line (at the start's
    # height) is put on the layer nearest it, never one a free agent height above or below.
    line = tail[:-1].copy()
    h = nav.surface_height(line, tol=0.5 * navc.height)
    line[np.isfinite(h), 1] = h[np.isfinite(h)]
    path = np.vstack([line, heads])
    trail = build_trail(path, env.rays, probe=probe, spacing=body.spacing, clearance=body.clearance,
                        hips=hip_extent(rig))
    flat = path.copy()
    flat[:, 1] = 0.0
    cum_h = polyline.arc_lengths(flat)
    frame_steps = np.arange(0, n_steps + 1, per_frame)
    head_arc = trail.arc_at(cum_h[len(tail) - 1 + frame_steps])
    lift = lift_profile(rec.cobra, rig.cobra.curve, rig.cobra.height, body.segments)
    bf = body_frames(trail, head_arc, body.spacing, body.segments, body.clearance, lift=lift,
                     rays=env.rays, ceiling_margin=rig.cobra.ceiling_margin, fps=cfg.fps,
                     ramp_time=rig.cobra.ramp_time)
    # Legs, antennae and ultimate legs for all frames at once, from the placed spine.
    limbs = {}
    if rig.legs.enabled:
        lf = leg_frames(bf, head_arc, frame_steps * dt, env.rays, rig, warning=rec.warning,
                        chain_period=getattr(intent, "chain_period", None))
        limbs = dict(joint_names=lf.names, joint_positions=lf.positions,
                     joint_rotations=lf.rotations, foot_contacts=lf.contacts)
    prey_t = prey_frames(rec, preys, bf, env.rays, rig, probe) if preys else {}
    return Trajectory(
        times=frame_steps * dt,
        spine_positions=bf.positions,
        spine_rotations=bf.rotations,
        head_surface_normal=bf.normals[:, 0],
        ground_heights=bf.ground,
        events=events,
        cobra_lift=bf.lift,
        warning=rec.warning,
        sun_directions=sun.at(frame_steps * dt),
        head_arc=head_arc,
        slither_phase=rec.slither,
        **limbs,
        **prey_t,
    )


def spawn_prey(count: int, start: np.ndarray, nav, rig, streams: Streams,
               shaded=None, in_cover=None) -> list[Prey]:
    """`count` prey at reachable points between 1.2 and 2 detection ranges from the start, each
    placed and later fleeing with its own stream. Prey shelter in shade as the centipede does:
    with `shaded` ((n, 3) points -> (n,) bool) each takes the first shaded one of 32 draws,
    else the first draw in range. `in_cover` is handed to each (Prey)."""
    preys = []
    r = rig.behaviour.detection_range
    for i in range(count):
        rng = streams.get("prey", i)
        found = []
        for _ in range(32):
            q = nav.random_point_near(start, 2.0 * r, rng)
            if q is not None and np.linalg.norm(q - start) >= 1.2 * r:
                found.append(q)
                if shaded is None or shaded(q[None])[0]:
                    found = [q]
                    break
        preys.append(Prey(i, found[0] if found else start.copy(), rig.prey, nav, rng,
                          in_cover))
    return preys


class Recorder:
    """Per-frame records of what the loop decided (brain drives and prey states)."""

    def __init__(self, n_frames: int, n_prey: int):
        self.cobra = np.zeros(n_frames)
        self.warning = np.zeros(n_frames)
        self.prey_pos = np.zeros((n_frames, n_prey, 3))
        self.prey_mode = np.zeros((n_frames, n_prey), dtype=np.int8)
        self.slither = np.zeros(n_frames)

    def sample(self, f: int, brain, preys, cobra: float, slither: float = 0.0) -> None:
        self.cobra[f] = cobra
        self.slither[f] = slither
        self.warning[f] = brain.warning
        for j, p in enumerate(preys):
            self.prey_pos[f, j] = p.position
            self.prey_mode[f, j] = p.mode


def prey_frames(rec: Recorder, preys, bf, rays, rig, probe: float) -> dict:
    """World frames of every prey capsule: on the surface while free or captured, held at the
    head while the centipede feeds, hidden (scale 0) once eaten."""
    pos = rec.prey_pos.copy()
    F, P, _ = pos.shape
    flat = pos.reshape(-1, 3)
    ground, _, hit = project_to_surface(rays, flat, probe)
    flat[hit] = ground[hit]
    pos = flat.reshape(F, P, 3) + rig.prey.radius * UP
    # heading from motion, held when still
    fwd = np.zeros_like(pos)
    fwd[1:] = pos[1:] - pos[:-1]
    fwd[..., 1] = 0.0
    moving = np.linalg.norm(fwd, axis=-1) > 1e-6
    fwd[0] = np.array([0.0, 0.0, 1.0])
    moving[0] = True
    # carry the last heading through stops: forward-fill the index of the last moving frame
    last = np.maximum.accumulate(np.where(moving, np.arange(F)[:, None], 0), axis=0)
    fwd = fwd[last, np.arange(P)[None, :]]
    rot = frames_to_quat(fwd, np.broadcast_to(UP, fwd.shape))
    held = rec.prey_mode == HELD
    if held.any():
        head_p = bf.positions[:, 0]
        head_q = bf.rotations[:, 0]
        ahead = quat_rotate(head_q, np.array([0.0, 0.0, 1.0]))
        below = quat_rotate(head_q, np.array([0.0, -1.0, 0.0]))
        grip = (head_p + ahead * (0.5 * rig.prey.length + 0.25 * rig.body.spacing)
                + below * 0.25 * rig.prey.radius)
        f_idx, j_idx = np.nonzero(held)
        pos[f_idx, j_idx] = grip[f_idx]
        side = quat_mul(head_q, Rotation.from_euler("y", np.pi / 2).as_quat())
        rot[f_idx, j_idx] = side[f_idx]
    return dict(prey_names=tuple(p.name for p in preys), prey_positions=pos,
                prey_rotations=rot, prey_visible=rec.prey_mode != HIDDEN,
                prey_modes=rec.prey_mode)
