"""Judge a bake from its files alone: read the GLB (and the USD) back, rebuild every joint's
world transform in float64, and measure the motion-quality limits against the environment
stored in the same file.

Nothing here uses the simulation's own bookkeeping (gait contacts, clearances, cobra lift): a
foot is in contact when it is within CONTACT_BL body lengths of the surface in two consecutive
frames, whatever the gait declares (the GMD-style skate measure), and the environment is the
`Environment` node's meshes as written.

    scene = read_glb(path)            # BakedScene: joints (F, J) world + environment triangles
    usd = read_usd(path_usd)          # joints only
    result = judge(scene, usd)        # {"metrics": {...}, "worst": {...}}
    failures(result["metrics"])       # the limits that do not hold

A crowd (`--creatures N`) holds a skin (GLB) and a Skeleton (USD) per creature: read_glb and
read_usd take a creature index (0 by default), and judge_creatures judges each of them.
"""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from baker.errors import BakerError, exception_text
from baker.geometry.transforms import quat_conj, quat_mul

#: a foot within this many body lengths of the surface is touching it
CONTACT_BL = 0.01
#: the limits of issue 10, as (metric, comparison, bound)
LIMITS = (
    ("spacing_error_max", "<=", 0.02),
    ("head_slope_max_deg", "<=", 60.0),
    ("spine_inside_geometry", "==", 0),
    ("spine_bone_hits", "==", 0),
    ("skate_median_pct_bl", "<", 0.2),
    ("skate_ratio", "<", 0.02),
    ("foot_penetration_max_pct_bl", "<", 0.5),
    ("leg_bone_hits", "==", 0),
    ("rotation_max_deg", "<", 30.0),
    ("neighbour_feet_min_spacing", ">=", 0.2),
    ("glb_usd_max_m", "<=", 1e-4),
    ("sim_max_m", "<=", 1e-5),
    ("validator_errors", "==", 0),
)

_COMP = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
         5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class InspectError(BakerError):
    """A file that is not a baker bake (no skin, no animation) or cannot be read."""


@dataclass(frozen=True)
class BakedScene:
    """What a bake's file holds, in world coordinates (float64).

    names     : J joint names, parents first
    parents   : (J,) int, parent joint index, -1 for the root joint
    positions : (F, J, 3) float64 metres, world joint origins at each frame
    rotations : (F, J, 4) float64 xyzw, world joint rotations
    local     : (F, J, 4) float64 xyzw, joint rotations relative to the parent joint (as animated)
    rest_translations : (J, 3) float64, local rest translations (bone vectors)
    fps       : frames per second of the frame grid the joints are sampled on
    env_vertices : (n, 3) float64 world; env_faces : (m, 3) int64 (empty for a USD read)
    extras    : the file's custom data (glTF scene extras, see glb_extras)
    """

    names: tuple[str, ...]
    parents: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    local: np.ndarray
    rest_translations: np.ndarray
    fps: int
    env_vertices: np.ndarray
    env_faces: np.ndarray
    extras: dict

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    def index(self, name: str) -> int:
        return self.names.index(name)


# ---------------------------------------------------------------- glTF


def glb_bytes(path: str | Path) -> bytes:
    """A GLB file's bytes, read whole only once its 20-byte header agrees with the file (the
    total length, a non-empty JSON chunk inside it): a sparse file of gigabytes is refused
    unread.
    InspectError otherwise."""
    with open(path, "rb") as f:
        head = f.read(20)
        size = os.fstat(f.fileno()).st_size
        if len(head) >= 20 and head[:4] == b"glTF":
            total, jlen = struct.unpack_from("<I", head, 8)[0], struct.unpack_from("<I", head, 12)[0]
            if total != size or 20 + jlen > size or not jlen or head[16:20] != b"JSON":
                raise InspectError(f"not a whole GLB file (its header says {total:,} bytes with "
                                   f"a {jlen:,}-byte JSON chunk; the file has {size:,})",
                                   where=str(path))
        return head + f.read()


def _not_json(name: str):
    raise ValueError(f"{name} is not a JSON number")


def strict_json(text):
    """json.loads, refusing NaN, Infinity and -Infinity (Python's reader takes them; they are
    not JSON, and a report printed with --json must be JSON): ValueError, as for arrays or
    objects nested deeper than Python's reader recurses (a GLB's JSON chunk of 100,000 '['
    was a RecursionError traceback)."""
    try:
        return json.loads(text, parse_constant=_not_json)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


