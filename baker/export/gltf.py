"""glTF 2.0 binary (GLB) writer: environment, sun, skinned centipede and one animation.

Built with pygltflib objects; the GLB container is assembled here so the output is byte-for-byte
deterministic and both chunks are padded to 4 bytes. Node layout of the scene:

    Environment            group, translation = env.origin -> one node per EnvMesh (vertices
                           in the environment's local frame)
    Sun                    KHR_lights_punctual directional light, local -Z along the light
    Prey                   group, translation = clip.placement -> one animated node per prey
    Centipede              non-joint placement node, translation = clip.placement
                           -> head -> trunk_01 -> ... (the root joint's keys are relative to it)
    centipede_mesh         skinned mesh `centipede_skinned`, at the scene root with no transform
    Centipede_01, ...      a crowd's further creatures (`--creatures N`): each its own placement
    centipede_mesh_01, ... node and joints (`c01_head`, ...; export.creature_label), its own skin
                           `Centipede_01_skin`, and a mesh node of its own that uses the one
                           skinned mesh `centipede_skinned` with that skin
    <debug layers>         optional overlays, one node each, translation = env.origin

Names: every node, mesh and material name is unique, also without regard to case (engines key
objects by name and some ignore case). A static part keeps its name on its node; its mesh and
material add `_mesh` and `_mat` (`ground`, `ground_mesh`, `ground_mat`). Joint names are the
skeleton's own. The bake's metadata is stored once, in the scene's `extras` (three.js:
`gltf.scene.userData`; Blender: the scene's custom properties).

Positions far from the world origin stay precise: float32 data (vertices, animation keys) holds
small numbers relative to a node whose translation, a JSON number, is double precision. A zero
translation is left out.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import struct
from collections.abc import Sequence

import numpy as np
import pygltflib as gl

import baker
from baker.clip import Clip, NodeTrack
from baker.environment.model import Environment
from baker.errors import ExportError
from baker.export import checked_mesh, creature_label, environment_parts, jsonable, safe_name
from baker.geometry.transforms import light_rotation
from baker.rig.build import Rig

ANIM_LINEAR = "LINEAR"   # animation interpolation (NOT pygltflib.LINEAR, the texture filter 9729)
SKINNED_MESH = "centipede_skinned"   # the skinned mesh's name (its node is `centipede_mesh`)

FLOAT, SHORT, UINT16, UINT32 = gl.FLOAT, gl.SHORT, gl.UNSIGNED_SHORT, gl.UNSIGNED_INT
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = gl.ARRAY_BUFFER, gl.ELEMENT_ARRAY_BUFFER
_TYPES = {1: gl.SCALAR, 2: gl.VEC2, 3: gl.VEC3, 4: gl.VEC4, 16: gl.MAT4}
_NP = {FLOAT: np.float32, SHORT: np.int16, UINT16: np.uint16, UINT32: np.uint32}

log = logging.getLogger(__name__)

DebugMesh = tuple  # (name, vertices (n, 3), faces (m, 3), rgba)


class _Builder:
    """Accumulates the binary chunk and the accessor/bufferView lists."""

    def __init__(self, gltf: gl.GLTF2) -> None:
        self.gltf = gltf
        self.chunks: list[bytes] = []
        self.size = 0

    def _view(self, data: bytes, target: int | None) -> int:
        pad = (-self.size) % 4
        if pad:
            self.chunks.append(b"\0" * pad)
            self.size += pad
        self.gltf.bufferViews.append(gl.BufferView(buffer=0, byteOffset=self.size,
                                                   byteLength=len(data), target=target))
        self.chunks.append(data)
        self.size += len(data)
        return len(self.gltf.bufferViews) - 1

    def accessor(self, array: np.ndarray, component: int, *, target: int | None = None,
                 minmax: bool = False, normalized: bool | None = None) -> int:
        """Append `array` (n, k) or (n,) as one accessor in its own bufferView."""
        a = np.ascontiguousarray(array, dtype=_NP[component])
        count = a.shape[0]
        width = int(np.prod(a.shape[1:])) if a.ndim > 1 else 1
        view = self._view(a.tobytes(), target)
        acc = gl.Accessor(bufferView=view, byteOffset=0, componentType=component, count=count,
                          type=_TYPES[width], normalized=normalized)
        if minmax and count:
            flat = a.reshape(count, width)
            cast = float if component == FLOAT else int
            acc.min = [cast(x) for x in flat.min(axis=0)]
            acc.max = [cast(x) for x in flat.max(axis=0)]
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1

    def indices(self, faces: np.ndarray, n_vertices: int) -> int:
        comp = UINT16 if n_vertices <= 65535 else UINT32
        return self.accessor(np.asarray(faces).reshape(-1), comp, target=ELEMENT_ARRAY_BUFFER)

    def blob(self) -> bytes:
        data = b"".join(self.chunks)
        return data + b"\0" * ((-len(data)) % 4)


def _material(gltf: gl.GLTF2, name: str, rgba, metallic: float, roughness: float,
              double_sided: bool) -> int:
    rgba = [float(np.clip(c, 0.0, 1.0)) for c in rgba]
    mat = gl.Material(
        name=name,
        pbrMetallicRoughness=gl.PbrMetallicRoughness(
            baseColorFactor=rgba, metallicFactor=float(np.clip(metallic, 0, 1)),
            roughnessFactor=float(np.clip(roughness, 0, 1))),
        doubleSided=bool(double_sided),
        alphaMode=gl.BLEND if rgba[3] < 1.0 else gl.OPAQUE,
    )
    gltf.materials.append(mat)
    return len(gltf.materials) - 1


def _static_mesh(gltf: gl.GLTF2, b: _Builder, name: str, vertices, faces, normals,
                 material: int) -> int:
    v, f, n = checked_mesh(name, vertices, faces, normals)
    prim = gl.Primitive(
        attributes=gl.Attributes(
            POSITION=b.accessor(v, FLOAT, target=ARRAY_BUFFER, minmax=True),
            NORMAL=b.accessor(n, FLOAT, target=ARRAY_BUFFER)),
        indices=b.indices(f, len(v)), material=material, mode=gl.TRIANGLES)
    gltf.meshes.append(gl.Mesh(name=name, primitives=[prim]))
    return len(gltf.meshes) - 1


def _part_names(name: str, taken: set[str], fallback: str,
                node_reserved: bool = False) -> tuple[str, str, str]:
    """(node, mesh, material) names of one static part: the node keeps the part's name (made
    safe and unique), the mesh and the material add `_mesh` and `_mat`; all three unique against
    `taken` (updated), also without regard to case. node_reserved: `name` is already in `taken`
    (a prey node, which the clips' tracks drive by that exact name)."""
    node = name if node_reserved else safe_name(name, taken, fallback)
    return node, safe_name(f"{node}_mesh", taken), safe_name(f"{node}_mat", taken)


def _add_node(gltf: gl.GLTF2, node: gl.Node) -> int:
    gltf.nodes.append(node)
    return len(gltf.nodes) - 1


def _rounded(v) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=np.float32)]


