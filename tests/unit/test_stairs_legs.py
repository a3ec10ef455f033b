"""Walking legs on a staircase built in code (issue 10: risers up to 0.1 BL are climbed, the legs
find holds on the treads with no bone through a step and no joint turning 30 deg in a frame)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config, scale_rig
from baker.environment.rays import RayCaster
from baker.geometry.transforms import quat_angle, quat_conj, quat_mul, quat_rotate
from baker.locomotion.body import BodyFrames
from baker.locomotion.legs import walking_legs
from baker.metrics import inside_geometry
from baker.rig.limbs import leg_layout

RIG = scale_rig(load_rig_config(DEFAULT_RIG), 8.0)      # the 2 m rig of the multi-storey level
RISER, TREAD, STEPS, WIDTH = 0.18, 0.35, 24, 8.0


def staircase() -> RayCaster:
    """A closed flight of STEPS steps rising toward +Z (step k's tread at (k + 1) * RISER over
    z in [k, k + 1] * TREAD), WIDTH wide, on y = 0."""
    outline = [(0.0, 0.0)]
    for k in range(STEPS):
        outline += [(k * TREAD, (k + 1) * RISER), ((k + 1) * TREAD, (k + 1) * RISER)]
    outline += [(z, 0.0) for z in np.arange(STEPS, 0, -1) * TREAD]   # the bottom, split per step
    zy = np.array(outline)
    n = len(zy)
    x = np.array([-0.5 * WIDTH, 0.5 * WIDTH])
    v = np.concatenate([np.c_[np.full(n, xx), zy[:, 1], zy[:, 0]] for xx in x])
    i = np.arange(n)
    j = (i + 1) % n
    faces = [np.c_[i, j, j + n], np.c_[i, j + n, i + n]]
    for k in range(STEPS):              # the two ends: per step's column, a fan from its corner
        ring = [0 if k == 0 else n - k] + ([2 * k] if k else []) + [1 + 2 * k, 2 + 2 * k]
        fan = np.array([[n - k - 1, a, b] for a, b in zip(ring[:-1], ring[1:])])
        faces += [fan[:, ::-1], fan + n]
    mesh = trimesh.Trimesh(v, np.concatenate(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return RayCaster(mesh)


def climbing_body(speed: float, seconds: float, heading: float = 0.0, fps: int = 30):
    """BodyFrames of a straight spine walking up the flight at `heading` [rad] from straight up
    it, pitched with the nosings' plane and `clearance` above it, at `speed` m/s."""
    from baker.geometry.transforms import quat_about, quat_mul

    b = RIG.body
    pitch = np.arctan2(RISER * np.cos(heading), TREAD)
    d = np.array([np.sin(heading) * np.cos(pitch), np.sin(pitch), np.cos(heading) * np.cos(pitch)])
    q = quat_mul(quat_about(np.array([0.0, 1.0, 0.0]), heading),
                 quat_about(np.array([1.0, 0.0, 0.0]), -pitch))       # +Z turned to d
    up = quat_rotate(q, np.array([0.0, 1.0, 0.0]))
    t = np.arange(int(seconds * fps) + 1) / fps
    arc = b.length + 0.6 + speed * t
    s = arc[:, None] - b.spacing * np.arange(b.segments)[None, :]      # (F, S) along the path
    start = np.array([-np.sin(heading) * 2.0, RISER, 0.0])           # on the first nosing
    pos = start + s[..., None] * d + b.clearance * up
    rot = np.broadcast_to(q, s.shape + (4,)).copy()
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0]), pos.shape).copy()
    ground = np.floor(pos[..., 2] / TREAD + 1.0) * RISER
    return BodyFrames(positions=pos, rotations=rot, normals=normals, ground=ground), arc, t


#: frames at the clip's ends (a swing already under way at frame 0, one unfinished at the end)
#: are not judged here
EDGE = 30


@pytest.fixture(scope="module", params=[0.0, 30.0, 50.0], ids=lambda h: f"heading{h:g}")
def climb(request):
    """Straight up the flight, and across it at 30 and 50 deg (holds next to a riser's foot,
    edges crossed diagonally)."""
    rays = staircase()
    bf, arc, t = climbing_body(speed=0.5, seconds=5.0, heading=np.radians(request.param))
    w = walking_legs(bf, arc, t, rays, RIG)
    keep = slice(EDGE, len(t) - EDGE)
    bf = BodyFrames(positions=bf.positions[keep], rotations=bf.rotations[keep],
                    normals=bf.normals[keep], ground=bf.ground[keep])
    return rays, bf, {k: w[k][keep] for k in ("rotations", "positions", "feet", "contacts")}


