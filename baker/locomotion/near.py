"""Other creatures' bodies near a creature's chains (ultimate legs and antennae), frame by
frame, for a crowd's solve: its chains raise clear of them as they raise clear of the
environment.

A crowd's heads keep two agent radii from other bodies, which covers a walking leg's reach; an
ultimate leg trails 4.4 spacings behind the tail, and where a body passes a fold of its trail
the tail swings round and sweeps it across a half disc that long: in a 100-creature minute one
swept 1 mm into a resting neighbour's head (the crowd check: no leg bone within a body radius
of another creature's spine). NearBodies stands in for the environment's rays in the chains'
solve (legs.posed_chains): `occluded` is the environment's, and `touches` adds the other
bodies' capsules.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from baker.config import RigConfig
from baker.parallel import compiled_call
from baker.rig.limbs import chains

#: a chain's bone keeps this many body radii from another creature's spine segments (the
#: crowd check's capsule is one body radius; the margin covers the keyframe reduction)
CLEAR_RADII = 1.25
#: frames searched for near segments at once (the other creatures' boxes over them first)
CHUNK = 32


class NearBodies:
    """The environment's rays and, for each of F frames, up to M other creatures' spine
    segments (a, b: (F, M, 3), NaN where none) that a creature's chains may reach; a bone
    within `radius` of one of them touches it."""

    def __init__(self, rays, a: np.ndarray, b: np.ndarray, radius: float):
        self.rays, self.a, self.b, self.radius = rays, a, b, float(radius)
        self.rows = np.nonzero(np.isfinite(a[:, :, 0]).any(axis=1))[0]    # frames with some

    def occluded(self, origins, directions, max_distance):
        return self.rays.occluded(origins, directions, max_distance=max_distance)

    def at(self, frames: np.ndarray) -> NearBodies:
        """The same for the given frames only (chains solved over a run of frames)."""
        return NearBodies(self.rays, self.a[frames], self.b[frames], self.radius)

    def touches(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(F, ...) bool: bone segments p-q (F, ..., 3), frame by frame, within `radius` of
        one of that frame's segments."""
        rows = self.rows
        out = np.zeros(p.shape[:-1], dtype=bool)
        if not len(rows):
            return out
        pr = np.ascontiguousarray(p[rows], dtype=np.float64).reshape(len(rows), -1, 3)
        qr = np.ascontiguousarray(q[rows], dtype=np.float64).reshape(len(rows), -1, 3)
        hit = np.zeros(pr.shape[:2], dtype=np.bool_)
        compiled_call(_capsules_touch, pr, qr, self.a[rows], self.b[rows], self.radius, hit)
        out[rows] = hit.reshape((len(rows),) + p.shape[1:-1])
        return out


class CrowdSpines:
    """Every creature's placed spine joints (n, F, S, 3), with each creature's box over each
    CHUNK of frames (lo, hi: (n, C, 3)), made once for the whole crowd: near_bodies' first
    cut (a point farther than its reach from a box is farther from everything in it)."""

    def __init__(self, spines: np.ndarray):
        self.spines = spines
        starts = np.arange(0, spines.shape[1], CHUNK)
        self.lo = np.minimum.reduceat(spines.min(axis=2), starts, axis=1)
        self.hi = np.maximum.reduceat(spines.max(axis=2), starts, axis=1)


def frames_of(rays, frames: np.ndarray):
    """The rays for a solve of these frames alone: a NearBodies' (at), the level's as they
    are."""
    return rays.at(frames) if isinstance(rays, NearBodies) else rays


