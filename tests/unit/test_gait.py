"""Gait clock, leg layout and the walking legs on synthetic bodies over flat ground."""

import numpy as np
import pytest

from baker.environment.model import Environment, Sun
from baker.geometry.transforms import normalize
from baker.locomotion.body import BodyFrames
from baker.locomotion.gait import gait_clock, stance_mask, stride_length
from baker.locomotion import legs
from baker.locomotion.legs import leg_frames, walking_legs
from baker.rig.limbs import leg_layout
from conftest import flat_ground


def test_phase_advances_with_distance_not_time():
    t = np.arange(301) / 30.0
    v = np.where(t < 4.0, 0.2, 0.0)                      # walk 4 s, then stand still 6 s
    arc = np.concatenate([[0.0], np.cumsum(v[1:] / 30.0)])
    c = gait_clock(arc, t, max_speed=0.2, stride_min=0.04, stride_max=0.075, smooth_s=0.0)
    walking = t < 3.9
    np.testing.assert_allclose(np.diff(c.phase)[walking[1:]], (0.2 / 30.0) / 0.075, rtol=1e-9)
    assert np.all(np.diff(c.phase)[t[1:] > 4.05] == 0.0)  # stopped body: the gait stops
    assert np.all(np.diff(c.phase) >= 0)


def test_stride_grows_with_speed():
    s = stride_length(np.array([0.0, 0.05, 0.1, 0.2, 0.4]), 0.2, 0.04, 0.075)
    assert np.all(np.diff(s) >= 0) and s[0] == 0.04 and s[-1] == 0.075


def test_layout_is_a_retrograde_two_wave_gait_in_antiphase(rig_config):
    lay = leg_layout(rig_config)
    assert lay.n_legs == 2 * (rig_config.body.segments - 1)
    assert lay.upper_names[:3] == ("leg_L_01_upper", "leg_R_01_upper", "leg_L_02_upper")
    assert lay.tip_names[13] == "leg_R_07_tip"
    left, right = lay.lag[0::2], lay.lag[1::2]
    d = (left[:-1] - left[1:]) % 1.0                      # rear leg lags its front neighbour
    np.testing.assert_allclose(d, rig_config.legs.waves / (rig_config.body.segments - 1))
    np.testing.assert_allclose(d * 360.0, 36.0)
    np.testing.assert_allclose((right - left) % 1.0, 0.5)
    phase = np.linspace(0, 5, 501)[:, None] + lay.lag[None, :]
    duty = stance_mask(phase, rig_config.legs.duty).mean()
    assert abs(duty - rig_config.legs.duty) < 0.01


def _straight_body(cfg, speed, seconds=6.0, stop_at=None, fps=30):
    """BodyFrames of a spine walking along +Z on y = 0 ground at `speed`, optionally stopping."""
    b = cfg.body
    t = np.arange(int(seconds * fps) + 1) / fps
    v = np.full(len(t), speed)
    if stop_at is not None:
        v[t >= stop_at] = 0.0
    arc = np.concatenate([[0.0], np.cumsum(v[1:] / fps)]) + b.length
    z = arc[:, None] - b.spacing * np.arange(b.segments)[None, :]
    pos = np.stack([np.zeros_like(z), np.full_like(z, b.clearance), z - 1.0], -1)
    rot = np.zeros(z.shape + (4,))
    rot[..., 3] = 1.0
    normals = np.zeros_like(pos)
    normals[..., 1] = 1.0
    return BodyFrames(positions=pos, rotations=rot, normals=normals,
                      ground=np.zeros_like(z)), arc, t


@pytest.fixture(scope="module")
def flat_env():
    return Environment(meshes=(flat_ground(size=8.0, n=8),), sun=Sun(direction=normalize(
        np.array([0.3, 0.9, 0.2]))), source="", name="flat")