def test_stair_swings_turn_no_leg_joint_30_degrees_in_a_frame(climb):
    _, bf, w = climb
    lay = leg_layout(RIG)
    q_seg = bf.rotations[:, lay.segment]
    q_u, q_t = w["rotations"][:, 0::2], w["rotations"][:, 1::2]
    local_u, local_t = quat_mul(quat_conj(q_seg), q_u), quat_mul(quat_conj(q_u), q_t)
    worst = max(np.degrees(quat_angle(q[1:], q[:-1])).max() for q in (q_u, q_t, local_u, local_t))
    assert worst < 30.0


def test_stair_feet_and_leg_bones_stay_out_of_the_steps(climb):
    rays, _, w = climb
    bl = RIG.body.length
    feet = w["feet"]
    F, L, _ = feet.shape
    inside = inside_geometry(feet.reshape(-1, 3), rays)
    depth = rays.closest(feet.reshape(-1, 3)[inside], 0.5 * bl)[0] if inside.any() else np.zeros(1)
    assert np.nan_to_num(depth, nan=bl).max() < 0.005 * bl
    hip, knee = w["positions"][:, 0::2], w["positions"][:, 1::2]
    hits = 0
    for a, b in ((hip, knee), (knee, feet)):
        v = (b - a).reshape(-1, 3)
        n = np.linalg.norm(v, axis=1)
        hits += int(rays.first_hit(a.reshape(-1, 3), v,
                                   max_distance=np.maximum(n - 0.005 * bl, 0.0)).hit.sum())
    assert hits == 0
    # the feet climb with the body
    assert np.ptp(w["feet"][..., 1][w["contacts"]]) > 5 * RISER


def test_a_tread_is_level_under_a_body_leaning_with_the_flight_and_a_riser_foot_is_not():
    """Footholds prefer level ground away from a step's edge (legs.is_level). Under a segment
    pitched with the flight (its up leans back by the flight's slope) the middle of a tread is
    level, and the foot of a riser or a nosing is not."""
    from baker.locomotion.legs import PLAN_REACH, EDGE_CLEAR, is_level

    rays = staircase()
    pitch = np.arctan2(RISER, TREAD)
    edge = EDGE_CLEAR * PLAN_REACH * (RIG.legs.upper_length + RIG.legs.tip_length)
    k = np.arange(3, 9)
    mid = np.c_[np.zeros(len(k)), (k + 1) * RISER, (k + 0.5) * TREAD]
    riser_foot = np.c_[np.zeros(len(k)), (k + 1) * RISER, (k + 1) * TREAD - 0.01]
    nosing = np.c_[np.zeros(len(k)), (k + 1) * RISER, k * TREAD + 0.01]
    for up in (np.array([0.0, 1.0, 0.0]),
               np.array([0.0, np.cos(pitch), -np.sin(pitch)])):       # leaning with the flight
        n = len(k)
        args = (np.broadcast_to(up, (n, 3)), np.broadcast_to([1.0, 0.0, 0.0], (n, 3)), edge)
        assert is_level(rays, mid, *args).all()
        assert not is_level(rays, riser_foot, *args).any()
        assert not is_level(rays, nosing, *args).any()


def test_the_foot_of_a_step_standing_on_the_floor_is_not_level():
    """A 0.18 m step standing on the floor (its bottom on the floor's top, as the multi-storey
    level's flight stands) and a foot 1 mm from its side, with the 2 m rig's `edge` (6.8 cm:
    the level test's rays start 2 `edge` = 13.6 cm up, inside the step). The ray toward the
    step meets the step's bottom or the floor under it, level with the foot; it started inside
    a solid, so the foot is not level. A foot 0.3 m away is."""
    from baker.locomotion.legs import EDGE_CLEAR, PLAN_REACH, is_level

    edge = EDGE_CLEAR * PLAN_REACH * (RIG.legs.upper_length + RIG.legs.tip_length)
    floor = trimesh.creation.box(bounds=[[-2.0, -0.3, -2.0], [2.0, 0.0, 2.0]])
    step = trimesh.creation.box(bounds=[[0.0, 0.0, -1.0], [1.0, RISER, 1.0]])
    rays = RayCaster(trimesh.util.concatenate([floor, step]))
    assert 2.0 * edge < RISER
    pts = np.array([[-0.001, 0.0, 0.0], [-0.3, 0.0, 0.0]])
    for up, inward in (([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]), ([0.0, 1.0, 0.0], [1.0, 0.0, 0.0])):
        args = (np.tile(up, (2, 1)), np.tile(inward, (2, 1)), edge)
        assert is_level(rays, pts, *args).tolist() == [False, True]
