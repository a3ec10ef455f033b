"""Skinned and morphed glTF meshes of a level, in the pose engines draw them with no animation
playing (three.js, Blender, Godot, Unity):

- a mesh with morph targets gets its default weights (the node's `weights`, else the mesh's):
  POSITION (and NORMAL) + sum_k w_k * target_k, in the mesh's own space;
- a skinned mesh (a node with a `skin`, whose primitive has JOINTS_n and WEIGHTS_n) is moved by
  its joints: vertex = sum_i w_i * (world(joint_i) @ inverseBindMatrix_i) @ vertex, the joints'
  world matrices from the node hierarchy (translation, rotation and scale or matrix; no
  animation), the inverse bind matrices identity when the skin has none. The skinned node's own
  transform is ignored, as the glTF spec says (only the joints place the mesh). Weights are
  normalized to sum 1 as three.js does on load (a vertex of no weight goes to its first joint);
  normals are moved by the inverse transpose of the vertex's blended matrix.

A primitive of a skinned node without JOINTS_0 and WEIGHTS_0 is placed by the node, as three.js
does ("skinning disabled"). NaN or infinite weights and matrices, negative weights and joint
indices past the skin's joints are refused (EnvironmentLoadError, naming the accessor). The
work is bounded: vertices x (4 x JOINTS_n sets + morph targets of non-zero weight) over the
level stays within MAX_POSE_TERMS (a small file cannot reuse one accessor as thousands of
targets or influence sets), and the blending runs in chunks of vertices.

The reader (load._GltfReader) hands itself in: `doc`, `path`, `accessor(i)`, `view(j)` and
`local_matrix(node)`; nothing here imports the loader.
"""

from __future__ import annotations

import math

import numpy as np

from baker.environment import gltf_ext
from baker.errors import EnvironmentLoadError

#: the most vertex x term products a level's posing may take (a term: one joint influence or
#: one morph target of non-zero weight); 20 M vertices with 4 influences and a target or so
MAX_POSE_TERMS = 100_000_000
#: the most JOINTS_n / WEIGHTS_n sets a primitive may have (32 influences per vertex)
MAX_SETS = 8
#: vertices blended at once (bounds the gathered (chunk, influences, 3, 4) matrices)
_CHUNK = 1 << 15
_JOINT_TYPES = (5121, 5123)                 # unsigned byte, unsigned short
_WEIGHT_TYPES = (5126, 5121, 5123)          # float, normalized unsigned byte or short


# --------------------------------------------------------------------------- structure
def check(d, doc: dict) -> None:
    """Check the skins, the nodes' skin and weights, the meshes' weights and the primitives'
    targets and JOINTS_n / WEIGHTS_n accessors (types and counts; no data read). d is the
    document checker (`load._Doc`); the meshes' primitives are already checked objects."""
    acc = doc.get("accessors", [])
    for si, skin in enumerate(d.array("skins")):
        w = f"skins[{si}]"
        joints = skin.get("joints")
        if not isinstance(joints, list) or not joints:
            d.fail(f"{w}.joints must be a non-empty array of node indices")
        n = len(d.array("nodes"))
        for k, j in enumerate(joints):
            if isinstance(j, bool) or not isinstance(j, int) or not 0 <= j < n:
                d.fail(f"{w}.joints[{k}] = {str(j)[:40]} is not an index into nodes "
                       f"({n} entries)")
        ibm = d.index(skin, "inverseBindMatrices", w, "accessors")
        if ibm is not None:
            a = acc[ibm]
            if a.get("type") != "MAT4" or a.get("componentType") != 5126:
                d.fail(f"{w}.inverseBindMatrices must be a MAT4 accessor of floats")
            if a.get("count", 0) < len(joints):
                d.fail(f"{w}.inverseBindMatrices holds {a.get('count')} matrices for "
                       f"{len(joints)} joints")
        d.index(skin, "skeleton", w, "nodes")
    for ni, node in enumerate(d.array("nodes")):
        d.index(node, "skin", f"nodes[{ni}]", "skins")
        _check_weights(d, node, f"nodes[{ni}]")
    for mi, mesh in enumerate(d.array("meshes")):
        _check_weights(d, mesh, f"meshes[{mi}]")
        for pi, prim in enumerate(mesh.get("primitives", [])):
            _check_primitive(d, acc, prim, f"meshes[{mi}].primitives[{pi}]")


