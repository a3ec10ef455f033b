"""The creature's rig: skeleton (parents array + rest pose), skinned mesh, and building them
from a rig config."""

from baker.rig.build import Rig, build_rig
from baker.rig.mesh import SkinnedMesh
from baker.rig.skeleton import Skeleton, forward_kinematics

__all__ = ["Rig", "build_rig", "SkinnedMesh", "Skeleton", "forward_kinematics"]