def _offset(v) -> dict:
    """{"translation": v} in double precision, or {} for a zero offset."""
    v = np.asarray(v, dtype=np.float64).reshape(3)
    return {"translation": [float(x) for x in v]} if np.any(v != 0) else {}


def build_glb(env: Environment, rig: Rig | None, clip: Clip | None, *, extras: dict,
              debug_meshes: Sequence[DebugMesh] = (), props: Sequence[DebugMesh] = (),
              extra_clips: Sequence[Clip] = (), root_motion: NodeTrack | None = None,
              crowd: Sequence[Clip] = (),
              crowd_root_motion: Sequence[NodeTrack | None] = ()) -> bytes:
    """The whole scene as GLB bytes. Same inputs give identical bytes.

    env          : environment meshes (each gets a node and a PBR material) and the sun; the
                   Environment group node is translated by env.origin
    rig          : skeleton + skinned mesh, or None for an environment-only file
    clip         : animation over rig.skeleton's joints (and its node tracks: prey, sun), or
                   None for the rest pose only; clip.placement translates the Centipede and
                   Prey nodes
    extras       : custom data, stored once, in the scene's `extras` (made JSON-safe)
    debug_meshes : (name, vertices (n, 3), faces (m, 3), rgba) extra layers in the
                   environment's local frame, one node each (translated by env.origin)
    props        : (name, vertices, faces, rgba) animated scene objects (prey), one node each
                   under the Prey group, named exactly `name` so the clips' node tracks can
                   drive them
    extra_clips  : more animations over the same joints and nodes (per-behaviour clips)
    root_motion  : the motion an in-place clip leaves out (a track on the `root` joint), written
                   as one more animation named `root_motion`
    crowd        : the bake clips of a crowd's further creatures (creature 1, 2, ...) over the
                   same skeleton, each with its own placement and no node tracks: each gets its
                   own joints, skin and mesh node (sharing the skinned mesh), and its channels
                   go into the main clip's animation. extra_clips drive creature 0 only.
    crowd_root_motion : their root motion tracks (in-place), joined to `root_motion`'s
    Each clip's `events` go into its animation's `extras` (a crowd's bake animation: creature
    0's; every creature's timeline and foot contacts are in `extras`, see export.report).
    """
    if clip is not None and rig is None:
        raise ExportError("a clip needs a rig to drive")
    if any(np.any(c.placement != (clip.placement if clip else 0.0)) for c in extra_clips):
        raise ExportError("every clip of a scene must share the main clip's placement")
    if crowd and (clip is None or any(c.tracks for c in crowd)):
        raise ExportError("a crowd needs the main clip, and only it drives scene nodes")
    gltf = gl.GLTF2(asset=gl.Asset(version="2.0", generator=f"baker {baker.__version__}"))
    gltf.buffers = []
    b = _Builder(gltf)
    names, debug_names, creature_mats = _reserve_names(rig, props, debug_meshes,
                                                       1 + len(crowd))
    placement = clip.placement if clip is not None else np.zeros(3)
    scene_nodes: list[int] = []

    # -- environment
    env_children = []
    for m, rgba in environment_parts(env):
        nm, mesh_nm, mat_nm = _part_names(m.name, names, "env_mesh")
        mat = _material(gltf, mat_nm, rgba, m.metallic, m.roughness, double_sided=True)
        mesh = _static_mesh(gltf, b, mesh_nm, m.vertices, m.faces, m.normals, mat)
        env_children.append(_add_node(gltf, gl.Node(name=nm, mesh=mesh)))
    if env_children:
        scene_nodes.append(_add_node(gltf, gl.Node(name="Environment", children=env_children,
                                                   **_offset(env.origin))))

    # -- sun: KHR_lights_punctual directional light; it shines along the node's local -Z
    sun = env.sun
    gltf.extensions = {"KHR_lights_punctual": {"lights": [{
        "name": "Sun", "type": "directional",
        "color": [float(c) for c in sun.color], "intensity": float(sun.intensity)}]}}
    gltf.extensionsUsed = ["KHR_lights_punctual"]
    node_by_name: dict[str, int] = {}
    node_by_name["Sun"] = _add_node(gltf, gl.Node(
        name="Sun", rotation=_rounded(light_rotation(sun.direction)),
        extensions={"KHR_lights_punctual": {"light": 0}}))
    scene_nodes.append(node_by_name["Sun"])

    # -- props (prey): a mesh node each under a static group at the placement, animated by
    # the clips' node tracks
    prey_nodes = []
    for name, verts, faces, rgba in props:
        rgba = tuple(float(c) for c in rgba)
        _, mesh_nm, mat_nm = _part_names(name, names, "prey", node_reserved=True)
        mat = _material(gltf, mat_nm, rgba + (1.0,) * (4 - len(rgba)), 0.0, 0.7,
                        double_sided=False)
        mesh = _static_mesh(gltf, b, mesh_nm, verts, faces, None, mat)
        first = next((t for t in (clip.tracks if clip is not None else ()) if t.node == name), None)
        rest = {} if first is None or first.translations is None else dict(
            translation=_rounded(first.translations[0]), rotation=_rounded(first.rotations[0]))
        node_by_name[name] = _add_node(gltf, gl.Node(name=name, mesh=mesh, **rest))
        prey_nodes.append(node_by_name[name])
    if prey_nodes:
        scene_nodes.append(_add_node(gltf, gl.Node(name="Prey", children=prey_nodes,
                                                   **_offset(placement))))

    # -- the creature and its animations
    clips = (([clip] if clip is not None else []) + list(extra_clips)) if rig is not None else []
    if rig is not None:
        node_of, others = _add_creatures(gltf, b, creature_mats, rig, placement, crowd,
                                         scene_nodes)
        parts = [(c, node_of) for c in clips] + others
        dropped = _drop_static_channels(gltf, parts, node_by_name)
        for k, c in enumerate(clips):
            _add_animation(gltf, b, c, node_of, node_by_name, dropped,
                           more=others if k == 0 else ())
        motions = [(root_motion, node_of)] + list(zip(crowd_root_motion, [o[1] for o in others]))
        if any(m is not None for m, _ in motions):
            if clip is None:
                raise ExportError("root motion needs a clip")
            _add_root_motion(gltf, b, clip, rig, motions)

    # -- debug overlays
    for (name, verts, faces, rgba), nm in zip(debug_meshes, debug_names):
        if len(verts) == 0 or len(faces) == 0:
            log.warning("skipping empty debug layer %r", name)
            continue
        _, mesh_nm, mat_nm = _part_names(nm, names, "debug", node_reserved=True)
        rgba = tuple(float(c) for c in rgba)
        mat = _material(gltf, mat_nm, rgba + (1.0,) * (4 - len(rgba)), 0.0, 1.0,
                        double_sided=True)
        mesh = _static_mesh(gltf, b, mesh_nm, verts, faces, None, mat)
        scene_nodes.append(_add_node(gltf, gl.Node(name=nm, mesh=mesh, **_offset(env.origin))))

    gltf.scenes = [gl.Scene(name="Scene", nodes=scene_nodes)]
    gltf.scene = 0
    blob = b.blob()
    gltf.buffers = [gl.Buffer(byteLength=len(blob))]

    doc = _document(gltf)
    # extras are inserted after pygltflib's JSON pass, which would drop None/empty values;
    # stored once, on the scene: three.js (scene.userData) and Blender (the scene's custom
    # properties) surface scene extras, neither surfaces asset.extras
    doc["scenes"][0]["extras"] = jsonable(dict(extras))
    for anim, c in zip(doc.get("animations", []), clips):
        if c.events:
            anim["extras"] = jsonable(dict(c.events))
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False, ensure_ascii=True)
    return _glb_container(text.encode("utf-8"), blob)