def test_walking_legs_plant_feet_and_keep_the_rhythm(rig_config, flat_env):
    bf, arc, t = _straight_body(rig_config, speed=0.15, seconds=8.0)
    w = walking_legs(bf, arc, t, flat_env.rays, rig_config)
    feet, c = w["feet"], w["contacts"]
    bl = rig_config.body.length
    # planted feet do not move, and sit on the ground
    still = c[1:] & c[:-1]
    step = np.linalg.norm(np.diff(feet, axis=0), axis=-1)
    assert step[still].max() < 1e-9
    assert np.abs(feet[..., 1][c]).max() < 1e-8     # a foothold is a float32 ray hit
    # swinging feet stay above the ground and land exactly where they were aimed
    assert feet[..., 1].min() > -1e-8
    assert np.linalg.norm(w["feet"] - w["targets"], axis=-1)[c].max() < 1e-9
    # duty factor near the setting, rhythm as set
    assert 0.45 < c[30:].mean() < 0.65
    td = c[1:] & ~c[:-1]
    for a in range(0, 36, 7):
        fa = np.nonzero(td[:, a])[0]
        fr = np.nonzero(td[:, a + 2])[0]
        k = np.searchsorted(fa, fr) - 1
        ok = (k >= 0) & (k < len(fa) - 1)
        lag = (arc[fr[ok] + 1] - arc[fa[k[ok]] + 1]) / (arc[fa[k[ok] + 1] + 1] - arc[fa[k[ok]] + 1])
        assert abs(np.median(lag) - 0.1) < 0.05
    # no neighbouring feet on one side closer than 20% of the spacing
    gaps = np.linalg.norm(feet[:, 2:] - feet[:, :-2], axis=-1)
    assert gaps.min() > 0.2 * rig_config.body.spacing
    assert np.all(np.isfinite(w["rotations"]))
    assert step.max() < 0.2 * bl


def test_feet_settle_when_the_body_stops(rig_config, flat_env):
    bf, arc, t = _straight_body(rig_config, speed=0.2, seconds=6.0, stop_at=3.0)
    w = walking_legs(bf, arc, t, flat_env.rays, rig_config)
    after = t >= 3.0 + rig_config.legs.settle_time + 2.0 / 30.0
    assert w["contacts"][after].all()                     # every foot is down ...
    f = w["feet"][after]
    assert np.abs(np.diff(f, axis=0)).max() < 1e-12       # ... and stays put


def test_leg_frames_names_and_shapes(rig, rig_config, flat_env):
    bf, arc, t = _straight_body(rig_config, speed=0.1, seconds=2.0)
    lf = leg_frames(bf, arc, t, flat_env.rays, rig_config)
    names = set(rig.skeleton.names)
    assert set(lf.names) <= names
    assert {"leg_L_07_upper", "leg_R_20_tip", "ultimate_L_upper", "antenna_R_2"} <= set(lf.names)
    assert lf.positions.shape == (len(t), len(lf.names), 3)
    assert lf.rotations.shape == (len(t), len(lf.names), 4)
    np.testing.assert_allclose(np.linalg.norm(lf.rotations, axis=-1), 1.0, atol=1e-9)


def test_warning_raises_the_ultimate_legs(rig_config, flat_env):
    bf, arc, t = _straight_body(rig_config, speed=0.0, seconds=3.0)
    warning = (t >= 1.0).astype(float)
    lf = leg_frames(bf, arc, t, flat_env.rays, rig_config, warning=warning)
    from baker.metrics import quat_rotate_y

    i = lf.names.index("ultimate_L_upper")
    y = quat_rotate_y(lf.rotations[:, i])                 # bone direction, world (+Y up here)
    pitch = np.degrees(np.arcsin(np.clip(y[:, 1], -1, 1)))
    assert abs(pitch[0] - np.degrees(rig_config.legs.ultimate_raise)) < 8.0
    assert pitch[-1] > 70.0                               # Posture 1: raised near vertical
    steps = np.abs(np.diff(pitch))
    assert steps.max() < 15.0                             # eased, not snapped