def _check_weights(d, obj: dict, where: str) -> None:
    if "weights" not in obj:
        return
    v = obj["weights"]
    if not isinstance(v, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in v):
        d.fail(f"{where}.weights must be an array of finite numbers (got {str(v)[:40]})")


def _check_primitive(d, acc: list, prim: dict, w: str) -> None:
    attrs = prim.get("attributes", {})
    count = acc[attrs["POSITION"]].get("count") if "POSITION" in attrs else None
    for name, i in attrs.items():
        kind = name.split("_", 1)[0]
        if kind in ("JOINTS", "WEIGHTS") and name[len(kind) + 1:].isdigit():
            a = acc[i]
            types = _JOINT_TYPES if kind == "JOINTS" else _WEIGHT_TYPES
            if a.get("type") != "VEC4" or a.get("componentType") not in types or (
                    kind == "WEIGHTS" and a.get("componentType") != 5126
                    and not a.get("normalized")) or (kind == "JOINTS" and a.get("normalized")):
                d.fail(f"{w}.attributes.{name} must be a VEC4 accessor of "
                       + ("unsigned bytes or shorts" if kind == "JOINTS"
                          else "floats or normalized unsigned bytes or shorts"))
    targets = prim.get("targets")
    if targets is None:
        return
    if not isinstance(targets, list) or not all(isinstance(t, dict) for t in targets):
        d.fail(f"{w}.targets must be an array of objects")
    for k, t in enumerate(targets):
        for name in t:
            d.index(t, name, f"{w}.targets[{k}]", "accessors")
        for name in ("POSITION", "NORMAL"):
            if name in t:
                a = acc[t[name]]
                if a.get("type") != "VEC3":
                    d.fail(f"{w}.targets[{k}].{name} must be a VEC3 accessor")
                if count is not None and a.get("count") != count:
                    d.fail(f"{w}.targets[{k}].{name} has {a.get('count')} elements, "
                           f"POSITION {count}")


# --------------------------------------------------------------------------- posing
def morph_weights(node: dict, mesh: dict) -> list:
    """A mesh's default morph weights where a node places it: the node's, else the mesh's."""
    return node.get("weights", mesh.get("weights", []))


def needs_pose(node: dict, mesh: dict) -> bool:
    """Whether a node's mesh is skinned or morphed (else it is read as it was, untouched)."""
    if "skin" in node:
        return True
    return any(w != 0 for w in morph_weights(node, mesh)) and any(
        p.get("targets") for p in mesh.get("primitives", []))


def _sets(attrs: dict) -> int:
    """How many JOINTS_n / WEIGHTS_n pairs a primitive has, counting from 0."""
    n = 0
    while f"JOINTS_{n}" in attrs and f"WEIGHTS_{n}" in attrs:
        n += 1
    return n