def _document(gltf: gl.GLTF2) -> dict:
    """The glTF JSON document of `gltf` as a dict: json.loads(gltf.gltf_to_json()), the same
    keys in the same order, without pygltflib's deep copy of every value and its JSON round
    trip (most of the export's time in a crowd: 350k calls for 20 creatures). One pass builds
    it and drops the empty keys (_pruned)."""
    return _pruned(_items(gltf))


def _items(obj):
    """The (key, value) pairs _plain(obj) has when it is a dict (a pygltflib dataclass, its
    Attributes or a dict), else None."""
    kind = type(obj)
    if kind in _LEAVES or kind is list or kind is tuple:
        return None
    if kind is dict:
        return obj.items()
    if isinstance(obj, gl.Attributes):
        return obj.__dict__.items()
    fields = _fields_of(obj)
    if fields is not None:
        return [(name, getattr(obj, name)) for name in fields]
    return obj.items() if isinstance(obj, dict) else None


def _pruned(items) -> dict:
    """gl.delete_empty_keys(dict of _plain's values of items), built in one pass: a key whose
    plain value is None or empty is left out; a dict value (not an "extensions" one) and the
    dicts in a list value are pruned in turn (a dict emptied by its pruning stays, as there)."""
    out = {}
    for key, value in items:
        kind = type(value)
        if kind in _LEAVES:
            if kind is not str or value:
                out[key] = value
            continue
        if value is None:
            continue
        inner = _items(value)
        if inner is not None:
            if len(inner):
                out[key] = _plain(value) if key == "extensions" else _pruned(inner)
        elif isinstance(value, (list, tuple)):
            if len(value):
                out[key] = (list(value) if all(type(v) in _LEAVES for v in value) else
                            [_plain(v) if (sub := _items(v)) is None else _pruned(sub)
                             for v in value])
        elif not (hasattr(value, "__iter__") and len(value) == 0):
            out[key] = value
    return out