class GlbFile:
    """A GLB container parsed: `doc` (the JSON document) and `accessor(i)` (float64 arrays)."""

    def __init__(self, data: bytes):
        if len(data) < 20 or data[:4] != b"glTF":
            raise InspectError("not a GLB file")
        jlen = struct.unpack_from("<I", data, 12)[0]
        self.doc = strict_json(data[20:20 + jlen])
        off = 20 + jlen
        self.bin = data[off + 8:] if off + 8 <= len(data) else b""

    def accessor(self, i: int) -> np.ndarray:
        acc = self.doc["accessors"][i]
        view = self.doc["bufferViews"][acc["bufferView"]]
        width = _WIDTH[acc["type"]]
        dt = np.dtype(_COMP[acc["componentType"]])
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        a = np.frombuffer(self.bin, dtype=dt, count=acc["count"] * width, offset=start)
        a = a.astype(np.float64)
        if acc.get("normalized"):
            a = np.maximum(a / np.iinfo(dt).max, -1.0)
        return a.reshape(acc["count"], width) if width > 1 else a


def glb_extras(doc: dict) -> dict:
    """The bake's metadata in a glTF document: the default scene's `extras` (where baker stores
    it), or `asset.extras` in files written before it moved there; {} when neither is a dict."""
    scenes = doc.get("scenes") or []
    i = doc.get("scene", 0)
    scene = scenes[i] if isinstance(i, int) and 0 <= i < len(scenes) else {}
    for ex in (scene.get("extras") if isinstance(scene, dict) else None,
               (doc.get("asset") or {}).get("extras")):
        if isinstance(ex, dict) and ex:
            return ex
    return {}