def test_antennae_dip_under_a_low_ceiling(rig_config):
    """Under a ceiling 14 mm up (the antennae reach 16 mm on open ground), no raise clears
    and the chains dip instead; they used to be raised fully, straight into the ceiling
    (every second antenna bone through it in every frame: inside the showcase's hollow log)."""
    import trimesh

    from baker.locomotion.legs import posed_chains

    v = np.array([[-1, 0.014, -3], [1, 0.014, -3], [1, 0.014, 3], [-1, 0.014, 3]], float)
    ceiling = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    env = Environment(meshes=(flat_ground(size=8.0, n=8), ceiling), sun=Sun(direction=normalize(
        np.array([0.3, 0.9, 0.2]))), source="", name="low ceiling")
    bf, arc, t = _straight_body(rig_config, speed=0.1, seconds=4.0)
    names, pos, rot = posed_chains(bf, t, env.rays, rig_config)
    _assert_antennae_clear(env, rig_config, names, pos, rot)


def _assert_antennae_clear(env, cfg, names, pos, rot):
    """No antenna bone through the environment, none turning 30 deg or more in a frame."""
    from baker.geometry.transforms import quat_angle
    from baker.metrics import quat_rotate_y

    ant = [i for i, n in enumerate(names) if n.startswith("antenna_")]
    d = quat_rotate_y(rot[:, ant])
    hit = env.rays.first_hit(pos[:, ant].reshape(-1, 3), d.reshape(-1, 3),
                             max_distance=cfg.legs.antenna_length).hit
    assert not hit.any()
    assert np.degrees(quat_angle(rot[1:, ant], rot[:-1, ant])).max() < 30.0


def test_an_antenna_beside_a_post_sweeps_less_far_rather_than_through_it(rig_config, flat_env):
    """A resting head with a thin post 2 cm ahead and 2 cm to its left, in the left antenna's
    sweep: the full sweep clears the post only reared far up, and the raise eased to it, then
    the antenna's turn limit, left the tip bone through the post (17 bone-frames in 4 s; a
    100-creature minute, 2797015: 91 over 60 s beside a stem). Now that antenna sweeps less
    far (legs._sweep_share) and clears it every frame; the right antenna, with nothing near
    it, sweeps as on open ground."""
    import trimesh

    from baker.locomotion.legs import posed_chains
    from baker.metrics import quat_rotate_y

    bf, arc, t = _straight_body(rig_config, speed=0.0, seconds=4.0)
    head = bf.positions[0, 0]
    post = trimesh.creation.box(extents=(0.004, 0.3, 0.004))
    post.apply_translation((0.02, 0.15, head[2] + 0.02))
    env = Environment(meshes=(flat_ground(size=8.0, n=8), post), sun=flat_env.sun, source="",
                      name="post")
    names, pos, rot = posed_chains(bf, t, env.rays, rig_config)
    _assert_antennae_clear(env, rig_config, names, pos, rot)
    _, pos0, rot0 = posed_chains(bf, t, flat_env.rays, rig_config)
    right = [i for i, n in enumerate(names) if n.startswith("antenna_R")]
    left = [i for i, n in enumerate(names) if n.startswith("antenna_L")]
    assert np.array_equal(rot[:, right], rot0[:, right])
    # the left antenna still sweeps (less far): its tip moves sideways over a few centimetres
    tip = pos[:, left[1]] + quat_rotate_y(rot[:, left[1]]) * rig_config.legs.antenna_length
    assert np.ptp(tip[:, 0]) > 0.005


@pytest.mark.parametrize("x, dz, width", [(0.02, 0.025, 0.004), (0.02, 0.03, 0.01),
                                           (0.015, 0.03, 0.01), (0.01, 0.03, 0.01)])
