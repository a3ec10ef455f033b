"""The cycles' simulations: scripted drives on the flat ground, cut into exact loops and
one-shots (see library.py for the method)."""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from baker.behaviour.script import Drive, ScriptedIntent
from baker.clip import Clip, build_clip
from baker.config import BakeConfig, RigConfig
from baker.cycles import looping
from baker.cycles.spec import (BLEND_MIN, BLEND_RATE, CHAIN_TOL, COOLDOWN, IDLE_WARMUP,
                               LOOP_MAX, LOOP_MIN, LOOP_SUFFIX, LUNGE, NUDGE_TOL, PROBE,
                               RESIDUAL_WARN, TURN_RADIUS, LoopSpec, warmup, window_range)
from baker.locomotion.gait import gait_clock
from baker.rootmotion import apply_root_motion
from baker.streams import Streams

log = logging.getLogger(__name__)

#: [s] the one-shots' action starts this long after their first frame
LEAD_IN = 0.25
#: [s] after a one-shot's last drive, time for the legs and the lift to settle
SETTLE = 1.0


class ClipMaker:
    """Runs the simulations of every cycle on one flat environment and navigation surface."""

    def __init__(self, cfg, env, nav, rig, ctx):
        self.cfg, self.env, self.nav, self.rig, self.ctx = cfg, env, nav, rig, ctx
        self.fps = cfg.fps
        self.start = np.asarray(nav.nearest(np.zeros(3), np.inf), dtype=np.float64)
        self.rooted_rig = None
        #: loop name -> the simulation's frames -1 .. N+1 around its window (root mode)
        self.references: dict[str, Clip] = {}

    # ------------------------------------------------------------------ simulation
    def run(self, rig: RigConfig, drives, seconds: float, chain_period: float | None = None):
        """The Trajectory of `drives` (from the start point, facing +Z) for `seconds`."""
        from baker.sim.loop import simulate

        cfg = BakeConfig(seconds=round(seconds * self.fps) / self.fps, fps=self.fps, rig=rig,
                         start=tuple(float(x) for x in self.start), start_heading=(0.0, 0.0, 1.0))
        return simulate(cfg, self.env, self.nav, Streams(0), self.ctx,
                        intent=ScriptedIntent(drives, chain_period=chain_period))

    def route(self, spec: LoopSpec, seconds: float) -> np.ndarray:
        """(k, 3) the agent's route: straight along +Z, or a circle of TURN_RADIUS to the
        left (+X) or right, sampled every millimetre, longer than the walk."""
        loco = self.cfg.rig.locomotion
        length = spec.speed * seconds * 1.2 + spec.speed ** 2 / loco.acceleration + 0.5
        if spec.turn == 0:
            return self.start + np.array([[0.0, 0.0, 0.0], [0.0, 0.0, length]])
        r = TURN_RADIUS * self.cfg.rig.body.length
        a = np.linspace(0.0, length / r, int(math.ceil(length / 1e-3)) + 1)
        side = float(spec.turn)
        pts = np.stack([side * r * (1.0 - np.cos(a)), np.zeros_like(a), r * np.sin(a)], axis=1)
        return self.start + pts

    def clocks(self, traj, rig: RigConfig, f0: int, n: int) -> tuple[float, float]:
        """(slither periods, gait cycles) from frame f0 to f0 + n (the gait clock of
        locomotion.gait with this rig's strides, on the head's arc along its trail)."""
        lg = rig.legs
        phase = gait_clock(traj.head_arc, traj.times, rig.locomotion.max_speed, lg.stride_min,
                           lg.stride_max).phase
        th = traj.slither_phase
        return float(th[f0 + n] - th[f0]) / (2.0 * math.pi), float(phase[f0 + n] - phase[f0])

    def rooted(self, traj, name: str) -> Clip:
        """The whole simulation as a root-mode clip (root motion is computed on it all, then
        cut, so no end effect reaches a window)."""
        clip = build_clip(traj, self.rig, name=name, fps=self.fps, placement=np.zeros(3))
        rooted, self.rooted_rig, _ = apply_root_motion(clip, self.rig, "root")
        return rooted

    def cut(self, full: Clip, f0: int, count: int, loop: bool = False) -> Clip:
        """Frames f0 .. f0 + count - 1, the root starting at the origin facing +Z (a loop: its
        heading with the slither's sway averaged out, looping.loop_heading)."""
        clip = full.segment(f0, f0 + count, full.name)
        return looping.start_at_origin(clip, heading=looping.loop_heading(clip) if loop else None)

    # ------------------------------------------------------------------ loops
    def loop(self, spec: LoopSpec) -> tuple[Clip, dict]:
        """An exact loop of `spec` (three runs: measure the rates, fit the gait to the nudged
        slither, then the full creature) and its measures."""
        rig0, fps = self.cfg.rig, self.fps
        bl, lg = rig0.body.length, rig0.legs
        f0 = round(warmup(spec, rig0) * fps)
        lo, hi = window_range(spec, rig0)
        longest = f0 / fps + hi + COOLDOWN
        drives = [Drive(0.0, spec.state, route=self.route(spec, longest),
                        speed_scale=spec.speed_scale, turn_scale=spec.turn_scale)]
        legless = (lambda r: replace(r, legs=replace(r.legs, enabled=False)))
        # 1. the slither's and the gait's rates in the steady walk
        probe = round(PROBE * fps)
        traj = self.run(legless(rig0), drives, f0 / fps + PROBE + COOLDOWN)
        s, g = self.clocks(traj, rig0, f0, probe)
        win = looping.plan_window((s * fps / probe, g * fps / probe), fps, lo, hi, NUDGE_TOL,
                                  extra=(lg.antenna_rate, 0.5 * lg.antenna_rate),
                                  extra_tol=CHAIN_TOL)
        n = win.frames
        seconds = f0 / fps + n / fps + COOLDOWN
        tuned = replace(rig0, locomotion=replace(
            rig0.locomotion, head_turn_rate=rig0.locomotion.head_turn_rate * win.scales[0]))
        # 2. the gait cycles in the window with the nudged slither: the stride that fits them
        s, g = self.clocks(self.run(legless(tuned), drives, seconds), tuned, f0, n)
        stride = g / win.counts[1]
        tuned = replace(tuned, legs=replace(tuned.legs, stride_min=lg.stride_min * stride,
                                            stride_max=lg.stride_max * stride))
        # 3. the creature, with its chains periodic in the window
        traj = self.run(tuned, drives, seconds, chain_period=n / fps)
        s, g = self.clocks(traj, tuned, f0, n)
        full = self.rooted(traj, spec.name)
        cycle = {"frames": n, "seconds": n / fps, "slither_periods": win.counts[0],
                 "gait_cycles": win.counts[1], "slither_period_frames": n / win.counts[0],
                 "gait_period_frames": n / win.counts[1],
                 "slither_nudge": win.scales[0] - 1.0, "stride_nudge": stride - 1.0,
                 "measured_slither_periods": s, "measured_gait_cycles": g,
                 "speed_bl_per_s": spec.speed / bl}
        if spec.turn:
            cycle["turn_radius_bl"] = TURN_RADIUS
        return self.finish_loop(full, traj, f0, n, cycle)

    def events(self, traj, f0: int, frames: int, markers, loop: bool, details: dict) -> dict:
        """The clip's events (export.events schema): the walking feet's contacts and the
        scripted states of frames f0 .. f0 + frames - 1, `details` added to every state, and
        `markers` ((name, frame), clip frames)."""
        from baker.export.events import clip_events, marker
        from baker.rig.limbs import leg_layout

        contacts = traj.foot_contacts
        feet = leg_layout(self.cfg.rig).foot_names if contacts is not None else ()
        timeline = [dict(e, details={**e["details"], **details}) for e in traj.events]
        return clip_events(self.fps, frames, contacts=contacts, feet=feet, timeline=timeline,
                           f0=f0, markers=[marker(nm, f, self.fps) for nm, f in markers],
                           loop=loop)

    def finish_loop(self, full: Clip, traj, f0: int, n: int, cycle: dict) -> tuple[Clip, dict]:
        """Frames f0..f0 + n of `full` as a loop: its seam closed, loop flag and events, and its
        measures (the velocities against the simulation's frames f0 - 1 .. f0 + n + 1)."""
        parents = self.rooted_rig.skeleton.parents
        clip = self.cut(full, f0, n + 1, loop=True)
        residual = looping.seam_error(parents, clip.translations, clip.rotations)
        ref = full.segment(f0 - 1, f0 + n + 2, full.name)
        raw_v = looping.seam_velocity(parents, (clip.translations, clip.rotations),
                                      (ref.translations, ref.rotations))
        clip = looping.close_loop(clip)
        m = looping.seam_velocity(parents, (clip.translations, clip.rotations),
                                  (ref.translations, ref.rotations))
        m["seam_error_m"] = looping.seam_error(parents, clip.translations, clip.rotations)
        self.references[clip.name] = ref
        t_end = float(clip.times[-1])
        events = self.events(traj, f0, n + 1, [("loop_start", 0), ("loop_end", n)], True,
                             {"cycle": cycle})
        clip = replace(clip, loop=True, events=events)
        m.update(name=clip.name, loop=True, keys=clip.n_frames, duration_s=t_end,
                 residual_m=residual, residual_velocity_mismatch=raw_v["velocity_mismatch"],
                 max_joint_turn_deg=float(
                     looping.frame_turns(clip).max()), cycle=cycle)
        if residual > RESIDUAL_WARN:
            log.warning("%s: the simulation's seam residual is %.2g m (distributed over the "
                        "clip)", clip.name, residual)
        log.info("%s: %d frames, residual %.2g m, seam %.2g m, velocity mismatch %.2g",
                 clip.name, clip.n_frames, residual, m["seam_error_m"],
                 m["velocity_mismatch"])
        return clip, m

    # ------------------------------------------------------------------ idle and one-shots
    def idle_family(self) -> list[tuple[Clip, dict]]:
        """The idle loop (standing; antennae and ultimate legs periodic in its window) and the
        one-shots, each a whole number of idle periods long, blended from and back to it."""
        rig0, fps = self.cfg.rig, self.fps
        lg = rig0.legs
        win = looping.plan_window((), fps, LOOP_MIN, LOOP_MAX, extra=(
            lg.antenna_rate, 0.5 * lg.antenna_rate), extra_tol=CHAIN_TOL)
        n = win.frames
        period = n / fps
        f0 = round(IDLE_WARMUP * fps)
        shots = one_shots(rig0, IDLE_WARMUP)
        reps = {k: max(1, math.ceil((dur + BLEND_MIN) * fps / n)) for k, (_, dur) in shots.items()}
        seconds = f0 / fps + max(reps.values()) * period + COOLDOWN
        traj = self.run(rig0, [Drive(0.0, "idle")], seconds, chain_period=period)
        cycle = {"frames": n, "seconds": period, "chain_period_s": period,
                 "chain_rates_hz": chain_rates(rig0, period)}
        idle, m = self.finish_loop(self.rooted(traj, "idle" + LOOP_SUFFIX), traj, f0, n, cycle)
        m["idle_foot_slide_m"] = foot_slide(self.rooted_rig, idle)
        out = [(idle, m)]
        for name, (drives, dur) in shots.items():
            traj = self.run(rig0, drives, seconds, chain_period=period)
            action = self.cut(self.rooted(traj, name), f0, reps[name] * n + 1)
            out.append(self.one_shot(idle, action, dur, traj, f0))
        return out

    def one_shot(self, idle: Clip, action: Clip, duration: float, traj, f0: int
                 ) -> tuple[Clip, dict]:
        """`action` blended in joint space from the idle loop (tiled) at its first frame and
        back to it at its last, with a ramp long enough that the blend turns no joint more than
        BLEND_RATE degrees a frame."""
        n = idle.n_frames - 1
        idx = np.arange(action.n_frames) % n
        base = replace(idle, times=action.times, translations=idle.translations[idx],
                       rotations=idle.rotations[idx], scales=idle.scales[idx])
        turn = looping.largest_turn(base, action)
        ramp = max(round(BLEND_MIN * self.fps), math.ceil(1.5 * turn / math.radians(BLEND_RATE)))
        shot = looping.blend(base, action, looping.blend_weights(action.n_frames, ramp))
        parents = self.rooted_rig.skeleton.parents
        p = looping.root_relative(parents, shot.translations, shot.rotations)
        p_idle = looping.root_relative(parents, idle.translations[:1], idle.rotations[:1])[0]
        t_end = float(shot.times[-1])
        last = shot.n_frames - 1
        events = self.events(traj, f0, shot.n_frames,
                             [("start", 0), ("action", round(LEAD_IN * self.fps)), ("end", last)],
                             False, {"one_shot": {"starts_and_ends_in": idle.name,
                                                  "blend_frames": ramp}})
        shot = replace(shot, loop=False, events=events)
        root = shot.translations[:, 0].astype(np.float64)
        m = {"name": shot.name, "loop": False, "keys": shot.n_frames, "duration_s": t_end,
             "action_s": duration, "blend_frames": ramp,
             "largest_blend_turn_deg": math.degrees(turn),
             "start_error_m": float(np.linalg.norm(p[0] - p_idle, axis=-1).max()),
             "end_error_m": float(np.linalg.norm(p[-1] - p_idle, axis=-1).max()),
             "root_travel_m": float(np.linalg.norm(root[-1] - root[0])),
             "max_joint_turn_deg": float(looping.frame_turns(shot).max())}
        log.info("%s: %d frames, blend %d frames", shot.name, shot.n_frames, ramp)
        return shot, m