def node_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    m = np.eye(4)
    r = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    m[:3, :3] = Rotation.from_quat(r).as_matrix() * np.asarray(node.get("scale", [1.0] * 3))
    m[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return m


def _trs_matrices(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(F, 4, 4) from (F, 3) translations, (F, 4) xyzw rotations, (F, 3) scales."""
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = Rotation.from_quat(q).as_matrix() * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def sample_track(times: np.ndarray, keys: np.ndarray, values: np.ndarray,
                 rotation: bool) -> np.ndarray:
    """LINEAR sampling of a glTF channel at `times` (clamped at both ends); rotations slerp."""
    t = np.clip(times, keys[0], keys[-1])
    if len(keys) == 1:
        return np.repeat(values[:1], len(times), axis=0)
    if len(keys) == len(t) and np.array_equal(keys, t):      # a key on every frame (a bake)
        return Rotation.from_quat(values).as_quat() if rotation else values.copy()
    if rotation:
        return Slerp(keys, Rotation.from_quat(values))(t).as_quat()
    return np.stack([np.interp(t, keys, values[:, c]) for c in range(values.shape[1])], 1)


def environment_nodes(doc: dict, world: dict[int, np.ndarray]) -> list[int]:
    """Mesh nodes of the environment: under the `Environment` node when there is one, else every
    static mesh node that is not skinned."""
    nodes = doc.get("nodes", [])
    env = [i for i, n in enumerate(nodes) if n.get("name") == "Environment"]
    if env:
        out, stack, seen = [], list(env), set()
        while stack:
            i = stack.pop()
            _first_visit(seen, i)
            if "mesh" in nodes[i]:
                out.append(i)
            stack.extend(nodes[i].get("children", []))
        return sorted(out)
    animated = {ch["target"]["node"] for a in doc.get("animations", []) for ch in a["channels"]}
    return [i for i in world if "mesh" in nodes[i] and "skin" not in nodes[i] and i not in animated]


def _environment(g: GlbFile, world: dict[int, np.ndarray]):
    vs, fs, off = [], [], 0
    for i in environment_nodes(g.doc, world):
        m = world[i]
        for prim in g.doc["meshes"][g.doc["nodes"][i]["mesh"]]["primitives"]:
            if prim.get("mode", 4) != 4:
                continue
            v = g.accessor(prim["attributes"]["POSITION"])
            f = (g.accessor(prim["indices"]).astype(np.int64) if "indices" in prim
                 else np.arange(len(v), dtype=np.int64))
            vs.append(v @ m[:3, :3].T + m[:3, 3])
            fs.append(f.reshape(-1, 3) + off)
            off += len(v)
    if not vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.concatenate(vs), np.concatenate(fs)


def static_world(doc: dict) -> dict[int, np.ndarray]:
    """{node index: (4, 4) float64 world matrix} of every node in the default scene, from the
    nodes' own (unanimated) transforms."""
    nodes = doc.get("nodes", [])
    world: dict[int, np.ndarray] = {}
    stack = [(i, np.eye(4)) for i in doc["scenes"][doc.get("scene", 0)]["nodes"]]
    seen = set()
    while stack:
        i, pm = stack.pop()
        _first_visit(seen, i)
        world[i] = pm @ node_matrix(nodes[i])
        stack.extend((c, world[i]) for c in nodes[i].get("children", []))
    return world


def _first_visit(seen: set, i) -> None:
    """Add node i to the nodes `seen`; ValueError when it was there already: a node its own
    descendant (a cycle: the walk went on for ever, --judge and preview hung) or listed under
    two parents, which glTF forbids."""
    if not isinstance(i, int) or isinstance(i, bool) or i < 0:
        raise ValueError(f"node index {i!r} is not a node")
    if i in seen:
        raise ValueError(f"node {i} is reached twice in the node hierarchy (a cycle or two "
                         "parents)")
    seen.add(i)


def frame_times(n_frames: int, fps: int) -> np.ndarray:
    """(n_frames,) float64 seconds: frame f at float32(f / fps), as glTF stores key times."""
    return (np.arange(n_frames) / fps).astype(np.float32).astype(np.float64)


def creature_count(doc: dict) -> int:
    """How many creatures a bake's glTF document holds: one skin each."""
    return len(doc.get("skins") or [])


#: a crowd creature's glTF joint-name prefix (c01_head, ...; export.creature_label)
_PREFIX = re.compile(r"^c\d+_")


def _unprefixed(names: list[str]) -> list[str]:
    """Joint names less the creature prefix they all share (`c01_`), as the rig names them."""
    m = _PREFIX.match(names[0]) if names else None
    if m and all(n.startswith(m.group(0)) for n in names):
        return [n[len(m.group(0)):] for n in names]
    return names


def read_glb(path: str | Path, animation: str | int = 0,
             glb: GlbFile | None = None, creature: int = 0) -> BakedScene:
    """Read a bake's GLB: the skin's joints posed by `animation` (name or index) at every frame
    of the bake's fps grid, composed with their non-joint ancestors in float64, and the
    environment's triangles in world coordinates. glb: the file already parsed (then `path`
    only names it in messages). creature: which skin (a crowd's creature); its joint names
    are returned less their creature prefix."""
    g = glb if glb is not None else GlbFile(glb_bytes(path))
    doc = g.doc
    nodes = doc.get("nodes", [])
    if not doc.get("skins") or not doc.get("animations"):
        raise InspectError(f"{path}: no skin or no animation")
    if not 0 <= creature < creature_count(doc):
        raise InspectError(f"{path}: no creature {creature} (it has {creature_count(doc)})")
    anims = doc["animations"]
    anim = next((a for a in anims if a.get("name") == animation), None) if isinstance(
        animation, str) else anims[animation]
    if anim is None:
        raise InspectError(f"{path}: no animation named {animation!r}")
    extras = glb_extras(doc)
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    world = static_world(doc)
    chans = {(ch["target"]["node"], ch["target"]["path"]): anim["samplers"][ch["sampler"]]
             for ch in anim["channels"]}
    keys = np.concatenate([g.accessor(s["input"]) for s in anim["samplers"]])
    fps = int(extras.get("fps") or round((len(np.unique(keys)) - 1) / max(keys.max(), 1e-9)))
    n_frames = int(round(float(keys.max()) * fps)) + 1
    # frame f is keyed at float32(f / fps), as glTF stores times: sample exactly there
    times = frame_times(n_frames, fps)

    def local_tracks(i: int):
        n = nodes[i]
        out = []
        for p, default, rot in (("translation", [0.0] * 3, False),
                                ("rotation", [0.0, 0.0, 0.0, 1.0], True),
                                ("scale", [1.0] * 3, False)):
            s = chans.get((i, p))
            if s is None:
                out.append(np.tile(np.asarray(n.get(p, default), float), (n_frames, 1)))
            else:
                out.append(sample_track(times, g.accessor(s["input"]), g.accessor(s["output"]),
                                        rot))
        return out

    joints = list(doc["skins"][creature]["joints"])
    jset = set(joints)
    # joint order parents first (the skin lists them that way in a baker bake; sort to be sure)
    depth = {}
    for j in joints:
        d, k = 0, j
        while k in parent:
            k, d = parent[k], d + 1
        depth[j] = d
    pos = {j: k for k, j in enumerate(joints)}
    if any(parent.get(j) in pos and pos[parent[j]] > pos[j] for j in joints):
        joints.sort(key=lambda j: (depth[j], pos[j]))
    mats: dict[int, np.ndarray] = {}
    local_q = np.zeros((n_frames, len(joints), 4))
    rest_t = np.zeros((len(joints), 3))
    for k, j in enumerate(joints):
        t, q, s = local_tracks(j)
        local_q[:, k] = q
        rest_t[k] = nodes[j].get("translation", [0.0] * 3)
        p = parent.get(j)
        pm = mats[p] if p in mats else (world[p] if p is not None else np.eye(4))
        mats[j] = pm @ _trs_matrices(t, q, s)
    m = np.stack([mats[j] for j in joints], axis=1)                     # (F, J, 4, 4)
    rot = m[..., :3, :3] / np.linalg.norm(m[..., :3, :3], axis=-2, keepdims=True)
    world_q = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(n_frames, -1, 4)
    index = {j: k for k, j in enumerate(joints)}
    parents = np.array([index.get(parent.get(j), -1) if parent.get(j) in jset else -1
                        for j in joints])
    ev, ef = _environment(g, world)
    names = _unprefixed([nodes[j].get("name", f"joint{j}") for j in joints])
    return BakedScene(names=tuple(names),
                      parents=parents, positions=m[..., :3, 3].copy(), rotations=world_q,
                      local=local_q, rest_translations=rest_t, fps=fps, env_vertices=ev,
                      env_faces=ef, extras=extras)


# ---------------------------------------------------------------- USD


def open_stage(path: str | Path):
    """Usd.Stage.Open(path), or None; what USD's C++ code prints itself (a corrupt crate's
    'failed call to posix_madvise') is held back from stderr (environment.native). The stage
    is opened on a thread with the stack a USD level is read on (load.USD_STACK_BYTES), after
    _check_layers: USD's C++ code recurses once per level of prims in prims, and a text
    layer 200,000 levels deep crashed the process (SIGSEGV)."""
    from baker.environment.load import USD_STACK_BYTES
    from baker.environment.native import held_stderr
    from baker.parallel import on_own_stack

    with held_stderr(str(path)):
        return on_own_stack(USD_STACK_BYTES, _open_checked, str(path))


def _open_checked(path: str):
    from pxr import Usd

    _check_layers(path)
    return Usd.Stage.Open(path)


def _check_layers(path: str) -> None:
    """InspectError for a layer the file brings in (sublayers, references, payloads,
    recursively) that USD must not be let open: a FIFO, a device or a folder (a FIFO's read
    waited for ever for a writer), and the level reader's bounds (load.walk_usd_layers: the
    layers' count and depth). What is missing or corrupt is left to Usd.Stage.Open."""
    from baker.environment.load import walk_usd_layers

    walk_usd_layers(Path(path), lambda layer, name, dep: _layer_file(path, layer, name, dep),
                    lambda text: InspectError(text, where=path), must_open=False)


def _layer_file(path: str, layer, name: str, dep: str) -> str | None:
    """The resolved file of a layer's dependency `dep` to walk next (walk_usd_layers), None
    for one that is not a file of its own (a URL, a layer inside a package, what does not
    exist: Usd.Stage.Open says it); InspectError for a FIFO, a device or a folder."""
    import stat

    from pxr import Ar

    if "://" in dep:
        return None
    target = layer.ComputeAbsolutePath(dep)
    outer = Ar.SplitPackageRelativePathOuter(target)[0]
    try:
        mode = os.stat(outer).st_mode
    except (OSError, ValueError):   # missing, a loop, a name too long: Open says it
        return None
    if not stat.S_ISREG(mode):
        raise InspectError(f"USD layer {name} refers to '{dep[:80]}', which is not a file",
                           where=path)
    return None if Ar.IsPackageRelativePath(target) else str(Path(outer).resolve())


def read_usd(path: str | Path, creature: int = 0) -> BakedScene:
    """Read a bake's USD: the skeleton's joints (the `creature`-th Skeleton, in stage order:
    a crowd's creatures), posed by its bound animation at every time code, as world transforms
    (UsdSkel, double precision). No environment."""
    from pxr import Tf, Usd, UsdGeom, UsdSkel

    try:
        stage = open_stage(path)
    except Tf.ErrorException as e:  # a corrupt file (--judge's USD beside the GLB: a traceback)
        reason = " ".join(exception_text(e).split()).rpartition(" : ")[2].strip("'") or "USD error"
        raise InspectError(f"cannot open the USD stage: {reason[:200]}", where=str(path)) \
            from None
    if stage is None:
        raise InspectError(f"{path}: cannot open the USD stage")
    skels = [p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)]
    skel_prim = skels[creature] if 0 <= creature < len(skels) else None
    root_prim = skel_prim.GetParent() if skel_prim is not None else None
    while root_prim is not None and root_prim.IsValid() and not root_prim.IsA(UsdSkel.Root):
        root_prim = root_prim.GetParent()
    if skel_prim is None or root_prim is None or not root_prim.IsValid():
        raise InspectError(f"{path}: no UsdSkel skeleton" + (f" for creature {creature}"
                                                              if creature else ""))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(root_prim), Usd.TraverseInstanceProxies())
    sq = cache.GetSkelQuery(UsdSkel.Skeleton(skel_prim))
    order = [str(j) for j in sq.GetJointOrder()]
    names = tuple(j.rsplit("/", 1)[-1] for j in order)
    index = {j: k for k, j in enumerate(order)}
    parents = np.array([index.get(j.rsplit("/", 1)[0], -1) if "/" in j else -1 for j in order])
    t0, t1 = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    codes = np.arange(int(round(t0)), int(round(t1)) + 1)
    xf = UsdGeom.XformCache()
    mats = np.empty((len(codes), len(order), 4, 4))
    for k, c in enumerate(codes):
        xf.SetTime(Usd.TimeCode(float(c)))
        mats[k] = np.array(sq.ComputeJointWorldTransforms(xf, False))
    m = np.transpose(mats, (0, 1, 3, 2))                       # USD row vectors -> columns
    rot = m[..., :3, :3] / np.linalg.norm(m[..., :3, :3], axis=-2, keepdims=True)
    world_q = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(len(codes), -1, 4)
    pq = np.where(parents[None, :, None] >= 0, world_q[:, np.maximum(parents, 0)], [0, 0, 0, 1])
    local = quat_mul(quat_conj(pq), world_q)
    rest = np.array(sq.GetJointWorldBindTransforms())[:, 3, :3] if len(order) else np.zeros((0, 3))
    rest_t = rest - np.where(parents[:, None] >= 0, rest[np.maximum(parents, 0)], 0.0)
    return BakedScene(names=names, parents=parents, positions=m[..., :3, 3].copy(),
                      rotations=world_q, local=local, rest_translations=rest_t,
                      fps=int(round(stage.GetTimeCodesPerSecond())),
                      env_vertices=np.zeros((0, 3)), env_faces=np.zeros((0, 3), np.int64),
                      extras={})


