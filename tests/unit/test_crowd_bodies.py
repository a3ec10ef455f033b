"""Where a crowd's run believes each body lies (run.crowd.Bodies: locomotion.body.trail_ends
and chain_on) against where the solve puts it (build_trail + place_chain): the avoidance keeps
heads apart from those points, so they must be the body's. A head that turned on the spot, or
dithered, leaves a cusp in its path that the body's trail rounds off: sampled along the raw
path, the body points sat up to 90 mm from the solved spine, and in a 100-creature bake a head
walked into another body's tail (spine joints 10 mm apart)."""

from __future__ import annotations

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry import polyline
from baker.locomotion.body import build_trail, chain_on, place_chain, trail_ends
from baker.locomotion.cobra import lift_profile
from baker.run.crowd import Bodies
from signal_stops import assert_signals_stop_cleanly
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
SPACING, S = RIG.body.spacing, RIG.body.segments


@pytest.fixture(scope="module")
def rays():
    return env_of(floor(-2.0, 2.0, -2.0, 2.0)).rays


def solved_spine(path: np.ndarray, rays, lift: np.ndarray | None = None) -> np.ndarray:
    """(S, 2) x, z of the spine the solve places behind the end of `path` (flat ground)."""
    trail = build_trail(path, rays, probe=0.5 * RIG.navigation.height, spacing=SPACING,
                        clearance=RIG.body.clearance)
    flat = path.copy()
    flat[:, 1] = 0.0
    head = trail.arc_at(polyline.arc_lengths(flat)[-1:])
    offset = np.full((1, S), RIG.body.clearance) + (0.0 if lift is None else lift[None])
    pos, _ = place_chain(trail, head, offset, SPACING)
    return pos[0][:, [0, 2]]


def walk(*legs, step=0.0005) -> np.ndarray:
    """A head path through the corners `legs` ((x, z) pairs), a point every `step` metres."""
    pts = [np.array(legs[0], float)]
    for a, b in zip(legs[:-1], legs[1:]):
        a, b = np.array(a, float), np.array(b, float)
        n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        pts += [a + (b - a) * t for t in np.linspace(0, 1, n + 1)[1:]]
    xz = np.array(pts)
    return np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])


def raw_points(path: np.ndarray, back: np.ndarray) -> np.ndarray:
    cum = polyline.arc_lengths(path[:, [0, 2]])
    idx = np.searchsorted(cum, cum[-1] - back).clip(0, len(cum) - 1)
    return path[idx][:, [0, 2]]


def model(path: np.ndarray, lift: np.ndarray | None = None) -> np.ndarray:
    """(S, 2) the run's body model behind the end of `path`, at the solve's resolution."""
    cum = polyline.arc_lengths(path[:, [0, 2]])
    trails = trail_ends(path[None], cum[None], np.array([len(path) - 1]), (S + 6) * SPACING,
                        SPACING)
    lift = np.zeros((1, S)) if lift is None else lift[None]
    return chain_on(trails, lift, SPACING)[0][:, [0, 2]]