def _plain(obj):
    """pygltflib's gltf_asdict(obj) without copying the values: new dicts and lists, the
    same leaves (ints, floats, strings)."""
    if type(obj) in _LEAVES:
        return obj
    if isinstance(obj, gl.Attributes):
        return {k: _plain(v) for k, v in obj.__dict__.items()}
    fields = _fields_of(obj)
    if fields is not None:
        return {name: _plain(getattr(obj, name)) for name in fields}
    if isinstance(obj, (list, tuple)):
        if all(type(v) in _LEAVES for v in obj):
            return list(obj)
        return [_plain(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    return obj


def _fields_of(obj) -> tuple | None:
    """The field names of a dataclass instance (kept per class), else None."""
    fields = _FIELDS.get(type(obj))
    if fields is None and dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        fields = _FIELDS[type(obj)] = tuple(f.name for f in dataclasses.fields(obj))
    return fields


#: the types of JSON leaves: _plain keeps them as they are
_LEAVES = frozenset((int, float, str, bool))
#: the field names of each pygltflib dataclass
_FIELDS: dict = {}


def _glb_container(json_bytes: bytes, blob: bytes) -> bytes:
    json_bytes += b" " * ((-len(json_bytes)) % 4)
    blob += b"\0" * ((-len(blob)) % 4)
    total = 12 + 8 + len(json_bytes) + (8 + len(blob) if blob else 0)
    out = [b"glTF", struct.pack("<II", 2, total), struct.pack("<I", len(json_bytes)), b"JSON",
           json_bytes]
    if blob:
        out += [struct.pack("<I", len(blob)), b"BIN\0", blob]
    return b"".join(out)


def _reserve_names(rig: Rig | None, props: Sequence[DebugMesh],
                   debug_meshes: Sequence[DebugMesh],
                   creatures: int = 1) -> tuple[set[str], list[str], list[str]]:
    """The names baker itself writes, reserved before the environment's: the fixed nodes and
    the skinned mesh, the joints and prey (exactly as given), a crowd's further creatures'
    placement and mesh nodes and prefixed joints (export.creature_label), then the debug
    layers' nodes and the creature's materials (made safe and unique). Every other node, mesh
    and material name is made unique around them, also without regard to case.

    returns (taken: names and their lower-case forms, for safe_name; debug layer node names;
    the creature's material names, one per rig.mesh.materials entry)"""
    fixed = ["Environment", "Sun", "Centipede", "centipede_mesh", SKINNED_MESH] + (
        ["Prey"] if props else [])
    reserved = fixed + [p[0] for p in props] + (list(rig.skeleton.names) if rig else [])
    for i in range(1, creatures if rig else 1):
        top, prefix = creature_label(i, creatures)
        reserved += [top, _mesh_node_name(top)] + [prefix + n for n in rig.skeleton.names]
    names: set[str] = {n.lower() for n in reserved}
    if len(names) != len(reserved):
        raise ExportError("joint or prey names clash with the scene's node names "
                          f"({', '.join(fixed)}), also when case is ignored")
    names.update(reserved)
    debug = [safe_name(d[0], names, "debug") for d in debug_meshes]
    mats = [safe_name(f"centipede_{m}", names) for m, _ in (rig.mesh.materials if rig else ())]
    return names, debug, mats


def _add_creatures(gltf: gl.GLTF2, b: _Builder, mat_names: Sequence[str], rig: Rig, placement,
                   crowd: Sequence[Clip], scene_nodes: list[int]):
    """Creature 0 (_add_creature at placement (3,) float64 metres) and a crowd's further
    creatures (each at its clip's placement, named by export.creature_label, sharing creature
    0's skinned mesh); their root nodes are appended to scene_nodes.
    Returns (creature 0's joint node indices, [(clip, joint node indices)] of the others)."""
    roots, node_of = _add_creature(gltf, b, mat_names, rig, placement)
    scene_nodes.extend(roots)
    others = []
    for i, c in enumerate(crowd, start=1):
        more, nodes = _add_creature(gltf, b, mat_names, rig, c.placement,
                                    label=creature_label(i, 1 + len(crowd)),
                                    mesh=gltf.nodes[roots[1]].mesh)
        scene_nodes.extend(more)
        others.append((c, nodes))
    return node_of, others


def _mesh_node_name(top: str) -> str:
    """The skinned mesh node of the creature whose placement node is `top`:
    `centipede_mesh`, `centipede_mesh_01`, ..."""
    return "centipede_mesh" + top[len("Centipede"):]


def _add_creature(gltf: gl.GLTF2, b: _Builder, mat_names: Sequence[str], rig: Rig, placement,
                  label: tuple[str, str] = ("Centipede", ""), mesh: int | None = None):
    """Joint nodes under a non-joint placement node (`Centipede`, translated by placement
    (3,) float64, metres, world) and the skinned mesh node (scene root, no transform; its
    inverse bind matrices are in the skeleton's own frame, so the placement moves the skin with
    the joints).
    mat_names: the material name of each rig.mesh.materials entry.
    label : (placement node name, joint-name prefix), export.creature_label
    mesh  : the skinned mesh to use (a crowd's creatures share one), or None to write it
    Returns (the scene-root node indices it added, the node index of every joint)."""
    skel = rig.skeleton
    j_count = skel.n_joints
    top_name, prefix = label

    # joint nodes in skeleton order, rest TRS; children from the parents array
    first = len(gltf.nodes)
    node_of = np.arange(j_count) + first
    for j in range(j_count):
        kids = [int(node_of[c]) for c in skel.children(j)]
        gltf.nodes.append(gl.Node(
            name=prefix + skel.names[j], translation=_rounded(skel.rest_translations[j]),
            rotation=_rounded(skel.rest_rotations[j]), children=kids or None))
    roots = [int(node_of[j]) for j in range(j_count) if skel.parents[j] < 0]
    top = _add_node(gltf, gl.Node(name=top_name, children=roots, **_offset(placement)))

    # skin: inverse bind matrices = inverse(world bind), column-major
    ibm = np.linalg.inv(skel.world_bind())
    ibm_acc = b.accessor(ibm.transpose(0, 2, 1).reshape(j_count, 16), FLOAT)
    gltf.skins.append(gl.Skin(name=f"{top_name}_skin", inverseBindMatrices=ibm_acc,
                              joints=[int(x) for x in node_of], skeleton=roots[0]))
    skin = len(gltf.skins) - 1
    if mesh is None:
        mesh = _skinned_mesh(gltf, b, mat_names, rig)
    mesh_node = _add_node(gltf, gl.Node(name=_mesh_node_name(top_name), mesh=mesh, skin=skin))
    return [top, mesh_node], node_of


def _skinned_mesh(gltf: gl.GLTF2, b: _Builder, mat_names: Sequence[str], rig: Rig) -> int:
    """The rig's skinned mesh `centipede_skinned` with its materials; returns its index."""
    mesh = rig.mesh
    prims = []
    for mi, (mname, rgb) in enumerate(mesh.materials):
        used, faces = mesh.submesh(mi)
        if not len(faces):
            continue
        mat = _material(gltf, mat_names[mi], tuple(rgb) + (1.0,), 0.0, 0.6, double_sided=False)
        prims.append(gl.Primitive(
            attributes=gl.Attributes(
                POSITION=b.accessor(mesh.vertices[used], FLOAT, target=ARRAY_BUFFER, minmax=True),
                NORMAL=b.accessor(mesh.normals[used], FLOAT, target=ARRAY_BUFFER),
                JOINTS_0=b.accessor(mesh.joints[used], UINT16, target=ARRAY_BUFFER),
                WEIGHTS_0=b.accessor(mesh.weights[used], FLOAT, target=ARRAY_BUFFER)),
            indices=b.indices(faces, len(used)), material=mat, mode=gl.TRIANGLES))
    gltf.meshes.append(gl.Mesh(name=SKINNED_MESH, primitives=prims))
    return len(gltf.meshes) - 1


def _add_root_motion(gltf: gl.GLTF2, b: _Builder, clip: Clip, rig: Rig, motions) -> None:
    """The `root_motion` animation: each creature's track on its `root` joint.
    motions : (NodeTrack or None, node index of every joint) per creature, creature 0 first"""
    names = rig.skeleton.names
    tracks, joints = [], {}
    for i, (track, node_of) in enumerate(motions):
        if track is None:
            continue
        prefix = creature_label(i, len(motions))[1]
        joints.update({prefix + n: int(node_of[j]) for j, n in enumerate(names)})
        tracks.append(track if not prefix else NodeTrack(prefix + track.node, track.translations,
                                                         track.rotations, track.scales))
    _add_animation(gltf, b, _track_clip(clip, tuple(tracks)), np.zeros(0, np.int64), joints)


def _track_clip(clip: Clip, tracks: tuple[NodeTrack, ...]) -> Clip:
    """A clip named `root_motion` over no joints that plays node tracks along `clip`."""
    f = clip.n_frames
    empty = np.zeros((f, 0, 3), np.float32)
    return Clip(name="root_motion", times=clip.times, translations=empty,
                rotations=np.zeros((f, 0, 4), np.float32), scales=empty, fps=clip.fps,
                tracks=tracks, placement=clip.placement)


def _add_animation(gltf: gl.GLTF2, b: _Builder, clip: Clip, node_of: np.ndarray,
                   node_by_name: dict[str, int], dropped: frozenset = frozenset(),
                   more: Sequence[tuple[Clip, np.ndarray]] = ()) -> None:
    """One glTF animation for `clip`: every frame of every channel, or, for a reduced clip
    (clip.keys), each channel's kept keys (see _add_reduced_channels).
    more : (clip, node index of every joint) of a crowd's further creatures, played by the
           same animation (same frames; each reduced or not as `clip` is)"""
    parts = [(clip, node_of)] + list(more)
    times = np.asarray(clip.times, dtype=np.float32)
    if clip.translations.shape[0] == 0 or times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ExportError("clip times must start at >= 0 and strictly increase")
    for c, nodes in parts:
        j_count = c.translations.shape[1]
        if j_count != len(nodes):
            raise ExportError(f"clip has {j_count} joints, the skeleton {len(nodes)}")
        if c is not clip and (c.n_frames != clip.n_frames or (c.keys is None) != (clip.keys is None)):
            raise ExportError("a crowd's clips must have the same frames, all reduced or none")
        for tr in c.tracks:
            if tr.node not in node_by_name:
                raise ExportError(f"clip {c.name!r} animates node {tr.node!r}, which is not in the scene")
    if clip.keys is not None:
        _add_reduced_channels(gltf, b, parts, node_by_name, dropped)
        return
    t_acc = b.accessor(times, FLOAT, minmax=True)
    samplers, channels = [], []

    def channel(node: int, path: str, values: np.ndarray) -> None:
        samplers.append(gl.AnimationSampler(input=t_acc, output=b.accessor(values, FLOAT),
                                            interpolation=ANIM_LINEAR))
        channels.append(gl.AnimationChannel(
            sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=int(node), path=path)))

    for c, nodes in parts:
        rot = np.asarray(c.rotations, dtype=np.float32)
        scl = np.asarray(c.scales, dtype=np.float32)
        animate_scale = not np.all(scl == 1.0)
        for j in range(len(nodes)):
            channel(nodes[j], "translation", c.translations[:, j])
            channel(nodes[j], "rotation", rot[:, j])
            if animate_scale:
                channel(nodes[j], "scale", scl[:, j])
        for tr in c.tracks:
            node = node_by_name[tr.node]
            for path, values in (("translation", tr.translations), ("rotation", tr.rotations),
                                 ("scale", tr.scales)):
                if values is not None:
                    channel(node, path, np.asarray(values, dtype=np.float32))
    gltf.animations.append(gl.Animation(name=clip.name, samplers=samplers, channels=channels))


def _clip_channels(clip: Clip, node_of: np.ndarray, node_by_name: dict[str, int]):
    """(node, path, Keys, channel index) of every channel of a reduced clip, in writing order:
    per joint translation, rotation, scale; then each node track's paths."""
    k = clip.keys
    for j in range(len(node_of)):
        for path, keys in (("translation", k.translations), ("rotation", k.rotations),
                           ("scale", k.scales)):
            yield int(node_of[j]), path, keys, j
    for tr, tk in zip(clip.tracks, k.tracks):
        if tr.node not in node_by_name:
            raise ExportError(f"clip {clip.name!r} animates node {tr.node!r}, which is not in the scene")
        for path, keys in tk.parts():
            yield node_by_name[tr.node], path, keys, 0


def _drop_static_channels(gltf: gl.GLTF2, parts, node_by_name: dict[str, int]) -> frozenset:
    """The (node, path) channels that are static with the same value in every animation of the
    file that drives them (all reduced): they are written as the node's TRS and get no channel.
    parts : (clip, node index of every joint it drives) of every clip. Returns them."""
    if not parts or any(c.keys is None for c, _ in parts):
        return frozenset()
    value: dict = {}
    for c, node_of in parts:
        for node, path, keys, i in _clip_channels(c, node_of, node_by_name):
            v = None if keys.frames(i) is not None else tuple(float(x) for x in keys.static[i])
            if value.get((node, path), v) != v:
                v = None
            value[(node, path)] = v
    dropped = {key: v for key, v in value.items() if v is not None}
    for (node, path), v in sorted(dropped.items()):
        n = gltf.nodes[node]
        if path == "scale":
            n.scale = None if v == (1.0, 1.0, 1.0) else list(v)
        else:
            setattr(n, path, list(v))
    return frozenset(dropped)


def _add_reduced_channels(gltf: gl.GLTF2, b: _Builder, parts, node_by_name: dict[str, int],
                          dropped: frozenset) -> None:
    """A reduced clip's animation: each channel's kept frames (clip.keys), the key sets sharing
    their time accessors; rotations as normalized SHORT when the keys say so. A static channel
    is left out when it is in `dropped` (its value is the node's TRS), else written as one key.
    parts : (clip, node index of every joint) of each creature, in one animation named after
            the first clip"""
    clip = parts[0][0]
    times = np.asarray(clip.times, dtype=np.float32)
    time_of: dict[bytes, int] = {}
    samplers, channels = [], []
    channels_of = (ch for c, node_of in parts for ch in _clip_channels(c, node_of, node_by_name))
    for node, path, keys, i in channels_of:
        frames = keys.frames(i)
        if frames is None and (node, path) in dropped:
            continue
        if frames is None:                           # static, but not in every animation
            frames, out = np.zeros(1, np.int64), b.accessor(keys.static[i][None], FLOAT)
        elif keys.codes is not None:
            out = b.accessor(keys.codes[frames, i], SHORT, normalized=True)
        else:
            out = b.accessor(keys.values[frames, i], FLOAT)
        key = frames.tobytes()
        if key not in time_of:
            time_of[key] = b.accessor(times[frames], FLOAT, minmax=True)
        samplers.append(gl.AnimationSampler(input=time_of[key], output=out,
                                            interpolation=ANIM_LINEAR))
        channels.append(gl.AnimationChannel(
            sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=node, path=path)))
    gltf.animations.append(gl.Animation(name=clip.name, samplers=samplers, channels=channels))