# ---------------------------------------------------------------- judging


def _angle_steps(q: np.ndarray) -> np.ndarray:
    """(F-1, J) degrees turned between consecutive frames by rotations q (F, J, 4)."""
    dot = np.abs(np.sum(q[1:] * q[:-1], axis=-1)) / (
        np.linalg.norm(q[1:], axis=-1) * np.linalg.norm(q[:-1], axis=-1))
    return np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)))


def _worst(values: np.ndarray, names, largest: bool = True) -> dict:
    """{value, joint, frame} of the largest (or smallest) entry of a (F, K) array whose columns
    are named by `names`."""
    if values.size == 0:
        return {"value": None, "joint": None, "frame": None}
    flat = np.nanargmax(values) if largest else np.nanargmin(values)
    f, k = np.unravel_index(flat, values.shape)
    return {"value": float(values[f, k]), "joint": names[k], "frame": int(f)}


def _legs(names: tuple[str, ...]) -> list[tuple[str, str]]:
    """(side, number) of every walking leg, ordered L_01, R_01, L_02, ..."""
    legs = {(n.split("_")[1], n.split("_")[2]) for n in names
            if n.startswith("leg_") and n.endswith("_upper")}
    return sorted(legs, key=lambda sl: (sl[1], sl[0]))


def _feet(scene: BakedScene, legs) -> tuple[np.ndarray, list[str]]:
    """(F, L, 3) foot points: the `_foot` end joints, or the tip bone's end (its +Y times the
    rig's tip length from the extras) in files without them."""
    names = [f"leg_{s}_{k}_foot" for s, k in legs]
    if all(n in scene.names for n in names):
        return scene.positions[:, [scene.index(n) for n in names]], names
    tip = float(scene.extras["rig"]["legs"]["tip_length"])
    idx = [scene.index(f"leg_{s}_{k}_tip") for s, k in legs]
    y = Rotation.from_quat(scene.rotations[:, idx].reshape(-1, 4)).apply([0.0, tip, 0.0])
    return scene.positions[:, idx] + y.reshape(len(scene.positions), len(idx), 3), names