def test_an_antenna_beside_a_post_on_its_sweeps_way_back_clears_it(rig_config, x, dz, width):
    """Posts beside a resting head where the share of the sweep that clears changes sign over
    the sweep's cycle: away from the sweep clears the post going one way and meets it coming
    back (a 100-creature minute, 9032774: one resting creature's antenna tip through a post in
    163 bone-frames). The share eased frame by frame crossed the shares that meet the post
    (15, 10, 3 and 2 bone-frames in these 4 s); the cheapest path through the shares
    (legs._sweep_share) clears it every frame."""
    import trimesh

    from baker.locomotion.legs import posed_chains

    bf, arc, t = _straight_body(rig_config, speed=0.0, seconds=4.0)
    head = bf.positions[0, 0]
    post = trimesh.creation.box(extents=(width, 0.3, width))
    post.apply_translation((x, 0.15, head[2] + dz))
    env = Environment(meshes=(flat_ground(size=8.0, n=8), post), sun=Sun(direction=normalize(
        np.array([0.3, 0.9, 0.2]))), source="", name="post")
    names, pos, rot = posed_chains(bf, t, env.rays, rig_config)
    _assert_antennae_clear(env, rig_config, names, pos, rot)


def test_a_warning_under_a_low_overhang_raises_the_ultimate_legs_only_as_far_as_it_clears(
        rig_config):
    """Posture 1 under a ceiling 45 mm up (a rest under the showcase's bark sheet): the full
    warning raise, near vertical, drove both ultimate tips into it (showcase 94033, 5 tip-bone
    hits), and no dip from the raised pitch cleared. The raise now stops where the legs clear
    it, eased in, and is still a raise."""
    import trimesh

    from baker.geometry.transforms import quat_angle
    from baker.locomotion.legs import posed_chains
    from baker.metrics import quat_rotate_y

    v = np.array([[-1, 0.045, -3], [1, 0.045, -3], [1, 0.045, 3], [-1, 0.045, 3]], float)
    ceiling = trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)
    env = Environment(meshes=(flat_ground(size=8.0, n=8), ceiling), sun=Sun(direction=normalize(
        np.array([0.3, 0.9, 0.2]))), source="", name="low overhang")
    bf, arc, t = _straight_body(rig_config, speed=0.0, seconds=3.0)
    warning = (t >= 1.0).astype(float)
    names, pos, rot = posed_chains(bf, t, env.rays, rig_config, warning=warning)
    ult = [i for i, n in enumerate(names) if n.startswith("ultimate_")]
    d = quat_rotate_y(rot[:, ult])
    lengths = np.array([rig_config.legs.ultimate_upper if n.endswith("upper")
                        else rig_config.legs.ultimate_tip for n in np.array(names)[ult]])
    hit = env.rays.first_hit(pos[:, ult].reshape(-1, 3), d.reshape(-1, 3),
                             max_distance=np.tile(lengths, len(t))).hit
    assert not hit.any()
    assert np.degrees(quat_angle(rot[1:, ult], rot[:-1, ult])).max() < 30.0
    up = quat_rotate_y(rot[:, names.index("ultimate_L_upper")])[:, 1]
    pitch = np.degrees(np.arcsin(np.clip(up, -1, 1)))
    assert pitch[-1] > np.degrees(rig_config.legs.ultimate_raise) + 10.0    # still raised



def test_an_eased_knee_frame_that_hits_joins_its_run_with_the_frames_between():
    """legs._joined: the knees' swivel is chosen per run of frames; an eased frame whose partial
    swivel hits something joins its leg's nearest run, with the frames between (alone it would
    be a run of its own, keep no swivel, and the easing would put it back)."""
    from baker.locomotion.legs import _joined

    near = np.zeros((12, 2), bool)
    near[5:8, 0] = True
    got = _joined(near, np.array([2, 10, 4]), np.array([0, 0, 1]))
    assert np.flatnonzero(got[:, 0]).tolist() == [2, 3, 4, 5, 6, 7, 8, 9, 10]
    assert np.flatnonzero(got[:, 1]).tolist() == [4]        # no run on that leg: the frame alone