class Poser:
    """Poses a level's skinned and morphed primitives; one per glTF reader (it caches the nodes'
    world matrices and each skin's joint matrices, and counts the work)."""

    def __init__(self, reader):
        self.r = reader
        self.doc = reader.doc
        self.terms = 0
        self._parent: np.ndarray | None = None
        self._world: dict[int, np.ndarray] = {}
        self._skins: dict[int, np.ndarray] = {}

    def fail(self, what: str):
        raise EnvironmentLoadError(f"corrupt glTF: {what}", where=str(self.r.path))

    # ------------------------------------------------------------------ joints
    def world(self, i: int) -> np.ndarray:
        """nodes[i]'s world matrix (4, 4) from the hierarchy (the node need not be in the
        scene): parent @ local down from its top ancestor, as the scene walk multiplies."""
        nodes = self.doc.get("nodes", [])
        if self._parent is None:
            parent = np.full(len(nodes), -1, dtype=np.int64)
            for p, node in enumerate(nodes):
                for c in node.get("children", []):
                    if parent[c] >= 0:
                        self.fail(f"node {c} has two parents, nodes {parent[c]} and {p}")
                    parent[c] = p
            self._parent = parent
        chain, j = [], i
        while j >= 0 and j not in self._world:
            chain.append(j)
            if len(chain) > len(nodes):
                self.fail(f"node {i}'s ancestors form a cycle")
            j = int(self._parent[j])
        m = np.eye(4) if j < 0 else self._world[j]
        for k in reversed(chain):
            m = m @ self.r.local_matrix(nodes[k])
            self._world[k] = m
        return self._world[i]

    def skin_matrices(self, si: int) -> np.ndarray:
        """skins[si]'s joint matrices (J, 3, 4): world(joint) @ inverse bind matrix, the last
        row dropped (checked finite)."""
        if si not in self._skins:
            skin = self.doc["skins"][si]
            joints = skin["joints"]
            world = np.stack([self.world(j) for j in joints])
            if "inverseBindMatrices" in skin:
                ibm = self.r.accessor(skin["inverseBindMatrices"])[: len(joints)]
                ibm = ibm.reshape(-1, 4, 4).transpose(0, 2, 1)      # stored column-major
                if not np.all(np.isfinite(ibm)):
                    self.fail(f"skins[{si}].inverseBindMatrices holds a non-finite number")
                world = world @ ibm
            if not np.all(np.isfinite(world)):
                self.fail(f"skins[{si}]'s joint matrices are not finite")
            self._skins[si] = np.ascontiguousarray(world[:, :3, :])
        return self._skins[si]

    # ------------------------------------------------------------------ one primitive
    def pose(self, node: dict, mesh: dict, prim: dict, points: np.ndarray, normals, where: str):
        """A primitive's posed (points (n, 3) float64, normals (n, 3) or None, skinned): morphed
        in the mesh's space, then, when skinned, in world space (the caller then places it by
        the node's instancing only, not by the node's transform)."""
        attrs = prim.get("attributes", {})
        weights = morph_weights(node, mesh)
        targets = prim.get("targets") or []
        active = [(k, float(weights[k])) for k in range(min(len(weights), len(targets)))
                  if weights[k] != 0]
        sets = _sets(attrs) if "skin" in node else 0
        if sets > MAX_SETS:
            self.fail(f"{where} has {sets} JOINTS_n/WEIGHTS_n sets; at most {MAX_SETS} "
                      f"({4 * MAX_SETS} influences per vertex) are read")
        self.terms += len(points) * (4 * sets + len(active))
        if self.terms > MAX_POSE_TERMS:
            raise EnvironmentLoadError(
                f"the level's skinned and morphed meshes need {self.terms:,} vertex influences "
                f"and morph targets (vertices x terms); a bake takes at most "
                f"{MAX_POSE_TERMS:,}: keep the part of the level the creature uses",
                where=str(self.r.path))
        if active:
            points = points.copy()
            normals = None if normals is None else normals.copy()
            for k, wk in active:
                t = targets[k]
                if "POSITION" in t:
                    points += wk * self._finite(t["POSITION"], f"{where}.targets[{k}].POSITION")
                if normals is not None and "NORMAL" in t:
                    normals += wk * self._finite(t["NORMAL"], f"{where}.targets[{k}].NORMAL")
        if not sets:
            return points, normals, False
        joints, w = self._influences(node["skin"], prim, attrs, sets, len(points), where)
        points, normals = skin(points, normals, joints, w, self.skin_matrices(node["skin"]))
        return points, normals, True

    def _finite(self, i: int, where: str) -> np.ndarray:
        a = self.r.accessor(i)
        if not np.all(np.isfinite(a)):
            self.fail(f"{where} (accessors[{i}]) holds a non-finite number")
        return a

    def _values(self, prim: dict, name: str, where: str) -> np.ndarray:
        """An attribute's values: from the accessor, or decoded from the primitive's Draco
        stream when it holds the attribute."""
        draco = gltf_ext.draco_of(prim)
        if draco is not None and name in draco.get("attributes", {}):
            acc = self.doc["accessors"][prim["attributes"][name]]
            return gltf_ext.decode_draco_attribute(self.r.view(draco["bufferView"]), draco,
                                                   name, where, bool(acc.get("normalized")))
        return self.r.accessor(prim["attributes"][name])

    def _influences(self, si: int, prim: dict, attrs: dict, sets: int, n: int, where: str):
        """(joints (n, 4 sets) uint16 checked in range, weights (n, 4 sets) float64 normalized to
        sum 1; a vertex of no weight has its first joint at weight 1, as three.js makes it)."""
        nj = len(self.doc["skins"][si]["joints"])
        joints = np.empty((n, 4 * sets), dtype=np.uint16)     # (JOINTS_n are bytes or shorts)
        weights = np.empty((n, 4 * sets), dtype=np.float64)
        for s in range(sets):
            j = self._values(prim, f"JOINTS_{s}", where)
            w = self._values(prim, f"WEIGHTS_{s}", where)
            if j.shape != (n, 4) or w.shape != (n, 4):
                self.fail(f"{where}'s JOINTS_{s} and WEIGHTS_{s} do not hold 4 values for each "
                          f"of its {n} vertices")
            top = min(nj, 1 << 16)         # (a Draco stream's joints may be wider than shorts)
            if j.size and (j.min() < 0 or j.max() >= top):
                bad = int(j.max()) if j.max() >= top else int(j.min())
                self.fail(f"{where}.attributes.JOINTS_{s} names joint {bad}; its skin "
                          f"(skins[{si}]) has {nj} joints")
            if not np.all(np.isfinite(w)):
                self.fail(f"{where}.attributes.WEIGHTS_{s} holds a non-finite weight")
            if w.size and w.min() < 0:
                self.fail(f"{where}.attributes.WEIGHTS_{s} holds a negative weight "
                          f"({float(w.min()):.9g})")
            joints[:, 4 * s: 4 * s + 4] = j
            weights[:, 4 * s: 4 * s + 4] = w
        total = weights.sum(axis=1)
        none = total <= 0
        if np.any(none):
            weights[none] = 0.0
            weights[none, 0] = 1.0
            total[none] = 1.0
        if not np.all(np.isfinite(total)):
            self.fail(f"{where}'s weights add up past the largest float")
        weights /= total[:, None]
        return joints, weights