def _bones(scene: BakedScene, prefixes: tuple[str, ...]) -> list[tuple[int, np.ndarray]]:
    """(joint index, (F, 3) bone vector) of every bone whose joint name starts with one of
    `prefixes`: from the joint to its child joint (or, for a last bone without an end joint,
    along +Y by the rig's length from the extras)."""
    out = []
    kids = {}
    for j, p in enumerate(scene.parents):
        kids.setdefault(int(p), []).append(j)
    for j, n in enumerate(scene.names):
        if not n.startswith(prefixes) or n.endswith(("_foot", "_tip")) and j not in kids:
            continue
        if j in kids:
            c = kids[j][0]
            out.append((j, scene.positions[:, c] - scene.positions[:, j]))
    return out


def judge(scene: BakedScene, usd: BakedScene | None = None,
          sim: dict[str, np.ndarray] | None = None) -> dict:
    """The issue-10 quality numbers of one bake, from its files.

    scene : read_glb() of the bake; usd : read_usd() of the same bake (or None)
    sim   : optional {joint name: (F, 3) float64 world positions} from the simulation itself
    returns {"metrics": {name: value}, "worst": {name: {value, joint, frame}}}
    """
    import trimesh

    from baker.environment.rays import RayCaster
    from baker.metrics import inside_geometry

    names = scene.names
    spine = [scene.index("head")] + sorted(
        (i for i, n in enumerate(names) if n.startswith("trunk_")), key=lambda i: names[i])
    spacing = float(np.mean(np.linalg.norm(scene.rest_translations[spine[1:]], axis=1)))
    bl = spacing * (len(spine) - 1)
    rays = RayCaster(trimesh.Trimesh(scene.env_vertices, scene.env_faces, process=False))
    F = scene.n_frames
    m: dict = {"frames": F, "body_length_m": bl}
    worst: dict = {}
    sp = scene.positions[:, spine]
    sn = [names[i] for i in spine]

    err = np.abs(np.linalg.norm(np.diff(sp, axis=1), axis=2) / spacing - 1.0)
    worst["spacing_error_max"] = _worst(err, sn[1:])
    m["spacing_error_max"] = worst["spacing_error_max"]["value"]

    down = np.tile([0.0, -1.0, 0.0], (F, 1))
    h = rays.first_hit(sp[:, 0], down, max_distance=0.5 * bl)
    slope = np.where(h.hit, np.degrees(np.arccos(np.clip(np.abs(h.normals[:, 1]), 0, 1))), 0.0)
    worst["head_slope_max_deg"] = _worst(slope[:, None], ["head"])
    m["head_slope_max_deg"] = worst["head_slope_max_deg"]["value"]
    m["head_unsupported_frames"] = int(np.count_nonzero(~h.hit))

    inside = inside_geometry(sp.reshape(-1, 3), rays).reshape(F, len(spine))
    m["spine_inside_geometry"] = int(inside.sum())
    worst["spine_inside_geometry"] = _worst(inside.astype(float), sn)
    crossed = _chords_crossing(sp, rays)
    m["spine_bone_hits"] = int(crossed.sum())
    worst["spine_bone_hits"] = _worst(crossed.astype(float), sn[1:])

    _judge_feet(scene, rays, bl, spacing, m, worst)
    _judge_bones(scene, rays, bl, m, worst)

    local = _angle_steps(scene.local)
    world = _angle_steps(scene.rotations)
    both = np.maximum(local, world)
    worst["rotation_max_deg"] = _worst(both, names)
    m["rotation_max_deg"] = worst["rotation_max_deg"]["value"]
    for group, pref in (("spine", ("head", "trunk_")), ("legs", ("leg_",)),
                        ("antennae", ("antenna_",)), ("ultimate", ("ultimate_",)),
                        ("forcipules", ("forcipule_",))):
        cols = [i for i, n in enumerate(names) if n.startswith(pref)]
        if cols:
            m[f"rotation_local_{group}_deg"] = float(local[:, cols].max()) if F > 1 else 0.0
            m[f"rotation_world_{group}_deg"] = float(world[:, cols].max()) if F > 1 else 0.0

    if usd is not None:
        idx = [usd.names.index(n) for n in names]
        n_f = min(F, usd.n_frames)
        d = np.linalg.norm(usd.positions[:n_f, idx] - scene.positions[:n_f], axis=2)
        worst["glb_usd_max_m"] = _worst(d, names)
        m["glb_usd_max_m"] = worst["glb_usd_max_m"]["value"]
        m["usd_frames"] = usd.n_frames
    if sim:
        keys = [n for n in sim if n in names]
        d = np.stack([np.linalg.norm(scene.positions[:, scene.index(n)] - sim[n], axis=1)
                      for n in keys], axis=1)
        worst["sim_max_m"] = _worst(d, keys)
        m["sim_max_m"] = worst["sim_max_m"]["value"]
        # a reduced bake's keys are within its tolerance of the simulation, by design
        m["sim_tolerance_m"] = float((scene.extras.get("animation") or {}).get("tolerance_m", 0.0))
    return {"metrics": m, "worst": worst}


