"""Build a Rig (skeleton + skinned mesh) from a RigConfig."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.config import RigConfig
from baker.errors import RigError
from baker.rig.mesh import SkinnedMesh, build_body_mesh
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
    """Skeleton `head` -> `trunk_01` ... `trunk_NN` and its procedural skinned body mesh."""
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
    mesh = build_body_mesh(widths, body.spacing, body.height_ratio, body.leg_stub_length,
                           cfg.colors.body, cfg.colors.legs, spine,
                           clearance=body.clearance)
    return Rig(config=cfg, skeleton=skeleton, mesh=mesh, spine=spine)
