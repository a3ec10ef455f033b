"""Keyframe reduction (export.reduce): the world-space bound holds in the files as players read
them back (GLB: baker.inspect.read_glb; USD: usd-core UsdSkel), tolerance 0 changes nothing,
static channels are dropped, planted feet stay planted, the validators pass, and the outputs are
deterministic."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from glb_read import Glb
from scipy.spatial.transform import Rotation, Slerp
from validator import gltf_validate, issues_summary, usd_validate

from baker.atomic import atomic_write_bytes
from baker.clip import Clip, NodeTrack
from baker.errors import ExportError
from baker.export import reduce as red
from baker.export.gltf import build_glb
from baker.export.usd import build_stage, write_usd
from baker.inspect import read_glb, read_usd

TOL = 0.00025            # 0.1% of the 0.25 m body
SLACK = 2e-6             # float32 playback and read-back rounding


def _reduce(clip, rig, tol=TOL, **kw):
    skel = rig.skeleton
    return red.reduce_clip(clip, skel.parents, tol, rest=(skel.rest_translations,
                                                          skel.rest_rotations), **kw)


def _glb(tmp_path, name, env, rig, clip, **kw):
    path = tmp_path / f"{name}.glb"
    atomic_write_bytes(path, build_glb(env, rig, clip, extras={}, **kw))
    return path


def _anim_bytes(glb: Glb, anim: int = 0) -> int:
    a = glb.doc["animations"][anim]
    views = {glb.doc["accessors"][s[k]]["bufferView"] for s in a["samplers"]
             for k in ("input", "output")}
    return sum(glb.doc["bufferViews"][v]["byteLength"] for v in views)


@pytest.fixture(scope="module")
def reduced(clip, rig):
    return _reduce(clip, rig, short_rotations=True)


@pytest.fixture(scope="module")
def files(tmp_path_factory, small_env, rig, clip, reduced):
    tmp = tmp_path_factory.mktemp("reduce")
    out = {"full": _glb(tmp, "full", small_env, rig, clip),
           "reduced": _glb(tmp, "reduced", small_env, rig, reduced)}
    out["usd"] = tmp / "reduced.usd"
    write_usd(out["usd"], small_env, rig, reduced, fps=reduced.fps, extras={})
    return out


def test_reduction_keeps_fewer_keys_and_reports_them(clip, reduced):
    k = reduced.keys
    assert k is not None and k.short_rotations
    stats = red.reduction_stats(clip, reduced)
    assert stats["keys_after"] < stats["keys_before"] / 3
    assert stats["bytes_after"] < stats["bytes_before"] / 3
    assert 0 < stats["max_error_m"] <= TOL
    assert stats["tolerance_m"] == TOL and stats["rotations"] == "short"


def test_glb_joints_within_tolerance_of_the_unreduced(files, rig):
    full, got = read_glb(files["full"]), read_glb(files["reduced"])
    assert got.names == full.names and got.n_frames == full.n_frames
    err = np.linalg.norm(got.positions - full.positions, axis=-1)         # every joint, frame
    assert err.max() <= TOL + SLACK
    ends = [full.index(n) for n in full.names if n.endswith(("_foot", "_tip", "_end"))]
    assert len(ends) >= 40 and err[:, ends].max() <= TOL + SLACK
    assert err.max() > 0.3 * TOL           # it did use the tolerance


def test_usd_joints_within_tolerance_and_match_the_glb(files, clip, rig):
    usd = read_usd(files["usd"])
    world, _ = clip.world(rig.skeleton.parents)
    idx = [usd.names.index(n) for n in rig.skeleton.names]
    assert np.linalg.norm(usd.positions[:, idx] - world, axis=-1).max() <= TOL + SLACK
    glb = read_glb(files["reduced"])
    gi = [glb.index(n) for n in rig.skeleton.names]
    assert np.linalg.norm(usd.positions[:, idx] - glb.positions[:, gi], axis=-1).max() < 1e-4


def test_played_joints_are_what_the_usd_stores(files, reduced, rig):
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(files["usd"]))
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Centipede/Animation"))
    t, q, _ = red.played_joints(reduced)
    for f in (0, reduced.n_frames // 3, reduced.n_frames - 1):
        tc = Usd.TimeCode(float(f))
        assert np.array_equal(np.array(anim.GetTranslationsAttr().Get(tc)), t[f])
        assert np.array_equal(np.array(anim.GetRotationsAttr().Get(tc)), q[f])
    assert not anim.GetScalesAttr().GetTimeSamples()        # static: one default value


def test_tolerance_zero_writes_every_key_unchanged(tmp_path, small_env, rig, clip):
    same = red.reduce_clip(clip, rig.skeleton.parents, 0.0)
    assert same.keys is None
    assert build_glb(small_env, rig, same, extras={}) == build_glb(small_env, rig, clip, extras={})
    stages = [build_stage(small_env, rig, c, fps=30, extras={}) for c in (same, clip)]
    a, b = (s.GetRootLayer().ExportToString() for s in stages)      # the stages own the layers
    assert a == b
    stats = red.reduction_stats(clip, same)
    assert stats["keys_after"] == stats["keys_before"]
    assert stats["bytes_after"] == stats["bytes_before"] == _anim_bytes(
        Glb(build_glb(small_env, rig, clip, extras={})))


def test_static_channels_are_dropped(files, reduced, rig):
    glb = Glb(files["reduced"].read_bytes())
    names = [n["name"] for n in glb.doc["nodes"]]
    animated = {(names[c["target"]["node"]], c["target"]["path"])
                for c in glb.doc["animations"][0]["channels"]}
    k, skel = reduced.keys, rig.skeleton
    for j, name in enumerate(skel.names):
        for path, keys in (("translation", k.translations), ("rotation", k.rotations),
                           ("scale", k.scales)):
            assert ((name, path) in animated) == (not keys.is_static[j]), (name, path)
    static_t = np.flatnonzero(k.translations.is_static)
    assert len(static_t) > skel.n_joints // 2          # legs, antennae, end joints...
    assert all(p == "translation" or p == "rotation" for _, p in animated)
    node = glb.doc["nodes"][names.index("leg_L_05_foot")]   # a static end joint keeps its rest
    np.testing.assert_allclose(node["translation"],
                               skel.rest_translations[skel.index("leg_L_05_foot")], atol=1e-7)


def test_animation_bytes_are_counted_as_written(files, clip, reduced):
    glb = Glb(files["reduced"].read_bytes())
    assert red.glb_animation_bytes(reduced) == _anim_bytes(glb)
    assert red.glb_animation_bytes(clip) == _anim_bytes(Glb(files["full"].read_bytes()))
    a = glb.doc["animations"][0]
    keys = sum(glb.doc["accessors"][s["input"]]["count"] for s in a["samplers"])
    assert keys == red.clip_key_count(reduced)
    assert len({s["input"] for s in a["samplers"]}) < len(a["samplers"])   # shared time sets


def test_rotations_are_normalized_shorts(files):
    glb = Glb(files["reduced"].read_bytes())
    a = glb.doc["animations"][0]
    rot = [a["samplers"][c["sampler"]]["output"] for c in a["channels"]
           if c["target"]["path"] == "rotation"]
    assert rot
    for i in rot:
        acc = glb.doc["accessors"][i]
        assert acc["componentType"] == 5122 and acc["normalized"] is True
        q = glb.accessor(i).astype(np.float64) / 32767
        assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 5e-5


def test_float_rotations_stay_within_tolerance(tmp_path, small_env, rig, clip):
    r = _reduce(clip, rig, short_rotations=False)
    assert not r.keys.short_rotations and r.keys.rotations.codes is None
    got, full = read_glb(_glb(tmp_path, "f", small_env, rig, r)), read_glb(
        _glb(tmp_path, "u", small_env, rig, clip))
    assert np.linalg.norm(got.positions - full.positions, axis=-1).max() <= TOL + SLACK
    doc = Glb((tmp_path / "f.glb").read_bytes()).doc
    assert {a["componentType"] for a in doc["accessors"]} <= {5126, 5123, 5125}


def test_tighter_tolerance_keeps_more_keys(clip, rig, reduced):
    tight = _reduce(clip, rig, TOL / 4, short_rotations=True)
    assert tight.keys.max_error_m <= TOL / 4
    assert red.clip_key_count(tight) > red.clip_key_count(reduced)


def test_validators_pass_on_reduced_files(files):
    report = gltf_validate(files["reduced"])
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []
    from pxr import Usd

    assert usd_validate(Usd.Stage.Open(str(files["usd"]))) == []


def test_reduction_is_deterministic(tmp_path, small_env, rig, clip, files):
    again = _reduce(clip, rig, short_rotations=True)
    assert build_glb(small_env, rig, again, extras={}) == files["reduced"].read_bytes()
    write_usd(tmp_path / "again.usd", small_env, rig, again, fps=30, extras={})
    assert (tmp_path / "again.usd").read_bytes() == files["usd"].read_bytes()


def test_incremental_playback_is_a_fresh_playback(clip, rig):
    """The refinement replays only the (joint, frame) pairs that can change: after keys are
    added its arrays are exactly (bit for bit) those of a first playback of the same keys."""
    skel = rig.skeleton
    x = red._target(clip, skel.parents, None, TOL, True)
    j_count, f_count = x.t0.shape[:2]
    keep_t = np.zeros((j_count, f_count), dtype=bool)
    keep_r = np.zeros((j_count, f_count), dtype=bool)
    keep_t[:, [0, -1]] = keep_r[:, [0, -1]] = True
    static_t, static_r = np.zeros((j_count, 3)), np.tile([0.0, 0, 0, 1], (j_count, 1))
    player = red._Player(x, static_t, static_r)
    player.play(keep_t, keep_r)
    rng = np.random.default_rng(0)
    for _ in range(3):                 # keys added on a few joints, some near the root
        js = rng.choice(j_count, 4, replace=False)
        keep_t[js, rng.integers(1, f_count - 1, 4)] = True
        keep_r[js[::-1], rng.integers(1, f_count - 1, 4)] = True
        player.play(keep_t, keep_r)
    fresh = red._Player(x, static_t, static_r)
    fresh.play(keep_t, keep_r)
    for name in ("vt", "vq", "codes", "tr", "rr", "pos", "wq", "mat", "unit", "blender", "wn",
                 "diff", "err", "spread", "slide", "viol"):
        assert np.array_equal(getattr(player, name), getattr(fresh, name)), name


def _bits_equal(a, b) -> bool:
    a, b = np.asarray(a, np.float32), np.asarray(b, np.float32)
    return a.shape == b.shape and np.array_equal(a.view(np.int32), b.view(np.int32))


def test_compiled_playback_is_the_numpy_playback(reduced):
    """Keys.play (compiled: replay.play_channels) gives `sample` rounded to float32, bit for
    bit, on every channel of a reduced clip: static channels, key frames, the last key, lerps
    and slerps."""
    k = reduced.keys
    for keys, rotation in ((k.translations, False), (k.rotations, True), (k.scales, False)):
        want = red.sample(keys.values, keys.keep, keys.static, reduced.times, rotation)
        assert _bits_equal(keys.play(reduced.times, rotation), want.astype(np.float32))


def test_compiled_playback_of_awkward_rotation_keys():
    """Nearly equal keys (lerped and normalized), equal keys (the first as stored), keys of
    opposite sign (the short way round), unnormalized stored keys, a channel with one key (held
    after it) and one with none (static): the compiled slerp is the numpy one, bit for bit."""
    rng = np.random.default_rng(5)
    f_count, c_count = 40, 7
    q = Rotation.random(f_count * c_count, random_state=3).as_quat().reshape(f_count, c_count, 4)
    q[:, 1] = q[0, 1] + 1e-5 * rng.standard_normal((f_count, 4))      # nearly equal
    q[:, 2] = q[0, 2]                                                 # equal
    q[1::2, 3] = -q[1::2, 3]                                          # opposite signs
    q[:, 4] *= 1.0 + 1e-3 * rng.standard_normal((f_count, 1))         # unnormalized
    values = q.astype(np.float32)
    keep = rng.random((c_count, f_count)) < 0.3
    keep[:, 0] = True
    keep[5] = False
    keep[5, 7] = True                                                 # one key
    keep[6] = False                                                   # static
    static = Rotation.random(c_count, random_state=4).as_quat().astype(np.float32)
    times = np.arange(f_count) / 30.0
    keys = red.Keys(keep, values, static)
    want = red.sample(values, keep, static, times, True).astype(np.float32)
    assert _bits_equal(keys.play(times, True), want)
    want = red.sample(values[..., :3], keep, static[:, :3], times, False).astype(np.float32)
    assert _bits_equal(red.Keys(keep, values[..., :3], static[:, :3]).play(times, False), want)


def test_blame_in_small_blocks_is_the_same(clip, rig, monkeypatch):
    """The refinement blames the offending pairs in blocks (a long skeleton's chains times a
    clip's pairs were gigabytes at once): blocks of a few pairs give the same keys, bit for
    bit."""
    whole = red.reduce_clip(clip, rig.skeleton.parents, TOL, short_rotations=True)
    monkeypatch.setattr(red, "BLAME_PAIRS", 50)         # a few pairs a block
    blocks = red.reduce_clip(clip, rig.skeleton.parents, TOL, short_rotations=True)
    for part in ("translations", "rotations", "scales"):
        a, b = getattr(whole.keys, part), getattr(blocks.keys, part)
        assert np.array_equal(a.keep, b.keep) and np.array_equal(a.values, b.values), part


def test_local_pass_keeps_dense_channels_whole(clip, rig):
    """A channel whose frames mostly miss even between their neighbours is keyed at every
    frame; the others keep what top-down splitting keeps (each segment within tolerance)."""
    f_count = clip.n_frames
    t = np.linspace(0.0, 1.0, f_count)
    smooth = np.stack([t, 0.01 * t * t, np.zeros_like(t)], -1)
    noisy = smooth + np.random.default_rng(1).normal(0, 1e-3, smooth.shape)
    values = np.stack([smooth, noisy], 1).astype(np.float32)             # (F, 2, 3)
    keep, _ = red._local_keys(values, values, clip.times, False, np.full(2, 1e-4), None, 12)
    assert keep[1].all()
    assert 2 <= keep[0].sum() < f_count / 4
    played = red.sample(values, keep, values[0], clip.times, False)
    assert np.linalg.norm(played[:, 0] - values[:, 0], axis=-1).max() <= 1e-4


def test_bad_tolerance_is_an_export_error(clip, rig):
    for bad in (-1e-3, float("nan"), float("inf")):
        with pytest.raises(ExportError):
            red.reduce_clip(clip, rig.skeleton.parents, bad)
    with pytest.raises(ExportError, match="contacts"):
        red.reduce_clip(clip, rig.skeleton.parents, TOL, contacts=np.zeros((2, 2), bool))


# ------------------------------------------------------------------------------- tracks, clips


def _prey_track(n_frames: int) -> NodeTrack:
    t = np.linspace(0.0, 1.0, n_frames)
    pos = np.stack([0.3 * np.sin(2.0 * t), 0.01 + 0.0 * t, 0.5 * t], -1)
    yaw = 1.5 * np.sin(3.0 * t)
    rot = np.stack([0 * t, np.sin(yaw / 2), 0 * t, np.cos(yaw / 2)], -1)
    scale = np.where(t[:, None] < 0.6, 1.0, 0.0) * np.ones((1, 3))
    return NodeTrack("prey_0", pos.astype(np.float32), rot.astype(np.float32),
                     scale.astype(np.float32))


def _sample(times, keys, values, rotation):
    if len(keys) == 1:
        return np.repeat(values[:1], len(times), axis=0)
    if rotation:
        return Slerp(keys, Rotation.from_quat(values))(times).as_quat()
    return np.stack([np.interp(times, keys, values[:, c]) for c in range(3)], 1)


def test_node_tracks_within_tolerance(tmp_path, small_env, rig, clip):
    from baker.rig.props import capsule_mesh

    track = _prey_track(clip.n_frames)
    with_prey = dataclasses.replace(clip, tracks=(track,))
    r = _reduce(with_prey, rig, short_rotations=True)
    v, f = capsule_mesh(0.06, 0.012)
    path = _glb(tmp_path, "prey", small_env, rig, r, props=(("prey_0", v, f, (0.3, 0.4, 0.1)),))
    glb = Glb(path.read_bytes())
    assert issues_summary(gltf_validate(path), 0) == []
    tracks = glb.animation_tracks(0)
    times = clip.times.astype(np.float64)
    tk, tv = tracks[("prey_0", "translation")]
    assert len(tk) < clip.n_frames
    assert np.linalg.norm(_sample(times, tk, tv, False) - track.translations, axis=1).max() <= TOL
    rk, rv = tracks[("prey_0", "rotation")]
    q = _sample(times, rk, rv.astype(np.float64) / (32767 if rv.dtype == np.int16 else 1), True)
    lever = red.levers(rig.skeleton.parents, clip.world(rig.skeleton.parents)[0],
                       clip.translations).max()
    angle = Rotation.from_quat(q).inv() * Rotation.from_quat(track.rotations)
    assert angle.magnitude().max() * lever <= TOL + SLACK
    sk, sv = tracks[("prey_0", "scale")]
    np.testing.assert_array_equal(_sample(times, sk, sv, False), track.scales)   # exact steps


def test_a_channel_animated_in_any_clip_is_in_every_clip(tmp_path, small_env, rig, clip, reduced):
    """A channel may be left out (its value put on the node) only when it is static with the
    same value in every animation of the file; otherwise the clips that hold it still get a key,
    so an engine switching clips never keeps a pose from the previous one."""
    moved = clip.rotations.copy()
    j = rig.skeleton.index("forcipule_L")
    moved[:, j] = Rotation.from_euler("y", np.linspace(0, 0.5, clip.n_frames)[:, None]).as_quat()
    other = dataclasses.replace(clip, name="other", rotations=moved.astype(np.float32))
    other = _reduce(other, rig, short_rotations=True)
    path = _glb(tmp_path, "two", small_env, rig, reduced, extra_clips=(other,))
    glb = Glb(path.read_bytes())
    sets = [{(c["target"]["node"], c["target"]["path"]) for c in a["channels"]}
            for a in glb.doc["animations"]]
    assert sets[0] == sets[1]
    node = glb.node_index("forcipule_L")
    assert (node, "rotation") in sets[0]
    report = gltf_validate(path)
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []
    first = read_glb(path, animation=0)
    assert np.linalg.norm(first.positions - read_glb(_glb(tmp_path, "one", small_env, rig,
                                                          reduced)).positions, axis=-1).max() < 1e-9


# ------------------------------------------------------------------------------- a real bake


@pytest.fixture(scope="module")
def bakes(tmp_path_factory, nav_cache_dir):
    """A short default-scene bake with a prey and per-behaviour clips, unreduced and reduced."""
    from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
    from baker.pipeline import bake

    tmp = tmp_path_factory.mktemp("reduce_bake")
    cfg = BakeConfig(seconds=8, seed=4, rig=load_rig_config(DEFAULT_RIG), prey=1, clips=True,
                     out=tmp / "full", nav_cache_dir=nav_cache_dir)
    return {"full": bake(dataclasses.replace(cfg, tolerance=0.0)),
            "reduced": bake(dataclasses.replace(cfg, out=tmp / "reduced"))}


def test_bake_stays_within_tolerance_and_feet_stay_planted(bakes):
    full, got = (read_glb(bakes[k].outputs["glb"]) for k in ("full", "reduced"))
    tol = bakes["reduced"].report["animation"]["tolerance_m"]
    assert tol == pytest.approx(0.001 * 0.25)
    err = np.linalg.norm(got.positions - full.positions, axis=-1)
    assert err.max() <= tol + SLACK
    usd = read_usd(bakes["reduced"].outputs["usd"])
    idx = [usd.names.index(n) for n in full.names]
    assert np.linalg.norm(usd.positions[:, idx] - full.positions, axis=-1).max() <= tol + SLACK
    # planted feet: between two planted frames a foot moves at most PLANTED_SLIDE x tolerance
    steps = []
    for foot, spans in full.extras["foot_contacts"].items():
        k = got.index(foot)
        for a, b in spans:
            steps.append(np.linalg.norm(np.diff(got.positions[a:b + 1, k], axis=0), axis=1))
    steps = np.concatenate(steps)
    assert steps.size > 1000 and steps.max() <= red.PLANTED_SLIDE * tol + SLACK
    from baker.inspect import judge

    assert judge(got)["metrics"]["skate_median_pct_bl"] < 0.2


def _single_key_bytes(glb: Glb, anim: int = 0) -> int:
    """Bytes of the animation's one-key channels: a channel static in this clip but not in every
    clip of the file (--clips) is written as one key; a file with this clip alone drops it."""
    a, acc = glb.doc["animations"][anim], glb.doc["accessors"]
    single = [s for s in a["samplers"] if acc[s["input"]]["count"] == 1]
    views = {acc[s["output"]]["bufferView"] for s in single}
    views |= {acc[s["input"]]["bufferView"] for s in single}
    return sum(glb.doc["bufferViews"][v]["byteLength"] for v in views)


def test_bake_reports_the_reduction(bakes):
    rep = bakes["reduced"].report["animation"]
    glb = Glb(bakes["reduced"].outputs["glb"].read_bytes())
    assert glb.doc["scenes"][0]["extras"]["animation"] == rep
    # the report counts the clip as written alone in a file (glb_animation_bytes)
    assert rep["bytes_after"] == _anim_bytes(glb, 0) - _single_key_bytes(glb, 0)
    assert rep["bytes_before"] > 3 * rep["bytes_after"]
    assert rep["keys_after"] < rep["keys_before"] and rep["max_error_m"] <= rep["tolerance_m"]
    assert rep["rotations"] == "short" and rep["tolerance_bl"] == 0.001
    assert len(rep["segment_clips"]) == len(glb.doc["animations"]) - 1 >= 1
    assert "reduce" in bakes["reduced"].report["timings_s"]
    full = Glb(bakes["full"].outputs["glb"].read_bytes())
    assert "animation" not in full.doc["scenes"][0]["extras"]           # --tolerance 0: as before
    assert bakes["full"].report["animation"]["ratio"] == 1.0


def test_bake_segments_within_tolerance(bakes):
    glb = Glb(bakes["reduced"].outputs["glb"].read_bytes())
    full = Glb(bakes["full"].outputs["glb"].read_bytes())
    names = [a["name"] for a in glb.doc["animations"]]
    assert names == [a["name"] for a in full.doc["animations"]]
    for name in names[1:]:
        a = read_glb(bakes["reduced"].outputs["glb"], animation=name)
        b = read_glb(bakes["full"].outputs["glb"], animation=name)
        assert np.linalg.norm(a.positions - b.positions, axis=-1).max() <= 0.00025 + SLACK
    report = gltf_validate(bakes["reduced"].outputs["glb"])
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []


@pytest.mark.parametrize("value", ["-0.001", "0.5", "nan", "inf"])
def test_cli_rejects_a_bad_tolerance(tmp_path, capsys, value):
    from baker.cli import main

    code = main(["bake", "--seconds", "1", "--tolerance", value, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "--tolerance" in lines[0], err
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------------------- slow


@pytest.mark.slow
def test_60s_floor_bake_animation_is_5x_smaller(tmp_path, nav_cache_dir):
    """The reduction's Done-when, on the scene it was judged on (the bundled rainforest floor,
    the default scene then; 60 s, no prey): the GLB animation data is at least 5x smaller at
    the default tolerance, no joint is further than the tolerance from the unreduced pose, and
    planted feet skate < 0.2% BL per frame (all measured from the files). The showcase's
    minute (the default bake now) reduces 4.8x: its legs on the leaf litter keep more keys."""
    from baker.config import DEFAULT_RIG, FLOOR_ENVIRONMENT, BakeConfig, load_rig_config
    from baker.inspect import judge
    from baker.pipeline import bake

    cfg = BakeConfig(environment=FLOOR_ENVIRONMENT, prey=0, seconds=60, seed=0,
                     rig=load_rig_config(DEFAULT_RIG), formats=("glb",),
                     out=tmp_path / "full", nav_cache_dir=nav_cache_dir)
    full = bake(dataclasses.replace(cfg, tolerance=0.0))
    got = bake(dataclasses.replace(cfg, out=tmp_path / "reduced"))
    before = _anim_bytes(Glb(full.outputs["glb"].read_bytes()))
    after = _anim_bytes(Glb(got.outputs["glb"].read_bytes()))
    assert before >= 5 * after, (before, after)
    a, b = read_glb(got.outputs["glb"]), read_glb(full.outputs["glb"])
    assert np.linalg.norm(a.positions - b.positions, axis=-1).max() <= 0.00025 + SLACK
    assert judge(a)["metrics"]["skate_median_pct_bl"] < 0.2
    report = gltf_validate(got.outputs["glb"])
    assert issues_summary(report, 0) == [] and issues_summary(report, 1) == []


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".glb", ".usd"])
def test_blender_plays_reduced_files_within_tolerance(tmp_path, suffix, small_env, rig, clip,
                                                      reduced):
    """Blender 5 (BAKER_BLENDER_PYTHON, see test_blender.py) imports the reduced GLB (16-bit
    rotations, sparse keys; it interpolates quaternion components and normalizes) and USD, and
    puts every bone head within the tolerance of the unreduced pose at every frame."""
    import json
    import os
    import shutil
    import subprocess
    from pathlib import Path

    exe = os.environ.get("BAKER_BLENDER_PYTHON", "")
    if not exe or not shutil.which(exe):
        pytest.skip("set BAKER_BLENDER_PYTHON to a Python with bpy to run the Blender check")
    path = tmp_path / f"reduced{suffix}"
    if suffix == ".glb":
        atomic_write_bytes(path, build_glb(small_env, rig, reduced, extras={}))
    else:
        write_usd(path, small_env, rig, reduced, fps=reduced.fps, extras={})
    frames = list(range(clip.n_frames))
    probe = Path(__file__).resolve().parents[1] / "tools" / "blender_probe.py"
    r = subprocess.run([exe, str(probe), str(path), str(clip.fps), ",".join(map(str, frames))],
                       capture_output=True, text=True, timeout=600)
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("PROBE_JSON ")]
    assert lines, f"Blender probe failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    d = json.loads(lines[-1][len("PROBE_JSON "):])
    world, _ = clip.world(rig.skeleton.parents)
    for f in frames:
        got = np.array([d["positions"][str(f)][n] for n in rig.skeleton.names])
        p = world[f]
        want = np.stack([p[:, 0], -p[:, 2], p[:, 1]], -1)          # +Y up -> Blender's +Z up
        assert np.linalg.norm(got - want, axis=1).max() <= TOL + 1e-5, f


# ------------------------------------------------------------------ bones close to the world
def test_bones_near_marks_a_bone_that_clears_an_edge_by_less_than_the_margin():
    """A bone 0.1 mm above a box's top edge is near at a 0.25 mm margin (a reduced pose may move
    it into the box); 2 mm above, or ending on a surface, it is not."""
    import trimesh

    from baker.environment.rays import RayCaster

    rays = RayCaster(trimesh.creation.box((0.1, 0.1, 0.1)))     # top at y = 0.05
    starts, ends = np.ones((3, 2, 3)), np.ones((3, 2, 3))       # bone 1: far away
    ends[:, 1] += 0.01
    for f, y in enumerate((0.0501, 0.052)):
        starts[f, 0], ends[f, 0] = (-0.08, y, 0.0), (0.08, y, 0.0)   # over the top, across it
    starts[2, 0], ends[2, 0] = (0.0, 0.08, 0.0), (0.0, 0.05, 0.0)   # standing on the top
    near = red.bones_near(starts, ends, rays, 0.00025, end_gap=0.002)
    assert near.tolist() == [[True, False], [False, False], [False, False]]


def test_tight_frames_hold_their_joints_closer(clip, rig, reduced):
    """Joints at their tight frames keep within TIGHT_SHARE of the tolerance; the others within
    the tolerance, as before."""
    skel = rig.skeleton
    F, J = clip.translations.shape[:2]
    tight = np.zeros((F, J), dtype=bool)
    tight[F // 3: F // 2, J - 10:] = True
    got = _reduce(clip, rig, short_rotations=True, tight=tight)
    from baker.rig.skeleton import forward_kinematics

    def world(c):
        t, q, _ = red.played_joints(c)
        return forward_kinematics(skel.parents, t.astype(np.float64), q.astype(np.float64))[0]

    w0 = world(clip)
    err0 = np.linalg.norm(world(reduced) - w0, axis=-1)
    err = np.linalg.norm(world(got) - w0, axis=-1)
    assert err[tight].max() <= red.TIGHT_SHARE * TOL + SLACK < err0[tight].max()
    assert err.max() <= TOL + SLACK
    with pytest.raises(ExportError):
        _reduce(clip, rig, tight=tight[:-1])


def _long_chain_clip(j_count: int, f_count: int = 90) -> tuple:
    """A single chain of j_count joints 4 mm apart, each bending a little on a wave of its own:
    (clip, parents)."""
    rng = np.random.default_rng(3)
    t = np.arange(f_count, dtype=np.float32) / np.float32(30)
    phase = rng.uniform(0, 2 * np.pi, (j_count, 2))
    angle = 0.02 * np.sin(2.0 * t[:, None, None] + phase[None])            # (F, J, 2)
    rot = Rotation.from_euler("yz", angle.reshape(-1, 2)).as_quat().astype(np.float32)
    trans = np.zeros((f_count, j_count, 3), np.float32)
    trans[:, 1:, 0] = 0.004
    clip = Clip("chain", t, trans, rot.reshape(f_count, j_count, 4),
                np.ones((f_count, j_count, 3), np.float32))
    return clip, np.arange(j_count) - 1


def _first_round_offenders(clip, parents, monkeypatch) -> tuple[int, float]:
    """(offending (joint, frame) pairs when the world refinement starts, the final error)."""
    seen = []
    blame = red._blame

    def counted(x, chains, p):
        seen.append(int(p.viol.sum()))
        return blame(x, chains, p)

    monkeypatch.setattr(red, "_blame", counted)
    out = red.reduce_clip(clip, parents, TOL)
    monkeypatch.setattr(red, "_blame", blame)
    return (seen[0] if seen else 0), out.keys.max_error_m


def test_a_long_body_shares_the_local_tolerance_along_its_chains(clip, rig, monkeypatch):
    """Between keys the errors of all a joint's ancestors add up at it: a joint deeper than
    DEPTH_SHARED gets its local tolerance divided by depth / DEPTH_SHARED, so the world
    refinement of a very long body starts with fewer offending pairs (each blamed over every
    ancestor), and still ends within the tolerance. The rig's own chains are not that deep:
    its reduction is unchanged."""
    parents = rig.skeleton.parents
    assert np.all(red._local_share(parents, TOL) == red.LOCAL_SHARE * TOL)
    long_clip, chain = _long_chain_clip(160)
    share = red._local_share(chain, TOL)
    assert share[0] == red.LOCAL_SHARE * TOL
    assert share[-1] == pytest.approx(red.LOCAL_SHARE * TOL * red.DEPTH_SHARED / 160)
    shared, err = _first_round_offenders(long_clip, chain, monkeypatch)
    monkeypatch.setattr(red, "DEPTH_SHARED", 10**9)          # one share for every joint
    alone, err_alone = _first_round_offenders(long_clip, chain, monkeypatch)
    assert shared < alone
    assert err <= TOL and err_alone <= TOL


def _turning_chain_clip(j_count: int = 21, f_count: int = 150, spacing: float = 0.0125) -> tuple:
    """A chain of j_count joints a spacing apart whose bones turn (each local translation keeps
    its length and swings on a wave of its own) while the joints rotate: (clip, parents)."""
    rng = np.random.default_rng(5)
    t = np.arange(f_count, dtype=np.float32) / np.float32(30)
    phase = rng.uniform(0, 2 * np.pi, (j_count, 3))
    angle = 0.3 * np.sin(1.5 * t[:, None, None] + phase[None])              # (F, J, 3)
    rot = Rotation.from_euler("xyz", angle.reshape(-1, 3)).as_quat().astype(np.float32)
    trans = np.zeros((f_count, j_count, 3))
    swing = angle[..., 0]
    trans[:, 1:, 0] = spacing * np.sin(swing[:, 1:])
    trans[:, 1:, 2] = -spacing * np.cos(swing[:, 1:])
    trans[:, 0] = np.stack([t, 0.0 * t, 0.2 * t], axis=-1)
    clip = Clip("turning", t, trans.astype(np.float32), rot.reshape(f_count, j_count, 4),
                np.ones((f_count, j_count, 3), np.float32))
    return clip, np.arange(j_count) - 1


def test_rigid_bones_keep_their_length(monkeypatch):
    """A spine joint turns while its translation keeps its length (a spacing from the joint
    ahead). World errors alone let a joint and its parent each be off by up to the tolerance, so
    their distance by twice it. The reduction keys a rigid bone's chain where its played length
    is off by more than LENGTH_SHARE, so the spacing stays within it; without that check it
    does not (here 3.3 % off at a 0.5 mm tolerance on a 12.5 mm spacing)."""
    from baker.rig.skeleton import forward_kinematics

    spacing = 0.0125
    clip, parents = _turning_chain_clip(spacing=spacing)
    joints, lengths = red.rigid_bones(clip.translations.astype(np.float64), parents)
    assert joints.tolist() == list(range(1, len(parents)))
    np.testing.assert_allclose(lengths, spacing, rtol=1e-6)

    def spacing_error(c):
        t, q, _ = red.played_joints(c)
        pos = forward_kinematics(parents, t.astype(np.float64), q.astype(np.float64))[0]
        d = np.linalg.norm(pos[:, 1:] - pos[:, :-1], axis=-1)
        return np.abs(d / spacing - 1.0).max()

    tol = 0.0005
    got = red.reduce_clip(clip, parents, tol, short_rotations=True)
    assert spacing_error(got) <= red.LENGTH_SHARE + 1e-5
    assert got.keys.max_error_m <= tol
    assert got.keys.translations.keep.sum() < 0.25 * got.keys.translations.keep.size
    share = red.LENGTH_SHARE
    monkeypatch.setattr(red, "LENGTH_SHARE", 1.0)
    assert spacing_error(red.reduce_clip(clip, parents, tol, short_rotations=True)) > 2 * share


def _world(clip, rig):
    """(F, J, 3) world joint positions of the clip as a player plays its keys."""
    from baker.rig.skeleton import forward_kinematics

    t, q, _ = red.played_joints(clip)
    return forward_kinematics(rig.skeleton.parents, t.astype(np.float64), q.astype(np.float64))[0]


def test_a_clip_refined_in_pieces_keeps_the_bound(clip, rig, monkeypatch):
    """A clip of more than PIECE_FRAMES frames (reduce_plan's `split`) is refined in pieces,
    each on its own and in any order or process, keyed at their seams, then checked whole:
    every joint stays within the tolerance as played, about as many keys as in one piece."""
    from baker.parallel import can_fork, fork_map

    skel = rig.skeleton
    kw = dict(rest=(skel.rest_translations, skel.rest_rotations), short_rotations=True)
    whole = red.reduce_clip(clip, skel.parents, TOL, **kw)
    monkeypatch.setattr(red, "PIECE_FRAMES", clip.n_frames // 3)
    plan = red.reduce_plan(clip, skel.parents, TOL, split=True, **kw)
    assert plan.pieces == 3 and plan.bounds[0] == 0 and plan.bounds[-1] == clip.n_frames - 1
    pieces = [plan.piece(i) for i in reversed(range(plan.pieces))][::-1]
    split = plan.finish(pieces)
    if can_fork():                    # the pieces on other processes: the same keys
        forked = plan.finish(fork_map(plan.piece, plan.pieces, 2))
        assert np.array_equal(forked.keys.rotations.keep, split.keys.rotations.keep)
        assert _bits_equal(forked.keys.rotations.values, split.keys.rotations.values)
    k = split.keys
    for keys, local in zip((k.translations, k.rotations), plan.keeps):
        animated = local.any(axis=1)                    # animated after the local pass
        assert animated.any() and keys.keep[animated][:, plan.bounds].all()   # the seams
        assert keys.keep[~keys.is_static][:, [0, -1]].all()         # every channel's ends
    err = np.linalg.norm(_world(split, rig) - _world(clip, rig), axis=-1)
    assert k.max_error_m <= TOL and err.max() <= TOL + SLACK and err.max() > 0.3 * TOL
    count = k.translations.count + k.rotations.count
    assert count <= 1.1 * (whole.keys.translations.count + whole.keys.rotations.count)


def test_a_clip_in_one_piece_is_reduced_as_before(clip, rig):
    """split on a clip of at most PIECE_FRAMES frames: one piece, the keys of reduce_clip."""
    skel = rig.skeleton
    kw = dict(rest=(skel.rest_translations, skel.rest_rotations), short_rotations=True)
    plan = red.reduce_plan(clip, skel.parents, TOL, split=True, **kw)
    assert clip.n_frames <= red.PIECE_FRAMES + 1 and plan.pieces == 1
    got = plan.finish([plan.piece(0)])
    want = red.reduce_clip(clip, skel.parents, TOL, **kw)
    assert np.array_equal(got.keys.translations.keep, want.keys.translations.keep)
    assert _bits_equal(got.keys.rotations.values, want.keys.rotations.values)