def _judge_feet(scene: BakedScene, rays, bl: float, spacing: float, m: dict, worst: dict) -> None:
    """Skate (contact from the surface distance), penetration and neighbouring-feet distance."""
    from baker.metrics import depth_inside

    legs = _legs(scene.names)
    if not legs:
        return
    feet, fnames = _feet(scene, legs)
    F, L, _ = feet.shape
    flat = feet.reshape(-1, 3)
    dist = rays.closest(flat, CONTACT_BL * bl)[0]
    near = np.isfinite(dist).reshape(F, L)
    pair = near[1:] & near[:-1]
    step = np.linalg.norm(np.diff(feet, axis=0), axis=2) / bl * 100.0
    st = step[pair]
    m["foot_near_ground_fraction"] = float(near.mean())
    m["skate_median_pct_bl"] = float(np.median(st)) if st.size else 0.0
    m["skate_ratio"] = float(np.mean(st > 0.5)) if st.size else 0.0
    m["skate_max_pct_bl"] = float(st.max()) if st.size else 0.0
    worst["skate_ratio"] = _worst(np.where(pair, step, -np.inf), fnames)
    depth = depth_inside(flat, rays, 0.5 * bl).reshape(F, L) / bl * 100.0
    worst["foot_penetration_max_pct_bl"] = _worst(depth, fnames)
    m["foot_penetration_max_pct_bl"] = worst["foot_penetration_max_pct_bl"]["value"]
    by_side = {}
    for k, (s, _) in enumerate(legs):
        by_side.setdefault(s, []).append(k)
    gaps, gnames = [], []
    for s, ks in by_side.items():
        for a, b in zip(ks[:-1], ks[1:]):
            gaps.append(np.linalg.norm(feet[:, a] - feet[:, b], axis=1) / spacing)
            gnames.append(fnames[b])
    if gaps:
        worst["neighbour_feet_min_spacing"] = _worst(np.stack(gaps, 1), gnames, largest=False)
        m["neighbour_feet_min_spacing"] = worst["neighbour_feet_min_spacing"]["value"]