def skin(points: np.ndarray, normals, joints: np.ndarray, weights: np.ndarray,
         mats: np.ndarray):
    """Linear blend skinning.

    points  : (n, 3) float64, the mesh's bind-pose vertices
    normals : (n, 3) float64 or None
    joints  : (n, k) integer indices into mats; weights : (n, k) float64 summing to 1 per vertex
    mats    : (J, 3, 4) float64 joint matrices (world(joint) @ inverse bind matrix)
    returns : (points (n, 3) float64 world, normals (n, 3) float64 (not unit) or None), each
              vertex moved by its blended matrix B = sum_i w_i mats[j_i], a normal by B's
              inverse transpose (as the cofactor matrix, its sign kept for a mirroring B)
    """
    out = np.empty_like(points)
    nout = None if normals is None else np.empty_like(normals)
    for s in range(0, len(points), _CHUNK):
        e = s + _CHUNK
        b = np.einsum("nk,nkij->nij", weights[s:e], mats[joints[s:e]])     # (c, 3, 4)
        out[s:e] = np.einsum("nij,nj->ni", b[:, :, :3], points[s:e]) + b[:, :, 3]
        if nout is not None:
            a, bb, c = b[:, :, 0], b[:, :, 1], b[:, :, 2]
            bc, ca, ab = np.cross(bb, c), np.cross(c, a), np.cross(a, bb)
            n = normals[s:e]
            cof = n[:, :1] * bc + n[:, 1:2] * ca + n[:, 2:] * ab
            det = np.einsum("ni,ni->n", a, bc)
            nout[s:e] = np.where(det[:, None] < 0, -cof, cof)
    return out, nout
