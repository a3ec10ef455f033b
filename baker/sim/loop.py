"""The fixed-step simulation loop. Phases, in order, every step:
1. brain   — the behaviour may choose a new target (and the agent plans a path to it);
2. agent   — the navigation agent moves along its path;
3. head    — the head follows the agent with the slither;
4. record  — the head's position is appended to the trail.
After the loop, the body is placed on the trail for every exported frame in one vectorized pass.
"""

from __future__ import annotations

import logging

import numpy as np

from baker.behaviour.wander import WanderBrain
from baker.config import BakeConfig
from baker.context import Context
from baker.errors import NavError
from baker.geometry import polyline
from baker.locomotion.agent import PathAgent
from baker.locomotion.body import body_frames, build_trail
from baker.locomotion.head import HeadSteer
from baker.locomotion.legs import leg_frames
from baker.sim.trajectory import Trajectory

log = logging.getLogger(__name__)


def choose_start(nav, env, body_length: float, rng: np.random.Generator):
    """A walkable start point near the middle of the scene, and a heading whose straight body
    line behind the head is as walkable as possible.

    returns (position (3,), heading (3,) unit horizontal)
    """
    lo, hi = env.bounds
    centre = 0.5 * (lo + hi)
    anchor = nav.nearest(centre, np.inf)
    if anchor is None:
        raise NavError("environment has no walkable surface")
    extent = float(np.max(hi - lo))
    start = nav.random_point_near(anchor, 0.2 * extent, rng)
    if start is None:
        start = anchor
    angles = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, 16, endpoint=False)
    dirs = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1)
    d = np.linspace(0, body_length, 9)
    pts = start[None, None, :] - dirs[:, None, :] * d[None, :, None]
    ok = nav.is_walkable(pts.reshape(-1, 3)).reshape(len(dirs), len(d)).sum(axis=1)
    return start, dirs[int(np.argmax(ok))]


def simulate(cfg: BakeConfig, env, nav, rng: np.random.Generator, ctx: Context) -> Trajectory:
    """Run the bake's simulation and return the spine's world frames at the export fps."""
    rig = cfg.rig
    body, loco, navc = rig.body, rig.locomotion, rig.navigation
    dt = 1.0 / cfg.sim_rate
    n_steps = int(round(cfg.seconds * cfg.sim_rate))
    per_frame = cfg.sim_rate // cfg.fps

    start, heading = choose_start(nav, env, body.length, rng)
    agent = PathAgent(start, loco.max_speed, loco.acceleration, loco.stopping_distance)
    # Pure pursuit: the head chases the agent one turning radius ahead on the path.
    turn_radius = max(navc.radius, 3.0 * body.spacing)
    head = HeadSteer(start, heading, max_speed=loco.max_speed, turn_radius=turn_radius,
                     lead=turn_radius, turn_rate=loco.head_turn_rate,
                     amplitude=loco.slither_amplitude, max_offset=0.4 * navc.radius)
    brain = WanderBrain(nav, rig.wander.interval, rig.wander.radius, rng)

    # The body starts straight behind the head.
    tail = start[None, :] - heading[None, :] * np.linspace(body.length * 1.05, 0, 22)[:, None]
    heads = np.empty((n_steps + 1, 3))
    heads[0] = start
    events: list[dict] = []
    for k in range(1, n_steps + 1):
        t = (k - 1) * dt
        intent = brain.step(t, head.position)
        if intent is not None:
            if events:
                events[-1]["end"] = round(t, 6)
            details = dict(intent.details)
            if intent.target is not None:
                path = nav.find_path(agent.position, intent.target)
                agent.set_path(path.points)
                details["path_complete"] = bool(path.complete)
                details["path_length"] = round(float(polyline.arc_lengths(path.points)[-1]), 4)
            events.append({"start": round(t, 6), "end": None, "state": intent.state,
                           "details": details})
        # The agent waits while the head lags behind it (a sharp turn).
        gap = float(np.hypot(*(agent.position - head.base)[[0, 2]]))
        agent.step(dt, slack=2.0 - gap / turn_radius)
        head.step(dt, agent.position, agent.speed)
        heads[k] = head.position
        if k % 2400 == 0:
            ctx.report_progress("simulate", k / n_steps)
    if events:
        events[-1]["end"] = round(cfg.seconds, 6)

    # The trail: head path (preceded by the initial body line) projected onto the surface, with
    # rays searched from below the agent's free height so overhangs are never hit.
    probe = 0.5 * navc.height
    path = np.vstack([tail[:-1], heads])
    # Path heights are exact only at path corners: start the rays from the navigation surface.
    h = nav.surface_height(path)
    path[np.isfinite(h), 1] = h[np.isfinite(h)]
    trail = build_trail(path, env.rays, probe=probe, spacing=body.spacing, clearance=body.clearance)
    flat = path.copy()
    flat[:, 1] = 0.0
    cum_h = polyline.arc_lengths(flat)
    frame_steps = np.arange(0, n_steps + 1, per_frame)
    head_arc = trail.arc_at(cum_h[len(tail) - 1 + frame_steps])
    bf = body_frames(trail, head_arc, body.spacing, body.segments, body.clearance)
    # Legs, antennae and ultimate legs for all frames at once, from the placed spine.
    limbs = {}
    if rig.legs.enabled:
        lf = leg_frames(bf, head_arc, frame_steps * dt, env.rays, rig)
        limbs = dict(joint_names=lf.names, joint_positions=lf.positions,
                     joint_rotations=lf.rotations, foot_contacts=lf.contacts)
    return Trajectory(
        times=frame_steps * dt,
        spine_positions=bf.positions,
        spine_rotations=bf.rotations,
        head_surface_normal=bf.normals[:, 0],
        ground_heights=bf.ground,
        events=tuple(events),
        **limbs,
    )