def _chords_crossing(points: np.ndarray, rays) -> np.ndarray:
    """(F, N-1) bool: the chord from each of the (F, N, 3) chain's points to the next crosses
    the environment, cast both ways (a joint inside a block that is not closed, which the
    inside vote can miss, has its chords leave the block through a face)."""
    a = points[:, :-1].reshape(-1, 3)
    v = (points[:, 1:] - points[:, :-1]).reshape(-1, 3)
    reach = np.linalg.norm(v, axis=1)
    hit = rays.occluded(a, v, reach) | rays.occluded(a + v, -v, reach)
    return hit.reshape(len(points), -1)


def _judge_bones(scene: BakedScene, rays, bl: float, m: dict, worst: dict) -> None:
    """Leg bones (walking and ultimate legs) and antenna bones through the environment: a ray
    along each bone, less its last 0.5% BL (a foot resting on the ground does not count)."""
    for key, prefixes in (("leg_bone_hits", ("leg_", "ultimate_")), ("antenna_bone_hits",
                                                                      ("antenna_",))):
        bones = _bones(scene, prefixes)
        if not bones:
            m[key] = 0
            continue
        j = np.array([b[0] for b in bones])
        vec = np.stack([b[1] for b in bones], axis=1)                  # (F, B, 3)
        length = np.linalg.norm(vec, axis=2)
        o = scene.positions[:, j].reshape(-1, 3)
        reach = np.maximum(length.reshape(-1) - 0.005 * bl, 0.0)
        hits = rays.occluded(o, vec.reshape(-1, 3), reach).reshape(len(scene.positions),
                                                                    len(bones))
        m[key] = int(hits.sum())
        worst[key] = _worst(hits.astype(float), [scene.names[i] for i in j])


