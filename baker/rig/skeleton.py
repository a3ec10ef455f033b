"""Skeleton topology and rest pose: a parents array plus local rest TRS, UsdSkel style.

The skeleton is a flat list of joints, parents before children. Exporters read only these arrays,
so joints appended later (legs, antennae) need no exporter changes: use `Skeleton.with_joints`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.errors import RigError
from baker.geometry.conventions import is_valid_name
from baker.geometry.transforms import quat_mul, quat_rotate, trs_to_matrix


@dataclass(frozen=True)
class Skeleton:
    """Joint hierarchy and rest (= bind) pose.

    names             : J joint names, [A-Za-z0-9_], unique (also ignoring case), at most 63
                        bytes; parents first
    parents           : (J,) int32, parent joint index, -1 for the root joint ("head")
    rest_translations : (J, 3) float64, metres, local (relative to the parent joint)
    rest_rotations    : (J, 4) float64, xyzw unit quaternions, local

    The skeleton's own frame is the creature's placement frame (the non-joint "Centipede" node in
    glTF, the SkelRoot in USD). The rest pose is straight along +Z, head at the front.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    rest_translations: np.ndarray
    rest_rotations: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.names)
        parents = np.asarray(self.parents, dtype=np.int32).reshape(-1)
        t = np.asarray(self.rest_translations, dtype=np.float64)
        q = np.asarray(self.rest_rotations, dtype=np.float64)
        j = len(names)
        if j == 0:
            raise RigError("skeleton has no joints")
        if parents.shape != (j,) or t.shape != (j, 3) or q.shape != (j, 4):
            raise RigError(f"skeleton arrays disagree: {j} names, parents {parents.shape}, "
                           f"translations {t.shape}, rotations {q.shape}")
        bad = [n for n in names if not is_valid_name(n)]
        if bad:
            raise RigError(f"invalid joint name(s) {bad}: use [A-Za-z0-9_], at most 63 bytes")
        if len({n.lower() for n in names}) != j:
            raise RigError("joint names must be unique, also without regard to case")
        if parents[0] != -1 or np.any(parents[1:] < 0):
            raise RigError("the skeleton needs exactly one root joint, first in the list")
        if np.any(parents[1:] >= np.arange(1, j)):
            raise RigError("every joint's parent must come before it")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise RigError("skeleton rest pose has non-finite values")
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        for name, arr in (("parents", parents), ("rest_translations", t), ("rest_rotations", q)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "names", names)

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of joint `name`; RigError when absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise RigError(f"no joint named {name!r}") from None

    def world_rest(self) -> tuple[np.ndarray, np.ndarray]:
        """World (skeleton-space) rest translations (J, 3) and xyzw rotations (J, 4)."""
        t, q = forward_kinematics(self.parents, self.rest_translations[None], self.rest_rotations[None])
        return t[0], q[0]

    def world_bind(self) -> np.ndarray:
        """(J, 4, 4) float64 world bind matrices (rest pose), row-major, column vectors."""
        t, q = self.world_rest()
        return trs_to_matrix(t, q)

    def local_rest_matrices(self) -> np.ndarray:
        """(J, 4, 4) float64 local rest matrices, row-major, column vectors."""
        return trs_to_matrix(self.rest_translations, self.rest_rotations)

    def joint_paths(self) -> tuple[str, ...]:
        """USD joint tokens: each joint's path from the root, e.g. "head/trunk_01"."""
        paths: list[str] = []
        for i, p in enumerate(self.parents):
            paths.append(self.names[i] if p < 0 else f"{paths[p]}/{self.names[i]}")
        return tuple(paths)

    def children(self, i: int) -> tuple[int, ...]:
        """Indices of the direct children of joint i, in order."""
        return tuple(int(c) for c in np.nonzero(self.parents == i)[0])

    def with_joints(self, names, parents, rest_translations, rest_rotations) -> Skeleton:
        """A new skeleton with joints appended (parents index into the combined list)."""
        return Skeleton(
            names=self.names + tuple(names),
            parents=np.concatenate([self.parents, np.asarray(parents, dtype=np.int32)]),
            rest_translations=np.concatenate([self.rest_translations,
                                              np.asarray(rest_translations, float).reshape(-1, 3)]),
            rest_rotations=np.concatenate([self.rest_rotations,
                                           np.asarray(rest_rotations, float).reshape(-1, 4)]),
        )


def forward_kinematics(parents: np.ndarray, local_t: np.ndarray, local_q: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """World translations and rotations from local ones, vectorized over frames.

    parents : (J,) int, parents before children, -1 for roots
    local_t : (F, J, 3) float, local translations
    local_q : (F, J, 4) float, local xyzw rotations
    returns : (F, J, 3) world translations, (F, J, 4) world xyzw rotations (float64)
    """
    local_t = np.asarray(local_t, dtype=np.float64)
    local_q = np.asarray(local_q, dtype=np.float64)
    parents = np.asarray(parents)
    wt = np.empty_like(local_t)
    wq = np.empty_like(local_q)
    # a level of the skeleton at a time (joints at one depth, all parents posed): the same
    # element-wise arithmetic as joint by joint, so the same bits, in a few numpy steps
    depth = np.zeros(len(parents), dtype=np.int64)
    for j, p in enumerate(parents.tolist()):
        depth[j] = 0 if p < 0 else depth[p] + 1
    for d in range(int(depth.max(initial=-1)) + 1):
        level = np.flatnonzero(depth == d)
        if d == 0:
            wt[:, level] = local_t[:, level]
            wq[:, level] = local_q[:, level]
            continue
        up_t, up_q = wt[:, parents[level]], wq[:, parents[level]]
        wt[:, level] = up_t + quat_rotate(up_q, local_t[:, level])
        wq[:, level] = quat_mul(up_q, local_q[:, level])
    return wt, wq


def spine_skeleton(n_segments: int, spacing: float) -> Skeleton:
    """`head` -> `trunk_01` ... chain, straight along +Z: head at z=0, trunk_k at z=-k*spacing."""
    if n_segments < 2:
        raise RigError(f"a spine needs at least 2 segments (got {n_segments})")
    if not spacing > 0:
        raise RigError(f"segment spacing must be > 0 (got {spacing})")
    names = ("head",) + tuple(f"trunk_{k:02d}" for k in range(1, n_segments))
    parents = np.arange(-1, n_segments - 1, dtype=np.int32)
    t = np.zeros((n_segments, 3))
    t[1:, 2] = -spacing
    q = np.zeros((n_segments, 4))
    q[:, 3] = 1.0
    return Skeleton(names=names, parents=parents, rest_translations=t, rest_rotations=q)