class _StoppedPlan:
    """The step plan of a body that walks 2 s and stands still to 6 s, with leg LEG's stance
    under way at frame LIFT (4 s: planted to the end) lifted early there; plan() makes it
    afresh (_land_early changes it in place)."""
    LEG, LIFT = 5, 120

    def __init__(self, cfg, env):
        self.cfg, self.rays = cfg, env.rays
        bf, arc, self.t = _straight_body(cfg, speed=0.2, seconds=6.0, stop_at=2.0)
        self.lf = legs._leg_frames(bf, cfg)
        self.anchor = legs._anchors(self.rays, self.lf, bf)
        self.clock = gait_clock(arc, self.t, cfg.locomotion.max_speed, self.lf.lg.stride_min,
                                self.lf.lg.stride_max)

    def plan(self):
        st = legs._step_events(self.rays, self.lf, self.clock, self.anchor, self.t)
        holds = legs._footholds(self.rays, self.lf, self.cfg, self.anchor, st)
        leg, lift = self.LEG, self.LIFT
        c = int(np.nonzero((st.Ts[:-1, leg] <= lift) & (st.LOs[:, leg] > lift))[0][0])
        assert st.LOs[c, leg] == len(self.t)                # planted to the end ...
        st.LOs[c, leg] = lift                               # ... until it is lifted
        return st, holds, c

    def land_early(self, st, holds, c) -> bool:
        return legs._land_early(self.rays, self.lf, self.cfg, st, holds, self.anchor, self.t, c)


def test_a_foot_lifted_early_lands_within_the_settle_time(rig_config, flat_env):
    """A planted foot that something makes unusable lifts early (legs._lift_unusable). With
    the body stopped, the phase's next touchdown is never: the foot used to hover beside the
    body until then (15 s in a default bake, its tip bone dragged through a leaf). It lands
    settle_time after lifting, on a new hold on the ground within its leg's reach."""
    p = _StoppedPlan(rig_config, flat_env)
    st, holds, c = p.plan()
    leg, lf, t = p.LEG, p.lf, p.t
    before = (st.Ts.copy(), holds.copy())
    assert p.land_early(st, holds, c)
    land = int(np.searchsorted(t, t[p.LIFT] + rig_config.legs.settle_time - 1e-9))
    assert st.Ts[c + 1, leg] == land and not st.phase_td[c + 1, leg]
    hold = holds[c + 1, leg]
    assert abs(hold[1]) < 1e-6                               # on the ground
    assert np.linalg.norm(hold - lf.hip[land, leg]) < legs.PLAN_REACH * (lf.lay.l1 + lf.lay.l2)
    others = np.arange(lf.shape[1]) != leg
    np.testing.assert_array_equal(st.Ts[:, others], before[0][:, others])
    np.testing.assert_array_equal(holds[:, others], before[1][:, others])
    # a foot lifted in time (landing before the phase's touchdown anyway) is left alone
    assert not p.land_early(st, holds, c)


def test_a_foot_lifted_early_waits_for_a_hold_it_can_keep(rig_config, flat_env, monkeypatch):
    """The early landing's hold must stay usable for a settle time (legs._Frames.first_bad):
    when the first is not, the foot lands a settle time later; when none is before the phase's
    touchdown, it keeps hanging (no tapping on holds it must leave at once)."""
    p = _StoppedPlan(rig_config, flat_env)
    t, settle = p.t, rig_config.legs.settle_time
    unusable_until = {"frame": len(t)}
    real = legs._Frames.first_bad

    def first_bad(self, rays_, hold, start, stop, sight=False):
        out = real(self, rays_, hold, start, stop, sight)
        early = (start < stop) & (start < unusable_until["frame"])
        return np.where(early, start, out)

    st, holds, c = p.plan()
    ts, hs = st.Ts.copy(), holds.copy()
    monkeypatch.setattr(legs._Frames, "first_bad", first_bad)
    assert not p.land_early(st, holds, c)
    np.testing.assert_array_equal(st.Ts, ts)
    np.testing.assert_array_equal(holds, hs)
    # usable from 2.5 settle times after the lift: it lands at the third settle time
    monkeypatch.undo()
    st, holds, c = p.plan()
    unusable_until["frame"] = int(np.searchsorted(t, t[p.LIFT] + 2.5 * settle))
    monkeypatch.setattr(legs._Frames, "first_bad", first_bad)
    assert p.land_early(st, holds, c)
    assert st.Ts[c + 1, p.LEG] == np.searchsorted(t, t[p.LIFT] + 3 * settle - 1e-9)