def test_a_straight_path_puts_the_points_a_spacing_apart(rays):
    path = walk((0.0, 0.0), (0.0, 0.6))
    got = model(path)
    np.testing.assert_allclose(got[:, 1], 0.6 - SPACING * np.arange(S), atol=1e-6)
    np.testing.assert_allclose(got[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(got, solved_spine(path, rays), atol=1e-4)


@pytest.mark.parametrize("dither", [0.01, 0.02, 0.03])
@pytest.mark.parametrize("side", [0.0, 0.05])
def test_a_cusp_in_the_path_is_rounded_as_the_body_rounds_it(rays, dither, side):
    # walk 0.4 m, dither back and forth a few centimetres (a head cornered by other bodies,
    # turning on the spot), then walk on
    legs = [(0.0, 0.0), (0.0, 0.4)]
    for _ in range(3):
        legs += [(0.0, 0.4 - dither), (0.0, 0.4)]
    legs += [(side, 0.45)]
    path = walk(*legs)
    spine = solved_spine(path, rays)
    err = np.linalg.norm(model(path) - spine, axis=1).max()
    raw = np.linalg.norm(raw_points(path, SPACING * np.arange(S)) - spine, axis=1).max()
    assert err < 0.001, err
    assert raw > 0.05, raw            # the raw path's arc length folds the body up


def test_a_raised_front_is_nearer_the_head(rays):
    path = walk((0.0, 0.0), (0.0, 0.6))
    lift = lift_profile(np.array([1.0]), RIG.cobra.curve, RIG.cobra.height, S)[0]
    got = model(path, lift)
    assert got[-1, 1] > 0.6 - SPACING * (S - 1) + 0.01     # the front's rise shortens it
    np.testing.assert_allclose(got, solved_spine(path, rays, lift), atol=1e-3)


def test_bodies_keep_the_head_last_and_place_only_what_moved():
    line = walk((0.0, -0.3), (0.0, 0.0))[::10]
    path = walk((0.0, 0.0), (0.0, 0.2), step=0.0002)
    bodies = Bodies([line, line + [1.0, 0.0, 0.0]], len(path), SPACING, S, lift=lambda a: (
        lift_profile(np.array([a]), RIG.cobra.curve, RIG.cobra.height, S)[0]))
    for p in path:
        bodies.advance(np.stack([p, line[-1] + [1.0, 0.0, 0.0]]))   # the second stands
    assert bodies.count[0] < len(line) + len(path) // 2                # sparse, not every step
    np.testing.assert_array_equal(bodies.path[0, bodies.count[0]], path[-1])
    pts3, owner = bodies.points(np.array([0, 1]), np.array([0.0, 1.0]))
    assert pts3.shape == (2 * (S + 1), 3) and list(owner) == [0] * (S + 1) + [1] * (S + 1)
    pts = pts3[:, [0, 2]]
    np.testing.assert_allclose(pts[:S], model(np.vstack([line, path])), atol=2e-3)
    np.testing.assert_allclose(pts[0], [0.0, 0.2], atol=1e-9)
    assert np.all(np.diff(pts[S + 1:2 * S + 1, 1]) < 0)             # the raised one, behind


def plain_chain(trail: np.ndarray, lift: np.ndarray, spacing: float, look: int) -> np.ndarray:
    """chain_on for one trail (m, 3) written plainly: from each joint, the first of `look`
    samples back (from the last one used) more than `spacing` away, and the point at exactly
    `spacing` on the way to it from the sample before it (np.roots of the quadratic)."""
    pts = trail + lift[:, None, None] * np.array([0.0, 1.0, 0.0])     # (S, m, 3) per joint
    out = [pts[0, -1]]
    at = len(trail) - 2
    for i in range(1, len(lift)):
        prev = out[-1]
        cand = [pts[i, max(at - c, 0)] for c in range(look)]
        far = [c for c in range(look) if np.linalg.norm(cand[c] - prev) > spacing]
        j = far[0] if far else look - 1
        b = cand[j - 1] if j > 0 else prev
        d = cand[j] - b
        if far:
            roots = np.roots([d @ d, 2.0 * d @ (b - prev), (b - prev) @ (b - prev) - spacing ** 2])
            t = float(np.clip(max(r.real for r in roots), 0.0, 1.0))
        else:
            t = 1.0
        out.append(b + t * d)
        at = max(at - j, 0)
    return np.array(out)


@pytest.mark.parametrize("seed", range(4))
def test_compiled_placement_is_the_plain_one_on_folded_raised_trails(seed):
    """chain_on (compiled) against the plain loop, on trails that fold back on themselves,
    wander up and down, and are shorter than the body, with some joints raised."""
    rng = np.random.default_rng(seed)
    n, m = 6, [300, 300, 300, 300, 12, 2][seed % 6]
    steps = rng.normal(size=(n, m, 3)) * SPACING / 8.0
    steps[::2, m // 2:] *= -1.0                                       # folds
    trails = np.cumsum(steps, axis=1)
    lift = np.where(rng.random((n, S)) < 0.4, rng.uniform(0.0, 0.02, (n, S)), 0.0)
    got = chain_on(trails, lift, SPACING)
    look = min(33, m)
    for r in range(n):
        np.testing.assert_allclose(got[r], plain_chain(trails[r], lift[r], SPACING, look),
                                   rtol=0, atol=1e-12)


def test_signals_during_the_compiled_placement_stop_cleanly():
    """As for the keyframe reduction (test_reduce_kernels): 20 SIGTERMs at staggered moments
    during repeated compiled placements stop them cleanly."""
    assert_signals_stop_cleanly("""
        from baker.locomotion.body import chain_on
        rng = np.random.default_rng(0)
        trails = np.cumsum(rng.normal(0, 1e-3, (400, 600, 3)), axis=1)
        lift = np.zeros((400, 26))
        """, """
        chain_on(trails, lift, 0.0125)
        """)


def storey_walk(x: float, y: float) -> np.ndarray:
    """A head path along +z at x, on a floor at height y."""
    path = walk((x, -0.3), (x, 0.0))
    path[:, 1] = y
    return path


@pytest.mark.parametrize("rise, seen", [(0.0, True), (0.1, True), (2.0, False), (-2.0, False)])
def test_a_body_on_another_storey_is_not_in_a_head_s_way(rise, seen):
    """Two creatures side by side (0.04 m apart, closer than `reach`), the second's floor
    `rise` metres above the first's: its body points are the first head's obstacles on the
    same floor or a step up (within crowd_band), and not on a floor above or below (they
    were: a crowd on the multi-storey level avoided bodies on the other storey)."""
    from baker.run.crowd import crowd_band, crowd_separation, neighbours

    a, b = storey_walk(0.0, 0.0), storey_walk(0.04, rise)
    bodies = Bodies([a, b], 1, SPACING, S)
    heads = np.stack([a[-1], b[-1]])
    bodies.advance(heads)
    reach = 2.0 * crowd_separation(RIG)
    band = crowd_band(RIG, reach)
    assert 0.1 < band < 2.0
    out = neighbours(bodies, heads, np.zeros(2), reach, band=band)
    for i in (0, 1):
        pts, _ = out[i]
        assert (pts is not None) == seen
        if seen:
            assert pts.shape[1] == 2 and np.all(np.abs(pts[:, 0] - heads[1 - i, 0]) < 1e-9)
    # with no band (or an infinite one), every storey's points, as before
    assert all(p is not None for p, _ in neighbours(bodies, heads, np.zeros(2), reach))
