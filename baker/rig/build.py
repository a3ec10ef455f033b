"""Build a Rig (skeleton + skinned mesh) from a RigConfig."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.config import RigConfig
from baker.errors import RigError
from baker.geometry.transforms import quat_conj, quat_mul, quat_rotate
from baker.rig.limbs import limb_rest
from baker.rig.mesh import SkinnedMesh, add_limbs, build_body_mesh, build_limb_mesh
from baker.rig.skeleton import Skeleton, spine_skeleton


@dataclass(frozen=True, eq=False)
class Rig:
    """Everything about the creature that does not change over time.

    config   : the rig definition it was built from
    skeleton : joints, parents, rest pose
    mesh     : the skinned body in bind space
    spine    : (S,) int64, skeleton joint indices of the spine, head (0) to tail (S-1);
               row s of Trajectory.spine_* drives joint spine[s]
    """

    config: RigConfig
    skeleton: Skeleton
    mesh: SkinnedMesh
    spine: np.ndarray

    @property
    def spacing(self) -> float:
        """[m] rest distance between neighbouring spine joints."""
        return self.config.body.spacing


def build_rig(cfg: RigConfig) -> Rig:
    """Skeleton `head` -> `trunk_01` ... `trunk_NN` and its procedural skinned body mesh.

    With cfg.legs.enabled the skeleton also gets the limbs of rig/limbs.py (two joints per
    walking leg on every trunk segment, ultimate legs, antennae, forcipules) and the mesh gets
    tapered, skinned limb tubes instead of the static leg stubs."""
    body = cfg.body
    n = int(body.segments)
    widths = np.asarray(body.width_profile, dtype=np.float64)
    if widths.size == 0:
        widths = np.full(n, 0.045 * body.length)
    if widths.shape != (n,):
        raise RigError(f"rig {cfg.name!r}: width_profile needs {n} values (got {widths.size})")
    skeleton = spine_skeleton(n, body.spacing)
    spine = np.arange(n, dtype=np.int64)
    spine.setflags(write=False)
    legs = cfg.legs.enabled
    mesh = build_body_mesh(widths, body.spacing, body.height_ratio,
                           0.0 if legs else body.leg_stub_length,
                           cfg.colors.body, cfg.colors.legs, spine,
                           clearance=body.clearance)
    if legs:
        skeleton, mesh = _add_limbs(cfg, skeleton, mesh)
    return Rig(config=cfg, skeleton=skeleton, mesh=mesh, spine=spine)


def _add_limbs(cfg: RigConfig, skeleton: Skeleton, mesh: SkinnedMesh):
    """The limb joints of rig/limbs.py appended to `skeleton` (local rest TRS from their world
    rest frames; end joints exactly at (0, length, 0) with the identity rotation), and their
    skinned tubes appended to `mesh` (end joints carry no weights)."""
    rest = limb_rest(cfg, skeleton.names)
    base = skeleton.n_joints
    index = {n: i for i, n in enumerate(skeleton.names)}
    index.update({n: base + i for i, n in enumerate(rest.names)})
    parents = np.array([index[p] for p in rest.parents])
    wt, wq = skeleton.world_rest()
    world_t = np.concatenate([wt, rest.positions])
    world_q = np.concatenate([wq, rest.rotations])
    inv = quat_conj(world_q[parents])
    local_t = quat_rotate(inv, rest.positions - world_t[parents])
    local_q = quat_mul(inv, rest.rotations)
    end = np.asarray(rest.end, dtype=bool)
    bone = np.nonzero(~end)[0]
    local_t[end] = 0.0
    local_t[end, 1] = rest.lengths[bone.reshape(-1, 2)[:, 1]]
    local_q[end] = [0.0, 0.0, 0.0, 1.0]
    skeleton = skeleton.with_joints(rest.names, parents, local_t, local_q)
    k = rest.n_limbs
    lv, lf, lj, lw = build_limb_mesh(rest.positions[bone].reshape(k, 2, 3),
                                     rest.rotations[bone].reshape(k, 2, 4),
                                     rest.lengths[bone].reshape(k, 2), rest.radii[bone][0::2],
                                     (base + bone).reshape(k, 2))
    return skeleton, add_limbs(mesh, lv, lf, lj, lw)