class _PitchBands:
    """A stand-in environment for a chain whose base sits at x = frame (its bones are shorter
    than half a metre): from frame `first` to `last`, a bone pitched between `lo` and `hi`
    degrees meets something, for each (first, last, lo, hi) of `bands`."""

    def __init__(self, bands):
        self.bands = [(a, b, np.radians(lo), np.radians(hi)) for a, b, lo, hi in bands]

    def blocked(self, frame, pitch):
        return np.logical_or.reduce([(frame >= a) & (frame <= b) & (pitch > lo) & (pitch < hi)
                                     for a, b, lo, hi in self.bands])

    def occluded(self, origins, directions, max_distance=np.inf):
        return self.blocked(np.rint(np.asarray(origins)[:, 0]),
                            np.arcsin(np.clip(np.asarray(directions)[:, 1], -1.0, 1.0)))


def test_a_chain_eased_down_through_an_overhangs_reach_is_searched_afresh_not_jumped():
    """legs._eased_chain: an antenna raised 45 deg clear of a stone at frames 10-14 eases
    back down at CHAIN_RAISE_RATE a frame, but from frame 17 on every raise between 12 and 62
    deg meets an overhang, and from frame 21 on every raise above 12 deg (an antenna of
    creature 17 of a crowd of 20 on Recast's undulating level, seed 117910). The easing's
    rounds raised the chain into the closing gap above; the last resort then jumped it to
    the nearest clearing raise, and the antenna's turn limit held it back into the overhang
    (2 antenna bone hits). Now the raises round those frames are searched afresh
    (_chain_path): every frame clears and no raise changes faster than CHAIN_STEEP_RATE a
    frame."""
    from baker.locomotion.legs import (CHAIN_STEEP_RATE, _chain_pose, _chain_touches,
                                       _eased_chain)

    F = 60
    q = np.tile([0.0, 0.0, 0.0, 1.0], (F, 1))
    o = np.column_stack([np.arange(F, dtype=float), np.zeros(F), np.zeros(F)])
    rays = _PitchBands([(10, 14, -90.0, 40.0), (17, 99, 12.0, 62.0), (21, 99, 12.0, 90.0)])
    steps = np.radians([0.0, 6.0, 12.0, 20.0, 30.0, 45.0, 60.0, 80.0, -8.0, -16.0])
    base = np.zeros(F)
    yaws, bend, lengths = (np.zeros(F), np.zeros(F)), 0.0, (0.2, 0.2)
    raw = np.where((np.arange(F) >= 10) & (np.arange(F) <= 14), np.radians(45.0), 0.0)
    ok_all = ~rays.blocked(np.arange(F)[:, None], steps[None, :])
    d1, d2, knee = _eased_chain(rays, q, o, 1.0, yaws, base, bend, lengths, False, steps, raw,
                                ok_all)
    assert not _chain_touches(rays, o, d1, d2, knee, lengths).any()
    pitch = np.arcsin(np.clip(d1[:, 1], -1.0, 1.0))
    assert np.abs(np.diff(pitch)).max() <= CHAIN_STEEP_RATE + 1e-9
    assert (pitch[10:15] >= np.radians(40.0)).all()       # raised over the stone
    # the chain's bones are those of its pose at those pitches
    p1, p2, pk = _chain_pose(q, o, 1.0, yaws, pitch, bend, lengths[0], False)
    np.testing.assert_allclose(np.stack([d1, d2, knee]), np.stack([p1, p2, pk]), atol=1e-12)