def near_bodies(rays, crowd: CrowdSpines, i: int, bases: np.ndarray, reach: float,
                radius: float) -> NearBodies | None:
    """Creature i's NearBodies: every frame's spine segments of the other creatures whose
    midpoint is within `reach` of one of i's chain bases (None: no frame has one).

    crowd : every creature's spine joints; bases : (F, c, 3) creature i's chain bases;
    reach : [m] how far from a base a segment's midpoint may be and a chain still come within
    the clearance of it; radius : [m] a body radius"""
    spines = crowd.spines
    n, F, S, _ = spines.shape
    others = np.delete(np.arange(n), i)
    seg = S - 1
    mask = np.zeros((F, len(others), seg), dtype=bool)
    for c, f0 in enumerate(range(0, F, CHUNK)):
        f1 = min(f0 + CHUNK, F)
        # only the creatures whose box over these frames comes within reach of the bases' box
        lo, hi = crowd.lo[others, c], crowd.hi[others, c]                    # (n-1, 3)
        blo, bhi = bases[f0:f1].min(axis=(0, 1)), bases[f0:f1].max(axis=(0, 1))
        gap = np.maximum(np.maximum(lo - bhi, blo - hi), 0.0)
        near = np.nonzero(np.linalg.norm(gap, axis=1) <= reach)[0]
        if not len(near):
            continue
        box = spines[others[near], f0:f1]
        mids = 0.5 * (box[:, :, :-1] + box[:, :, 1:])                        # (k, fc, S-1, 3)
        d = np.linalg.norm(mids[:, :, None] - bases[None, f0:f1, :, None], axis=-1)
        mask[f0:f1, near] = np.moveaxis((d <= reach).any(axis=2), 0, 1)
    mask = mask.reshape(F, -1)
    rows, cols = np.nonzero(mask)
    if not len(rows):
        return None
    counts = mask.sum(axis=1)
    slot = np.arange(len(rows)) - np.repeat(np.cumsum(counts) - counts, counts)
    a = np.full((F, int(counts.max()), 3), np.nan)
    b = np.full_like(a, np.nan)
    c, j = others[cols // seg], cols % seg
    a[rows, slot] = spines[c, rows, j]
    b[rows, slot] = spines[c, rows, j + 1]
    return NearBodies(rays, a, b, CLEAR_RADII * radius)


def crowd_near(rays, crowd: CrowdSpines, i: int, rig: RigConfig) -> NearBodies | None:
    """Creature i's NearBodies in a crowd whose placed spines are `crowd`'s: the
    other bodies' segments a chain may come within CLEAR_RADII body radii of, found by their
    midpoints' distance from the joints the chains hang from (the longest chain and 5 %, the
    farthest chain base from its joint, the clearance and half a segment)."""
    radius = float(max(rig.body.width_profile))
    own = [ch for ch in chains(rig) if ch.kind != "forcipule"]
    reach = (max(float(np.sum(ch.lengths)) for ch in own) * 1.05
             + max(float(np.linalg.norm(ch.base)) for ch in own)
             + CLEAR_RADII * radius + 0.5 * rig.body.spacing)
    parents = sorted({ch.parent for ch in own})
    return near_bodies(rays, crowd, i, crowd.spines[i][:, parents], reach, radius)


@njit(cache=True, nogil=True, error_model="numpy")
def _capsules_touch(p, q, a, b, radius, out):
    """out[r, k] = whether segment p[r, k]-q[r, k] comes within `radius` of one of the
    segments a[r, m]-b[r, m] (NaN: none): geometry.proximity.segment_distances' arithmetic
    (Ericson 5.1.9) pair by pair, stopping at a bone's first touch. p, q (R, K, 3); a, b
    (R, M, 3); out (R, K) bool."""
    eps = 1e-18
    for r in range(p.shape[0]):
        for k in range(p.shape[1]):
            p1, q1 = p[r, k], q[r, k]
            d1 = (q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2])
            aa = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
            for m in range(a.shape[1]):
                p2, q2 = a[r, m], b[r, m]
                if math.isnan(p2[0]):
                    continue
                d2 = (q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2])
                w = (p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2])
                e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
                bb = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
                c = d1[0] * w[0] + d1[1] * w[1] + d1[2] * w[2]
                f = d2[0] * w[0] + d2[1] * w[1] + d2[2] * w[2]
                s, t = _closest_params(aa, bb, c, e, f, eps)
                dx = p1[0] + d1[0] * s - p2[0] - d2[0] * t
                dy = p1[1] + d1[1] * s - p2[1] - d2[1] * t
                dz = p1[2] + d1[2] * s - p2[2] - d2[2] * t
                if math.sqrt(dx * dx + dy * dy + dz * dz) < radius:
                    out[r, k] = True
                    break


@njit(cache=True, nogil=True, error_model="numpy")
def _closest_params(a, b, c, e, f, eps):
    """(s, t): the closest points' parameters on two segments (segment_distances' choices):
    a, e their squared lengths, b the dot of their directions, c and f those directions' dots
    with the first's start less the second's."""
    a_ok, e_ok = a > eps, e > eps
    a_ = a if a_ok else 1.0
    e_ = e if e_ok else 1.0
    denom = a * e - b * b
    s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > eps else 0.0
    if not e_ok:
        s = min(max(-c / a_, 0.0), 1.0)
    t = (b * s + f) / e_ if e_ok else 0.0
    if t < 0.0:
        s = min(max(-c / a_, 0.0), 1.0)
    elif t > 1.0:
        s = min(max((b - c) / a_, 0.0), 1.0)
    t = min(max(t, 0.0), 1.0)
    if not a_ok:
        s = 0.0
        t = min(max(f / e_, 0.0), 1.0) * (1.0 if e_ok else 0.0)
    return s, t