def judge_creatures(glb_path: str | Path, usd_path: str | Path | None = None,
                    sims: list | None = None) -> list[dict]:
    """judge() of every creature of a bake (one for a lone creature), each read from the GLB
    (its skin) and, when given, the USD (its Skeleton); sims: each creature's `sim` for
    judge() (None: none)."""
    g = GlbFile(glb_bytes(glb_path))
    names = [a.get("name") for a in g.doc.get("animations", [])]
    anim = "bake" if "bake" in names else 0
    out = []
    for i in range(creature_count(g.doc)):
        scene = read_glb(glb_path, anim, glb=g, creature=i)
        usd = read_usd(usd_path, i) if usd_path is not None else None
        if "root_motion" in names and "root" in scene.names:
            # an in-place bake is judged where it walked, the USD's creature moved the same
            fix = root_motion_fix(scene, read_glb(glb_path, "root_motion", glb=g, creature=i))
            scene = moved(scene, fix)
            usd = moved(usd, fix) if usd is not None else None
        out.append(judge(scene, usd, sim=None if sims is None else sims[i]))
    return out


def worst_over(results: list[dict]) -> tuple[dict, dict]:
    """(metrics, worst) over judge() results of several creatures: each number the worst
    creature's (the smallest for a `>=` limit, else the largest), its `worst` entry naming
    the creature; one creature's as they are."""
    if len(results) == 1:
        return results[0]["metrics"], results[0]["worst"]
    m, worst = dict(results[0]["metrics"]), {}
    ops = {name: op for name, op, _ in LIMITS}
    for name in list(m):
        vals = [(r["metrics"].get(name), i) for i, r in enumerate(results)]
        vals = [(v, i) for v, i in vals if isinstance(v, (int, float))]
        if not vals:
            continue
        v, i = (min if ops.get(name) == ">=" else max)(vals)
        m[name] = v
        if name in results[i]["worst"]:
            worst[name] = dict(results[i]["worst"][name], creature=i)
    return m, worst


def _matrices(b: BakedScene, joints=slice(None)) -> np.ndarray:
    """(F, J, 4, 4) the world transforms of joints `joints` (all of them by default)."""
    pos, rot = b.positions[:, joints], b.rotations[:, joints]
    m = np.zeros(pos.shape[:-1] + (4, 4))
    m[..., :3, :3] = Rotation.from_quat(rot.reshape(-1, 4)).as_matrix().reshape(
        pos.shape[:-1] + (3, 3))
    m[..., :3, 3] = pos
    m[..., 3, 3] = 1.0
    return m


def root_motion_fix(baked: BakedScene, motion: BakedScene) -> np.ndarray:
    """(n, 4, 4) the world transforms that put an in-place bake (`--root-motion in-place`)
    back where it walked, frame by frame: the `root_motion` animation's root transform over
    the held root's (n: the frames both have)."""
    n = min(baked.n_frames, motion.n_frames)
    return (_matrices(motion, motion.index("root"))[:n]
            @ np.linalg.inv(_matrices(baked, baked.index("root"))[:n]))


def moved(baked: BakedScene, fix: np.ndarray) -> BakedScene:
    """`baked` with every joint's world transform moved by `fix` (n, 4, 4) (root_motion_fix),
    its first n frames."""
    n = len(fix)
    w = fix[:, None] @ _matrices(baked)[:n]
    q = Rotation.from_matrix(w[..., :3, :3].reshape(-1, 3, 3)).as_quat().reshape(n, -1, 4)
    return replace(baked, positions=w[..., :3, 3].copy(), rotations=q, local=baked.local[:n])


def failures(metrics: dict) -> list[str]:
    """The LIMITS that `metrics` breaks (a metric that is absent or None is not judged)."""
    ops = {"<=": np.less_equal, "<": np.less, ">=": np.greater_equal, "==": np.equal}
    slack = {"sim_max_m": metrics.get("sim_tolerance_m") or 0.0}
    return [name for name, op, bound in LIMITS
            if metrics.get(name) is not None
            and not ops[op](metrics[name], bound + slack.get(name, 0.0))]
