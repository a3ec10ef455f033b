"""A bake's GLB read back for pictures: the environment with its colours, the skinned creature,
the prey, the sun over time, the behaviour timeline and the foot contacts.

Everything comes from the file alone (baker/inspect.py rebuilds the joints' world transforms),
so a preview shows what an engine would load, not the simulation's own bookkeeping.

    scene = load_bake("outputs/centipede.glb")     # PreviewScene, or InspectError (one line)
    verts, normals = scene.skin.pose(scene.joint_matrices(f))
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from baker.export import vertex_normals
from baker.inspect import (BakedScene, GlbFile, InspectError, environment_nodes, frame_times,
                           glb_bytes, moved, read_glb, root_motion_fix, sample_track,
                           static_world)

#: the debug layer of the walkable surface (`bake --debug-navmesh`): one quad per sample
NAVMESH_NODE = "navmesh"
#: direction toward the sun when a file has no KHR_lights_punctual light
DEFAULT_SUN = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])


@dataclass(frozen=True)
class Surface:
    """A static triangle mesh in world coordinates.

    vertices : (n, 3) float64 metres; faces : (m, 3) int64
    normals  : (n, 3) float64 unit vertex normals; colors : (n, 3) float64 linear RGB (the
               material's baseColorFactor times COLOR_0 when the primitive has one)
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    colors: np.ndarray


@dataclass(frozen=True)
class Skin:
    """The creature's skinned mesh, ready for linear-blend skinning.

    vertices, normals : (n, 3) float64 bind pose; faces : (m, 3) int64; colors : (n, 3) linear
    joints  : (n, 4) int64 indices into BakedScene's joint order; weights : (n, 4) float64
    ibm     : (J, 4, 4) float64 inverse bind matrices, BakedScene's joint order
    """

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    colors: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    ibm: np.ndarray

    def pose(self, joint_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(vertices (n, 3), unit normals (n, 3)) skinned by joint world matrices (J, 4, 4):
        each vertex moved by the weighted sum of (joint world x inverse bind) matrices."""
        m = joint_world @ self.ibm                                       # (J, 4, 4)
        blend = np.einsum("nk,nkij->nij", self.weights, m[self.joints])  # (n, 4, 4)
        v = np.einsum("nij,nj->ni", blend[:, :3, :3], self.vertices) + blend[:, :3, 3]
        n = np.einsum("nij,nj->ni", blend[:, :3, :3], self.normals)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        return v, n


@dataclass(frozen=True)
class Prop:
    """An animated static mesh (a prey): local vertices (n, 3), faces (m, 3), normals (n, 3),
    color (3,) linear RGB, world (F, 4, 4) float64 at every frame."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    color: np.ndarray
    world: np.ndarray

    def visible(self, f: int) -> bool:
        """False where the prop is scaled to nothing (a prey eaten)."""
        return bool(abs(np.linalg.det(self.world[f, :3, :3])) > 1e-12)

    def at(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        """(world vertices (n, 3), unit normals (n, 3)) at frame f."""
        m = self.world[f]
        n = self.normals @ np.linalg.inv(m[:3, :3])   # inverse transpose, as rows
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        return _apply(m, self.vertices), n


@dataclass(frozen=True)
class PreviewScene:
    """What a preview draws, in world coordinates.

    name        : the file's stem; baked : the joints (F, J) and the extras (inspect.read_glb)
    body_length : metres, head to last trunk joint (from the rest pose)
    env         : the environment; navmesh : (k, 3) walkable sample points or None, on a
                  grid of navmesh_cell metres (the file's `navmesh` debug layer)
    skin        : the creature's mesh; prey : the prey props
    sun         : (F, 3) unit directions toward the sun at every frame
    states      : the behaviour names in order of first appearance; state : (F,) int64 index
                  into `states` at every frame (-1 where the timeline says nothing)
    segments    : ((start s, end s, state name), ...) the behaviour timeline
    contacts    : {foot joint index: (k, 2) int64 [down, up) frame intervals}
    """

    name: str
    baked: BakedScene
    body_length: float
    env: Surface
    navmesh: np.ndarray | None
    navmesh_cell: float
    skin: Skin
    prey: tuple[Prop, ...]
    sun: np.ndarray
    states: tuple[str, ...]
    state: np.ndarray
    segments: tuple[tuple[float, float, str], ...]
    contacts: dict[int, np.ndarray]

    @property
    def n_frames(self) -> int:
        return self.baked.n_frames

    @property
    def fps(self) -> int:
        return self.baked.fps

    @property
    def seconds(self) -> float:
        return (self.n_frames - 1) / self.fps

    @property
    def spine(self) -> np.ndarray:
        """Joint indices of the head and the trunk segments, head first."""
        names = self.baked.names
        trunk = sorted((i for i, n in enumerate(names) if n.startswith("trunk_")),
                       key=lambda i: names[i])
        return np.array([self.baked.index("head")] + trunk)

    def joint_matrices(self, f: int) -> np.ndarray:
        """(J, 4, 4) world matrices of every joint at frame f (joints are not scaled)."""
        m = np.zeros((len(self.baked.names), 4, 4))
        m[:, :3, :3] = Rotation.from_quat(self.baked.rotations[f]).as_matrix()
        m[:, :3, 3] = self.baked.positions[f]
        m[:, 3, 3] = 1.0
        return m


# ---------------------------------------------------------------- reading


def _apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Points (n, 3) moved by a (4, 4) matrix."""
    return v @ np.ascontiguousarray(m[:3, :3].T) + m[:3, 3]


def load_bake(source: str | Path | bytes, name: str | None = None) -> PreviewScene:
    """Read a GLB baker wrote (a path, or the file's bytes). InspectError (one line, naming
    the file) when it is missing, not a GLB, or not a bake (no skin, no animation)."""
    if isinstance(source, (bytes, bytearray)):
        data, where = bytes(source), name or "GLB"
    else:
        p = Path(source)
        where = str(p)
        if not p.exists():
            raise InspectError("file not found", where=where)
        if not p.is_file():
            raise InspectError("not a file", where=where)
        data = glb_bytes(p)
        name = name or p.stem
        if not data:
            raise InspectError("the file is empty", where=where)
    try:
        glb = GlbFile(data)
    except InspectError as e:
        raise InspectError(f"{e.what} (no glTF header)", where=where) from None
    except (ValueError, UnicodeDecodeError, struct.error) as e:
        raise InspectError(f"not a whole GLB file ({type(e).__name__})", where=where) from None
    doc = glb.doc
    if not isinstance(doc, dict):
        raise InspectError("GLB JSON chunk is not an object", where=where)
    if not doc.get("skins"):
        raise InspectError("a glTF without a skin: not a baker bake", where=where)
    if not doc.get("animations"):
        raise InspectError("a glTF without an animation: nothing to preview", where=where)
    try:
        return _scene(glb, name or "bake", where)
    except InspectError as e:
        raise InspectError(e.what.removeprefix(f"{where}: "), where=where) from None
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, struct.error) as e:
        raise InspectError(f"malformed glTF ({type(e).__name__}: {e})", where=where) from None


def _scene(glb: GlbFile, name: str, where: str) -> PreviewScene:
    doc = glb.doc
    names = [a.get("name") for a in doc["animations"]]
    baked = read_glb(where, "bake" if "bake" in names else 0, glb=glb)
    if "root_motion" in names and "root" in baked.names:
        baked = moved(baked, root_motion_fix(baked, read_glb(where, "root_motion", glb=glb)))
    anim = doc["animations"][names.index("bake") if "bake" in names else 0]
    world = static_world(doc)
    times = frame_times(baked.n_frames, baked.fps)
    tracks = _tracks(glb, anim, times)
    spine = [baked.index("head")] + sorted(
        (i for i, n in enumerate(baked.names) if n.startswith("trunk_")),
        key=lambda i: baked.names[i])
    spacing = float(np.mean(np.linalg.norm(baked.rest_translations[spine[1:]], axis=1)))
    states, state, segments = _timeline(baked, anim)
    nav, nav_cell = _navmesh(glb, world)
    return PreviewScene(
        name=name, baked=baked, body_length=spacing * (len(spine) - 1),
        env=_environment(glb, world), navmesh=nav, navmesh_cell=nav_cell, skin=_skin(glb, baked),
        prey=_prey(glb, world, tracks, len(times)), sun=_sun(doc, world, tracks, len(times)),
        states=states, state=state, segments=segments, contacts=_contacts(baked, anim))


def _tracks(glb: GlbFile, anim: dict, times: np.ndarray) -> dict:
    """{(node, path): (F, k) values} of an animation's channels on nodes that are not joints
    (the prey, the sun) sampled at `times`."""
    joints = {j for skin in glb.doc.get("skins", []) for j in skin["joints"]}
    out = {}
    for ch in anim["channels"]:
        s = anim["samplers"][ch["sampler"]]
        key = (ch["target"]["node"], ch["target"]["path"])
        if key[0] in joints:
            continue
        out[key] = sample_track(times, glb.accessor(s["input"]), glb.accessor(s["output"]),
                                key[1] == "rotation")
    return out


def _color(doc: dict, prim: dict) -> np.ndarray:
    mats = doc.get("materials", [])
    m = mats[prim["material"]] if "material" in prim else {}
    rgba = (m.get("pbrMetallicRoughness") or {}).get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
    return np.clip(np.asarray(rgba[:3], dtype=np.float64), 0.0, 1.0)


def _primitives(glb: GlbFile, mesh: int):
    """(vertices, faces, normals or None, colors (n, 3)) of each triangle primitive of a mesh."""
    doc = glb.doc
    for prim in doc["meshes"][mesh]["primitives"]:
        if prim.get("mode", 4) != 4:
            continue
        a = prim["attributes"]
        v = glb.accessor(a["POSITION"])
        f = (glb.accessor(prim["indices"]).astype(np.int64).reshape(-1, 3) if "indices" in prim
             else np.arange(len(v), dtype=np.int64).reshape(-1, 3))
        n = glb.accessor(a["NORMAL"]) if "NORMAL" in a else None
        c = np.broadcast_to(_color(doc, prim), v.shape).copy()
        if "COLOR_0" in a:
            c *= glb.accessor(a["COLOR_0"])[:, :3]
        yield prim, v, f, n, c


def _environment(glb: GlbFile, world: dict) -> Surface:
    vs, fs, ns, cs, off = [], [], [], [], 0
    for i in environment_nodes(glb.doc, world):
        m = world[i]
        for _, v, f, n, c in _primitives(glb, glb.doc["nodes"][i]["mesh"]):
            n = vertex_normals(v, f).astype(np.float64) if n is None else n
            n = n @ np.linalg.inv(m[:3, :3])
            vs.append(_apply(m, v))
            fs.append(f + off)
            ns.append(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12))
            cs.append(c)
            off += len(v)
    if not vs:
        raise InspectError("the file has no environment mesh")
    return Surface(np.concatenate(vs), np.concatenate(fs), np.concatenate(ns), np.concatenate(cs))


def _navmesh(glb: GlbFile, world: dict) -> tuple[np.ndarray, float] | tuple[None, float]:
    """(centres (k, 3) of the walkable-surface debug layer's quads, its cell size in metres),
    or (None, 0) without the layer. Each quad (4 vertices) is one sample's grid cell."""
    nodes = glb.doc["nodes"]
    for i in world:
        if nodes[i].get("name") == NAVMESH_NODE and "mesh" in nodes[i]:
            prims = glb.doc["meshes"][nodes[i]["mesh"]]["primitives"]
            v = np.concatenate([glb.accessor(p["attributes"]["POSITION"]) for p in prims])
            q = v[: len(v) // 4 * 4].reshape(-1, 4, 3)
            if not len(q):
                break
            return _apply(world[i], q.mean(axis=1)), float(abs(q[0, 2, 0] - q[0, 0, 0]))
    return None, 0.0


def _skin(glb: GlbFile, baked: BakedScene) -> Skin:
    doc = glb.doc
    node = next((n for n in doc["nodes"] if "skin" in n and "mesh" in n), None)
    if node is None:
        raise InspectError("the skin has no mesh node: not a baker bake")
    skin = doc["skins"][node["skin"]]
    order = np.array([baked.index(doc["nodes"][j].get("name", f"joint{j}"))
                      for j in skin["joints"]])
    ibm = glb.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    ibm_baked = np.tile(np.eye(4), (len(baked.names), 1, 1))
    ibm_baked[order] = ibm
    parts = []
    for prim, v, f, n, c in _primitives(glb, node["mesh"]):
        a = prim["attributes"]
        n = vertex_normals(v, f).astype(np.float64) if n is None else n
        parts.append((v, f, n, c, order[glb.accessor(a["JOINTS_0"]).astype(np.int64)],
                      glb.accessor(a["WEIGHTS_0"])))
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    return Skin(vertices=np.concatenate([p[0] for p in parts]),
                faces=np.concatenate([p[1] + o for p, o in zip(parts, offsets)]),
                normals=np.concatenate([p[2] for p in parts]),
                colors=np.concatenate([p[3] for p in parts]),
                joints=np.concatenate([p[4] for p in parts]),
                weights=np.concatenate([p[5] for p in parts]), ibm=ibm_baked)


def _trs(tracks: dict, node: int, spec: dict, n: int) -> np.ndarray:
    """(n, 4, 4) local matrices of a node: its animated tracks, else its own TRS."""
    t = tracks.get((node, "translation"), np.tile(spec.get("translation", [0.0] * 3), (n, 1)))
    q = tracks.get((node, "rotation"), np.tile(spec.get("rotation", [0.0, 0.0, 0.0, 1.0]), (n, 1)))
    s = tracks.get((node, "scale"), np.tile(spec.get("scale", [1.0] * 3), (n, 1)))
    m = np.zeros((n, 4, 4))
    m[:, :3, :3] = Rotation.from_quat(q).as_matrix() * np.asarray(s)[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def _parent_world(doc: dict, world: dict, node: int) -> np.ndarray:
    parent = next((i for i, n in enumerate(doc["nodes"]) if node in n.get("children", [])), None)
    return world.get(parent, np.eye(4)) if parent is not None else np.eye(4)


def _prey(glb: GlbFile, world: dict, tracks: dict, n: int) -> tuple[Prop, ...]:
    doc = glb.doc
    group = next((i for i in world if doc["nodes"][i].get("name") == "Prey"), None)
    if group is None:
        return ()
    out = []
    for i in doc["nodes"][group].get("children", []):
        spec = doc["nodes"][i]
        if "mesh" not in spec:
            continue
        parts = list(_primitives(glb, spec["mesh"]))
        v = np.concatenate([p[1] for p in parts])
        offsets = np.cumsum([0] + [len(p[1]) for p in parts[:-1]])
        f = np.concatenate([p[2] + o for p, o in zip(parts, offsets)])
        nrm = np.concatenate([vertex_normals(p[1], p[2]) if p[3] is None else p[3] for p in parts])
        out.append(Prop(name=spec.get("name", f"prey{i}"), vertices=v, faces=f,
                        normals=nrm.astype(np.float64), color=parts[0][4][0],
                        world=world[group] @ _trs(tracks, i, spec, n)))
    return tuple(out)


def _sun(doc: dict, world: dict, tracks: dict, n: int) -> np.ndarray:
    """(n, 3) unit directions toward the sun: the directional light node's +Z (it shines along
    its local -Z), animated when the bake moves the sun."""
    lights = (doc.get("extensions") or {}).get("KHR_lights_punctual", {}).get("lights", [])
    for i in world:
        ext = (doc["nodes"][i].get("extensions") or {}).get("KHR_lights_punctual")
        if ext is None or lights[ext["light"]].get("type") != "directional":
            continue
        m = _parent_world(doc, world, i) @ _trs(tracks, i, doc["nodes"][i], n)
        d = m[:, :3, 2]
        return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.tile(DEFAULT_SUN, (n, 1))


def _timeline(baked: BakedScene, anim: dict):
    """(state names, (F,) state index per frame, segments) from the scene extras' timeline, or
    from the behaviour events in the animation's extras."""
    fps, n = baked.fps, baked.n_frames
    segs = []
    for e in baked.extras.get("timeline") or []:
        segs.append((float(e["start"]), float(e["end"]), str(e["state"])))
    if not segs:
        ev = [e for e in (anim.get("extras") or {}).get("events", [])
              if e.get("type") == "behaviour"]
        for a, b in zip(ev, ev[1:] + [None]):
            segs.append((a["frame"] / fps, (b["frame"] if b else n - 1) / fps, str(a["state"])))
    states = tuple(dict.fromkeys(s for _, _, s in segs))
    state = np.full(n, -1, dtype=np.int64)
    for t0, t1, s in segs:
        state[int(round(t0 * fps)): int(round(t1 * fps)) + 1] = states.index(s)
    return states, state, tuple(segs)


def _contacts(baked: BakedScene, anim: dict) -> dict[int, np.ndarray]:
    """{foot joint: [down, up) intervals}: the animation's events (docs/clip_events.schema.json),
    else the scene extras' inclusive [first, last] pairs."""
    ev = (anim.get("extras") or {}).get("contacts")
    half_open = isinstance(ev, dict) and bool(ev)
    src = ev if half_open else baked.extras.get("foot_contacts") or {}
    out = {}
    for foot, spans in src.items():
        if foot in baked.names and spans:
            a = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
            out[baked.index(foot)] = a if half_open else a + [0, 1]
    return out