def one_shots(rig: RigConfig, t0: float) -> dict[str, tuple[list, float]]:
    """{name: (drives, seconds from t0 until it has settled)} for cobra_rear, warning and
    strike, each standing still until LEAD_IN after t0 and idle again at its end."""
    beh, loco = rig.behaviour, rig.locomotion
    a = t0 + LEAD_IN
    idle = Drive(0.0, "idle")
    rise = rig.cobra.ramp_time
    hold = max(beh.scout_time, 2.0 * rise)
    lunge = LUNGE * rig.body.length
    speed = loco.max_speed * beh.onslaught_speed
    # the agent's time for the lunge: accelerate and brake (triangle), or cruise between
    lunge_s = (2.0 * math.sqrt(lunge / loco.acceleration) if lunge * loco.acceleration < speed ** 2
               else lunge / speed + speed / loco.acceleration)
    bite = a + rise + lunge_s + 0.1
    return {
        "cobra_rear": ([idle, Drive(a, "cobra_rear", cobra=1.0), Drive(a + rise + hold, "idle")],
                       LEAD_IN + rise + hold + rise + SETTLE),
        "warning": ([idle, Drive(a, "warning", warning=1.0),
                     Drive(a + beh.warning_time, "idle")],
                    LEAD_IN + beh.warning_time + SETTLE),
        "strike": ([idle, Drive(a, "strike", cobra=1.0),
                    Drive(a + rise, "strike", cobra=1.0, ahead=lunge,
                          speed_scale=beh.onslaught_speed, turn_scale=beh.onslaught_turn_rate),
                    Drive(bite, "strike", halt=True),
                    Drive(bite + beh.strike_time, "idle")],
                   bite - t0 + beh.strike_time + rise + SETTLE),
    }


def chain_rates(rig: RigConfig, period: float) -> dict:
    """The antennae's and ultimate legs' frequencies [Hz] as played in a loop of `period` s."""
    from baker.locomotion.legs import ULTIMATE_SWAY_HZ, whole_cycles

    rate = rig.legs.antenna_rate
    return {"antenna_sweep": whole_cycles(rate, period),
            "antenna_grope": whole_cycles(0.5 * rate, period),
            "ultimate_sway": [whole_cycles(f, period) for f in ULTIMATE_SWAY_HZ]}


def foot_slide(rig, clip: Clip) -> float:
    """Largest distance [m] a walking leg's foot joint moves over the clip (world)."""
    feet = [i for i, nm in enumerate(rig.skeleton.names)
            if nm.startswith("leg_") and nm.endswith("_foot")]
    t, _ = clip.world(rig.skeleton.parents)
    if not feet:
        return 0.0
    f = t[:, feet]
    return float(np.linalg.norm(f - f[:1], axis=-1).max())
