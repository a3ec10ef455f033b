"""`baker inspect FILE`: what a file baker wrote holds, read back from the file alone.

    report = inspect_file(path)            # a plain dict (the `--json` output)
    print(format_report(report))           # the human-readable text

GLB (.glb) and USD (.usd, .usdc, .usda) files give the skeleton (joint count, root joints,
depth, end joints, names by group), the clips (duration, frames, channels and key counts, loop
flag, events), a size breakdown (mesh, animation, environment, overlays, JSON, other: exact
for a GLB, by bufferView; estimated from the raw array sizes for a USD), the validator's
verdict (the Khronos glTF-Validator through node when both are installed, else "not
available"; UsdValidation for USD) and the embedded metadata (glTF scene extras, USD /World
customData). A bake's JSON report (.json) gives its parameters, outputs and metrics.

Anything that is not such a file (missing, empty, truncated, another format, a glTF without a
skin) raises InspectError, one line, which the CLI prints with exit code 2.

A clip loops when its glTF animation's (USD SkelAnimation's) `extras` (`customData`) say
`"loop": true`, or when its name follows the importers' convention (LOOP_RULE).
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np

from baker.errors import exception_text
from baker.inspect import InspectError, glb_extras, open_stage, strict_json

#: file types, by suffix
GLB, USD, REPORT = (".glb",), (".usd", ".usdc", ".usda"), (".json",)
#: the highest frame rate a file may say it has (a GLB's extras fps, a USD's
#: timeCodesPerSecond): beyond it the report's frame counts mean nothing
MAX_FPS = 100_000
#: Godot's importer (and baker's cycles) take a clip as looping when its name, less trailing
#: digits, spaces and underscores, ends with `_loop`/`-loop`/`_cycle`/`-cycle` or contains
#: `$loop`/`$cycle`, in any case (`walk_loop`, `Walk-Cycle`, `walk_loop_2`)
LOOP_RULE = re.compile(r"([_-](loop|cycle)$)|(\$(loop|cycle))", re.IGNORECASE)
_JOINT_PATHS = ("translation", "rotation", "scale")
_COMP_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def loops_by_name(name: str) -> bool:
    """True when importers that look at names (Godot) loop a clip called `name`."""
    return bool(LOOP_RULE.search(re.sub(r"[\d\s_]+$", "", str(name))))


def inspect_file(path: str | Path, validate: bool = True) -> dict:
    """The report of one file baker wrote (see the module docstring). validate: run the
    validator (Khronos for a GLB, UsdValidation for a USD). InspectError when it cannot be read."""
    p = Path(path)
    if not p.exists():
        raise InspectError("file not found", where=str(p))
    if not p.is_file():
        raise InspectError("not a file", where=str(p))
    suffix = p.suffix.lower()
    readers = {**{s: _glb_report for s in GLB}, **{s: _usd_report for s in USD}}
    if suffix in REPORT:
        return _json_report(p)
    if suffix not in readers:
        raise InspectError(f"cannot inspect a '{p.suffix or 'suffix-less'}' file: expected "
                           ".glb, .usd, .usdc, .usda or .json", where=str(p))
    if p.stat().st_size == 0:
        raise InspectError("the file is empty", where=str(p))
    return readers[suffix](p, validate)


def judge_file(path: str | Path) -> list[dict]:
    """The quality limits (inspect.LIMITS) of a GLB baker wrote, judged from its files alone
    (inspect.judge_creatures: the environment is the GLB's; the bake's USD beside it, same name,
    is compared too when there): per creature {creature, failures, values: {limit: value},
    worst: {limit: {value, joint, frame}}}. InspectError for a file that is not a GLB."""
    from baker.inspect import LIMITS, failures, judge_creatures

    p = Path(path)
    if p.suffix.lower() not in GLB:
        raise InspectError("--judge reads a GLB (the environment the creature walked is in it)",
                           where=str(p))
    inspect_file(p, validate=False)          # a file that cannot be read: one line, as inspect
    usd = next((u for u in (p.with_suffix(".usd"), p.with_suffix(".usda")) if u.is_file()), None)
    try:
        judged = judge_creatures(p, usd)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as e:
        # a file inspect reads but whose skin or animation cannot be played (no joints, an
        # fps that is not a number, ...)
        raise InspectError(f"cannot judge this glTF ({type(e).__name__}: {e})",
                           where=str(p)) from None
    out = []
    for i, r in enumerate(judged):
        m = r["metrics"]
        names = [n for n, _, _ in LIMITS if m.get(n) is not None]
        out.append(dict(creature=i, failures=failures(m), values={n: m[n] for n in names},
                        worst={n: r["worst"][n] for n in names if n in r["worst"]}))
    return out


def format_judged(judged: list[dict]) -> str:
    """The text of judge_file's result: a line per limit (its worst creature when there are
    several), then the verdict."""
    from baker.inspect import LIMITS, worst_over

    values, worst = worst_over([{"metrics": j["values"], "worst": j["worst"]} for j in judged])
    lines = ["quality limits, judged from the files:"]
    for name, op, bound in LIMITS:
        if name not in values:
            continue
        value = values[name]
        w = worst.get(name, {}) if value or op != "==" else {}     # none to point at
        where = (f"  {w['joint']} @ frame {w['frame']}" if w.get("joint") else "") + (
            f"  creature {w['creature']}" if "creature" in w else "")
        bad = "  FAILS" if any(name in x["failures"] for x in judged) else ""
        lines.append(f"  {name} {op} {bound:g}: {value:.6g}{where}{bad}")
    failing = [j["creature"] for j in judged if j["failures"]]
    lines.append(f"{len(judged) - len(failing)}/{len(judged)} creature(s) within every limit"
                 + (f"; failing: {', '.join(map(str, failing))}" if failing else ""))
    return "\n".join(lines)


# ---------------------------------------------------------------- skeleton


def skeleton_summary(names: list[str], parents: list[int]) -> dict:
    """Joint count, root joints, depth (joints on the longest chain), end joints (leaves) and
    the joint names grouped by their first word (`trunk_07` -> trunk)."""
    depth = [0] * len(names)
    kids = [0] * len(names)
    for j, p in enumerate(parents):          # parents first, as baker writes them
        depth[j] = depth[p] + 1 if 0 <= p < j else 1
        if 0 <= p:
            kids[p] += 1
    groups: dict[str, int] = {}
    for n in names:
        g = n.split("_")[0]
        groups[g] = groups.get(g, 0) + 1
    return {"joints": len(names), "roots": [n for n, p in zip(names, parents) if p < 0],
            "depth": max(depth, default=0), "end_joints": sum(k == 0 for k in kids),
            "groups": groups}


# ---------------------------------------------------------------- GLB


def _read_glb(path: Path) -> tuple[dict, int, int]:
    """(glTF JSON document, JSON chunk length, BIN chunk length) of a GLB; InspectError on
    anything that is not a whole GLB 2.0 container."""
    where = str(path)
    with open(path, "rb") as f:     # the header and the JSON chunk only: not the whole file
        size = os.fstat(f.fileno()).st_size
        data = f.read(20)
        if len(data) < 20 or data[:4] != b"glTF":
            raise InspectError("not a GLB file (no glTF header)", where=where)
        version, total = struct.unpack_from("<II", data, 4)
        if version != 2:
            raise InspectError(f"GLB version {version}, expected 2", where=where)
        if total != size:
            raise InspectError(f"truncated or padded GLB: the header says {total} bytes, the "
                               f"file has {size}", where=where)
        jlen, jtype = struct.unpack_from("<I4s", data, 12)
        if jtype != b"JSON" or 20 + jlen > size:
            raise InspectError("GLB without a whole JSON chunk", where=where)
        text = f.read(jlen)
        bin_head = f.read(8)
    try:
        doc = strict_json(text)
    except (UnicodeDecodeError, ValueError) as e:
        raise InspectError(f"GLB JSON chunk is not JSON: {e}", where=where) from None
    if not isinstance(doc, dict):
        raise InspectError("GLB JSON chunk is not an object", where=where)
    off = 20 + jlen
    blen = 0
    if len(bin_head) == 8:
        blen, btype = struct.unpack_from("<I4s", bin_head)
        if btype != b"BIN\0" or off + 8 + blen > size:
            raise InspectError("GLB without a whole BIN chunk", where=where)
    return doc, jlen, blen


def _glb_skeleton(doc: dict) -> tuple[dict, list[int]]:
    nodes = doc["nodes"]
    joints = list(doc["skins"][0]["joints"])
    if not joints:
        raise ValueError("skin 0 has no joints")
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    index = {j: k for k, j in enumerate(joints)}
    parents = [index.get(parent.get(j), -1) for j in joints]
    return skeleton_summary([nodes[j].get("name", f"node_{j}") for j in joints], parents), joints


def _accessor_max(doc: dict, i: int) -> float:
    acc = doc["accessors"][i]
    if "max" not in acc:
        raise InspectError(f"animation input accessor {i} has no max")
    return float(acc["max"][0])


def _glb_clips(doc: dict, joints: list[int], fps: int | None) -> list[dict]:
    jset = set(joints)
    clips = []
    for i, a in enumerate(doc.get("animations", [])):
        name = a.get("name", "")
        if not isinstance(name, str):   # (a number's went through to the text report's len())
            raise TypeError(f"animations[{i}].name is {type(name).__name__}, not a string")
        samplers = a["samplers"]
        chans = a["channels"]
        counts = [doc["accessors"][samplers[c["sampler"]]["input"]]["count"] for c in chans]
        duration = max((_accessor_max(doc, samplers[c["sampler"]]["input"]) for c in chans),
                       default=0.0)
        joint_chans = [c for c in chans if c["target"].get("node") in jset]
        by_path = {p: sum(c["target"]["path"] == p for c in joint_chans) for p in _JOINT_PATHS}
        extras = a.get("extras") if isinstance(a.get("extras"), dict) else {}
        clips.append(_clip_entry(
            name, duration, fps, extras, channels=len(chans),
            joint_channels=by_path, node_channels=len(chans) - len(joint_chans),
            keys=counts, n_joints=len(joints)))
    return clips


def _clip_entry(name: str, duration: float, fps: int | None, extras: dict, *, channels: int,
                joint_channels: dict, node_channels: int, keys: list[int],
                n_joints: int) -> dict:
    """One clip's line of the report (shared by GLB and USD); ValueError for a duration that is
    negative or not finite (a clip's last time, or a USD's timeCodesPerSecond, out of range:
    reported as '-2.000 s', 'inf s')."""
    if not (math.isfinite(duration) and duration >= 0):
        raise ValueError(f"clip {name!r} lasts {duration:g} s")
    loop_extra = extras.get("loop") is True
    events = extras.get("events")
    n_events = (len(events) if isinstance(events, list) else
                sum(len(v) for v in events.values() if isinstance(v, list))
                if isinstance(events, dict) else 0)
    return {
        "name": name, "duration_s": duration,
        "frames": int(round(duration * fps)) + 1 if fps else None,
        "channels": channels, "joint_channels": joint_channels,
        # a joint path with no channel keeps the node's rest value (a static channel dropped)
        "static_joint_channels": {p: n_joints - v for p, v in joint_channels.items()},
        "node_channels": node_channels,
        "keys": int(sum(keys)), "keys_per_channel": [int(min(keys, default=0)),
                                                     int(max(keys, default=0))],
        "loop": loop_extra or loops_by_name(name),
        "loop_by": "extras" if loop_extra else "name" if loops_by_name(name) else None,
        "events": n_events,
    }


def _glb_sizes(doc: dict, file_size: int, json_len: int, joints: list[int]) -> dict:
    """Bytes per use, by the bufferViews each use's accessors read: animation (samplers),
    mesh (the skinned creature, its skin, prey), environment (meshes under the Environment
    node), overlays (other static meshes: debug layers), json (the JSON chunk, of which
    `metadata_bytes` are the scene extras), other (headers, padding, unused views)."""
    nodes = doc.get("nodes", [])
    views = doc.get("bufferViews", [])
    accessors = doc.get("accessors", [])
    owner: dict[int, str] = {}

    def claim(acc: int, what: str) -> None:
        v = accessors[acc].get("bufferView")
        if v is not None:
            owner.setdefault(v, what)

    for a in doc.get("animations", []):
        for s in a["samplers"]:
            claim(s["input"], "animation")
            claim(s["output"], "animation")
    for s in doc.get("skins", []):
        if "inverseBindMatrices" in s:
            claim(s["inverseBindMatrices"], "mesh")
    env = _subtree(nodes, [i for i, n in enumerate(nodes) if n.get("name") == "Environment"])
    animated = {c["target"].get("node") for a in doc.get("animations", []) for c in a["channels"]}
    # a mesh node's use: skinned or animated (creature, prey), under Environment, or an overlay
    kind = {}
    for i, n in enumerate(nodes):
        if "mesh" in n:
            kind.setdefault(n["mesh"], "mesh" if "skin" in n or i in animated else
                            "environment" if i in env else "overlays")
    for m, what in sorted(kind.items()):
        for prim in doc["meshes"][m]["primitives"]:
            for acc in list(prim.get("attributes", {}).values()) + [prim.get("indices")]:
                if acc is not None:
                    claim(acc, what)
    sizes = dict.fromkeys(("mesh", "animation", "environment", "overlays", "json", "other"), 0)
    for v, what in owner.items():
        sizes[what] += int(views[v]["byteLength"])
    sizes["json"] = json_len
    sizes["other"] = file_size - sum(sizes.values())
    extras = glb_extras(doc)
    sizes["metadata_bytes"] = len(json.dumps(extras, separators=(",", ":"))) if extras else 0
    return sizes


def _subtree(nodes: list, roots: list[int]) -> set[int]:
    out, stack = set(), list(roots)
    while stack:
        i = stack.pop()
        if i not in out:
            out.add(i)
            stack.extend(nodes[i].get("children", []))
    return out


def _glb_report(path: Path, validate: bool) -> dict:
    doc, jlen, _ = _read_glb(path)
    if not doc.get("skins"):
        raise InspectError("a glTF without a skin: not a baker bake", where=str(path))
    if not doc.get("animations"):       # (was summarized as a bake of no clip)
        raise InspectError("a glTF with a skin but no animation: not a baker bake",
                           where=str(path))
    try:
        extras = glb_extras(doc)
        fps = extras.get("fps")
        fps = fps if isinstance(fps, int) and not isinstance(fps, bool) and 0 < fps <= MAX_FPS \
            else None
        skeleton, joints = _glb_skeleton(doc)
        clips = _glb_clips(doc, joints, fps)
        sizes = _glb_sizes(doc, path.stat().st_size, jlen, joints)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError) as e:
        raise InspectError(f"malformed glTF ({type(e).__name__}: {e})", where=str(path)) from None
    return _with_creatures(
        {"file": str(path), "format": "glb", "bytes": path.stat().st_size,
         "skeleton": skeleton, "clips": clips, "sizes": sizes, "sizes_exact": True,
         "validator": khronos_validate(path) if validate else {"skipped": True},
         "metadata": metadata_summary(extras)}, len(doc["skins"]))


def _with_creatures(report: dict, n: int) -> dict:
    """A crowd's report (`--creatures N`: N skins, or N Skeletons) says how many creatures the
    file holds; the skeleton summarized is the first one's (they are the same rig)."""
    if n > 1:
        report["creatures"] = n
    return report


# ---------------------------------------------------------------- USD


def _open_stage(path: Path):
    """The USD stage, USD's own diagnostics trapped; InspectError when it does not open."""
    from pxr import Tf

    with Tf.DiagnosticTrap() as trap:
        try:
            stage = open_stage(path)
        except InspectError:            # a layer it brings in refused (inspect._check_layers)
            raise
        except Exception as e:          # pxr raises Tf.ErrorException (an Exception subclass)
            raise InspectError(f"cannot open the USD stage: {_pxr_text(e)}",
                               where=str(path)) from None
        finally:
            trap.Clear()
    if stage is None:
        raise InspectError("cannot open the USD stage", where=str(path))
    return stage


def _pxr_text(exc: Exception) -> str:
    """One short line from a pxr exception (its text carries C++ source locations)."""
    text = " ".join(exception_text(exc).split())
    m = re.search(r"in file \S+ : (.*?)(?= Error in '|$)", text)
    return (m.group(1).strip().strip("'") if m else text)[:200] or type(exc).__name__


def _usd_skeleton(stage) -> tuple[dict, object]:
    from pxr import UsdSkel

    skel = next((p for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)), None)
    if skel is None:
        raise InspectError("no UsdSkel Skeleton: not a baker bake",
                           where=str(stage.GetRootLayer().realPath))
    paths = [str(j) for j in (UsdSkel.Skeleton(skel).GetJointsAttr().Get() or [])]
    if not paths:
        raise InspectError(f"the Skeleton {skel.GetPath()} has no joints: not a baker bake",
                           where=str(stage.GetRootLayer().realPath))
    index = {j: k for k, j in enumerate(paths)}
    parents = [index.get(j.rsplit("/", 1)[0], -1) if "/" in j else -1 for j in paths]
    return skeleton_summary([j.rsplit("/", 1)[-1] for j in paths], parents), skel


def _usd_clips(stage, skel, fps: float) -> list[dict]:
    from pxr import UsdSkel

    bound = UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets()
    clips = []
    for p in stage.Traverse():
        if not p.IsA(UsdSkel.Animation):
            continue
        anim = UsdSkel.Animation(p)
        n_joints = len(anim.GetJointsAttr().Get() or [])
        attrs = {"translation": anim.GetTranslationsAttr(), "rotation": anim.GetRotationsAttr(),
                 "scale": anim.GetScalesAttr()}
        samples = {k: a.GetTimeSamples() if a.HasAuthoredValue() else [] for k, a in attrs.items()}
        times = sorted({t for s in samples.values() for t in s})
        duration = (times[-1] - times[0]) / fps if len(times) > 1 else 0.0
        authored = {k: n_joints if (samples[k] or attrs[k].HasAuthoredValue()) else 0
                    for k in attrs}
        keys = [len(s) for s in samples.values() if s for _ in range(n_joints)]
        entry = _clip_entry(p.GetName(), duration, int(round(fps)), _custom_data(p),
                            channels=sum(authored.values()), joint_channels=authored,
                            node_channels=0, keys=keys, n_joints=n_joints)
        entry["prim"] = str(p.GetPath())
        entry["bound"] = p.GetPath() in bound
        entry["samples"] = {k: len(s) for k, s in samples.items()}
        clips.append(entry)
    return clips


def _value_bytes(value) -> int:
    try:
        return int(np.asarray(value).nbytes)
    except (TypeError, ValueError):
        return 8


def _usd_sizes(stage) -> dict:
    """Estimated bytes per use: the raw size of every authored array (once per time sample),
    by prim: SkelAnimations and time-sampled transforms are animation; meshes under
    /World/Environment environment, under /World/Debug overlays, other meshes and the
    Skeleton mesh; the rest other. The file's own encoding (crate compression, text) differs."""
    from pxr import UsdGeom, UsdSkel

    sizes = dict.fromkeys(("mesh", "animation", "environment", "overlays", "other"), 0)
    for p in stage.Traverse():
        path = str(p.GetPath())
        if p.IsA(UsdSkel.Animation):
            what = "animation"
        elif p.IsA(UsdGeom.Mesh) or p.IsA(UsdSkel.Skeleton):
            what = ("environment" if path.startswith("/World/Environment/") else
                    "overlays" if path.startswith("/World/Debug/") else "mesh")
        else:
            what = "other"
        for a in p.GetAttributes():
            if not a.HasAuthoredValue():
                continue
            ts = a.GetTimeSamples()
            if ts:
                sizes["animation"] += len(ts) * _value_bytes(a.Get(ts[0]))
            else:
                sizes[what] += _value_bytes(a.Get())
    return sizes


def _usd_report(path: Path, validate: bool) -> dict:
    stage = _open_stage(path)
    skeleton, skel = _usd_skeleton(stage)
    fps = stage.GetTimeCodesPerSecond()
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):     # (0, nan, inf were tracebacks)
        raise InspectError(f"timeCodesPerSecond = {fps:g}: expected a frame rate in "
                           f"(0, {MAX_FPS}]", where=str(path))
    from pxr import UsdSkel

    try:
        clips = _usd_clips(stage, skel, fps)
    except ValueError as e:
        raise InspectError(f"malformed USD ({e})", where=str(path)) from None
    if not clips:           # (was summarized as a bake of no clip)
        raise InspectError("no UsdSkel SkelAnimation: not a baker bake", where=str(path))
    custom = _custom_data(stage.GetDefaultPrim()) if stage.GetDefaultPrim() else {}
    return _with_creatures(
        {"file": str(path), "format": path.suffix.lower().lstrip("."),
         "bytes": path.stat().st_size, "skeleton": skeleton,
         "clips": clips, "sizes": _usd_sizes(stage),
         "sizes_exact": False,
         "validator": usd_validate(stage) if validate else {"skipped": True},
         "metadata": metadata_summary(custom)},
        sum(1 for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)))


def _custom_data(prim) -> dict:
    """The prim's authored customData, JSON strings parsed back (the schema's own entries,
    such as userDocBrief, left out)."""
    custom = dict(prim.GetCustomData())
    return _usd_plain({k: v for k, v in custom.items() if not k.startswith("userDoc")})


def _usd_plain(custom: dict) -> dict:
    """customData as baker wrote it: JSON strings (lists) parsed back."""
    out = {}
    for k, v in custom.items():
        if isinstance(v, str) and v[:1] in "[{":
            try:        # (strict: a string nested 100,000 deep was a RecursionError traceback)
                v = strict_json(v)
            except ValueError:
                pass
        out[k] = _usd_plain(dict(v)) if hasattr(v, "items") else v
    return out


# ---------------------------------------------------------------- validators


def usd_validate(stage) -> dict:
    """pxr.UsdValidation with every registered validator: counts by severity and the first
    messages."""
    from pxr import UsdValidation

    registry = UsdValidation.ValidationRegistry()
    found = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators()).Validate(stage)
    kinds = UsdValidation.ValidationErrorType
    count = {k: sum(e.GetType() == t for e in found)
             for k, t in (("errors", kinds.Error), ("warnings", kinds.Warn),
                          ("infos", kinds.Info))}
    return {"tool": "UsdValidation", "available": True, **count,
            "messages": [f"{e.GetName()}: {e.GetMessage()}"[:300] for e in found[:10]]}


#: run by node: validate the file with the gltf-validator package at the given folder
_VALIDATE_JS = """
const [pkg, file] = process.argv.slice(1);
const validator = require(pkg);
const bytes = new Uint8Array(require("fs").readFileSync(file));
validator.validateBytes(bytes, {maxIssues: 0, writeTimestamp: false}).then((r) => {
  const m = r.issues.messages.slice(0, 10).map((x) => ({code: x.code, severity: x.severity,
    pointer: x.pointer, message: x.message}));
  process.stdout.write(JSON.stringify({version: r.validatorVersion, errors: r.issues.numErrors,
    warnings: r.issues.numWarnings, infos: r.issues.numInfos, hints: r.issues.numHints,
    messages: m}));
}).catch((e) => { process.stderr.write(String(e && e.message || e)); process.exitCode = 2; });
"""


def find_gltf_validator() -> Path | None:
    """The folder of the `gltf-validator` npm package: $BAKER_GLTF_VALIDATOR (that folder, or
    one holding node_modules/gltf-validator), node_modules/ in the working folder or a parent,
    the test tools of a baker checkout, or npm's global folder; None when there is none."""
    def package(folder: Path) -> Path | None:
        for p in (folder, folder / "node_modules" / "gltf-validator"):
            # (a $BAKER_GLTF_VALIDATOR too long for the file system: is_file's ENAMETOOLONG)
            try:
                if (p / "package.json").is_file() and p.name == "gltf-validator":
                    return p
            except (OSError, ValueError):
                continue
        return None

    env = os.environ.get("BAKER_GLTF_VALIDATOR")
    places = [Path(env)] if env else []
    cwd = Path.cwd().resolve()
    places += [cwd, *cwd.parents]
    places.append(Path(__file__).resolve().parents[1] / "tests" / "tools")
    for folder in places:
        found = package(folder)
        if found:
            return found
    npm = shutil.which("npm")
    if npm:
        try:
            r = subprocess.run([npm, "root", "-g"], capture_output=True, text=True, timeout=30)
            if r.returncode == 0 and r.stdout.strip():
                return package(Path(r.stdout.strip()) / "gltf-validator")
        except (OSError, subprocess.SubprocessError):
            return None
    return None


def khronos_validate(path: Path) -> dict:
    """The Khronos glTF-Validator's verdict on a GLB, run by node on the installed npm package
    (`npm install -g gltf-validator`, or $BAKER_GLTF_VALIDATOR); {"available": False, "reason"}
    when node or the package is missing or the run fails."""
    tool = "Khronos glTF-Validator"
    node = shutil.which("node")
    if node is None:
        return {"tool": tool, "available": False, "reason": "node is not on PATH"}
    pkg = find_gltf_validator()
    if pkg is None:
        return {"tool": tool, "available": False,
                "reason": "the gltf-validator npm package is not installed "
                          "(npm install -g gltf-validator, or set BAKER_GLTF_VALIDATOR)"}
    try:
        r = subprocess.run([node, "-e", _VALIDATE_JS, str(pkg), str(Path(path).resolve())],
                           capture_output=True, text=True, timeout=600,
                           env={**os.environ, "NODE_NO_WARNINGS": "1"})
        out = json.loads(r.stdout) if r.returncode == 0 else None
    except (OSError, subprocess.SubprocessError, ValueError):
        out = None
    if not isinstance(out, dict):
        return {"tool": tool, "available": False, "reason": "the validator did not run"}
    return {"tool": f"{tool} {out.pop('version', '')}".strip(), "available": True, **out}


# ---------------------------------------------------------------- metadata and reports


def _scalars(d: dict, prefix: str = "") -> dict:
    """The numbers, strings and booleans of a nested dict, flattened to dotted keys."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_scalars(v, f"{prefix}{k}."))
        elif v is None or isinstance(v, (bool, int, float, str)):
            out[f"{prefix}{k}"] = v
    return out


def report_json(report: dict) -> str:
    """`baker inspect --json`'s text: strict JSON, a non-finite number (a USD's customData may
    hold NaN; json.dumps refused it, a traceback) written as a string, "nan" or "inf"."""
    return json.dumps(_finite(report), indent=2, allow_nan=False, default=str)


def _finite(v):
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    return v


def _seconds(v) -> float | None:
    """A timeline event's time: a finite number (missing: 0), else None (a file edited by
    hand or by another tool: 'x' for a start raised ValueError, a traceback)."""
    if v is None:
        return 0.0
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def metadata_summary(extras: dict) -> dict:
    """The embedded metadata in short: generator, seed, fps, seconds, the rig's name, the
    timeline (events, seconds per state), foot contacts (feet, planted intervals), and every
    other key's scalars (quality metrics, reduction figures, ...)."""
    if not extras:
        return {}
    out = {k: extras[k] for k in ("generator", "seed", "fps", "seconds") if k in extras}
    rig = extras.get("rig")
    if isinstance(rig, dict):
        out["rig"] = rig.get("name")
    elif rig is not None:
        out["rig"] = rig
    tl = extras.get("timeline")
    if isinstance(tl, list):
        states: dict[str, float] = {}
        for e in tl:
            if isinstance(e, dict) and isinstance(e.get("state"), str):
                start, end = _seconds(e.get("start")), _seconds(e.get("end"))
                d = end - start if start is not None and end is not None else 0.0
                states[e["state"]] = round(states.get(e["state"], 0.0) + d, 6)
        out["timeline"] = {"events": len(tl), "state_seconds": states}
    fc = extras.get("foot_contacts")
    if isinstance(fc, dict):
        out["foot_contacts"] = {"feet": len(fc), "intervals": sum(
            len(v) for v in fc.values() if isinstance(v, list))}
    known = {"generator", "seed", "fps", "seconds", "rig", "timeline", "foot_contacts"}
    for k, v in extras.items():
        if k in known:
            continue
        out[k] = _scalars(v) if isinstance(v, dict) else (
            v if v is None or isinstance(v, (bool, int, float, str)) else
            f"{type(v).__name__} of {len(v)}" if hasattr(v, "__len__") else str(v))
    return out


#: the largest report JSON read (a 1000-creature bake's is tens of MB)
MAX_REPORT_BYTES = 1 << 30


def _json_report(path: Path) -> dict:
    if path.stat().st_size > MAX_REPORT_BYTES:
        raise InspectError(f"not a baker report: {path.stat().st_size:,} bytes, over the "
                           f"{MAX_REPORT_BYTES >> 20:,} MB a report can be", where=str(path))
    try:
        doc = strict_json(path.read_bytes())
    except (UnicodeDecodeError, ValueError) as e:
        raise InspectError(f"not JSON: {e}", where=str(path)) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("metrics"), dict) \
            or not isinstance(doc.get("parameters"), dict):
        raise InspectError("not a baker report (no parameters and metrics)", where=str(path))
    for key in ("outputs", "timings_s"):   # (a number's went through to the text's .items())
        if not isinstance(doc.get(key, {}), dict):
            raise InspectError(f"not a baker report: its {key} is not an object", where=str(path))
    prm = doc["parameters"]
    rig = prm.get("rig")
    return {"file": str(path), "format": "json", "bytes": path.stat().st_size,
            "report": {"baker_version": doc.get("baker_version"), "seed": doc.get("seed"),
                       "environment": prm.get("environment"), "seconds": prm.get("seconds"),
                       "fps": prm.get("fps"), "formats": prm.get("formats"),
                       "rig": rig.get("name") if isinstance(rig, dict) else rig,
                       "outputs": doc.get("outputs", {}),
                       "timings_s": doc.get("timings_s", {})},
            "metrics": _scalars(doc["metrics"]),
            "metadata": metadata_summary({"timeline": doc.get("timeline")}
                                         if isinstance(doc.get("timeline"), list) else {})}


# ---------------------------------------------------------------- text


def _mb(n: int) -> str:
    return (f"{n / 1e6:.2f} MB" if n >= 1e5 else f"{n / 1e3:.1f} kB" if n >= 1000 else
            f"{n} B")


def _num(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}" if math.isfinite(v) else str(v)
    return str(v)


def format_report(r: dict) -> str:
    """The human-readable text of an inspect_file report."""
    lines = [f"{r['file']}: {r['format'].upper()}, {_mb(r['bytes'])}"]
    if r["format"] == "json":
        return "\n".join(lines + _format_json(r))
    sk = r["skeleton"]
    lines.append(f"skeleton: {sk['joints']} joints, root {', '.join(sk['roots'])}, depth "
                 f"{sk['depth']}, {sk['end_joints']} end joints")
    lines.append("  " + ", ".join(f"{g} {n}" for g, n in sk["groups"].items()))
    if r.get("creatures"):
        lines.append(f"creatures: {r['creatures']} (a skeleton each, as above)")
    lines.append(f"clips: {len(r['clips'])}")
    width = max((len(c["name"]) for c in r["clips"]), default=0)
    for c in r["clips"]:
        trs = "/".join(str(c["joint_channels"][k]) for k in ("translation", "rotation", "scale"))
        kmin, kmax = c["keys_per_channel"]
        frames = f"{c['frames']} frames" if c["frames"] is not None else "? frames"
        lines.append(
            f"  {c['name']:<{width}}  {c['duration_s']:.3f} s  {frames}  {c['channels']} "
            f"channels (joints keyed T/R/S {trs}"
            + (f", {c['node_channels']} node" if c["node_channels"] else "")
            + f")  {c['keys']} keys ({kmin}-{kmax} per channel)  loop: "
            f"{'yes (' + c['loop_by'] + ')' if c['loop'] else 'no'}"
            + (f"  events: {c['events']}" if c["events"] else "")
            + ("  [bound]" if c.get("bound") else ""))
    s = r["sizes"]
    parts = [f"{k} {_mb(v)}" for k, v in s.items() if k != "metadata_bytes" and v]
    lines.append(f"size{'' if r['sizes_exact'] else ' (estimated raw arrays)'}: "
                 + ", ".join(parts)
                 + (f" (metadata {_mb(s['metadata_bytes'])})" if s.get("metadata_bytes") else ""))
    lines.append("validator: " + _format_validator(r["validator"]))
    lines.append("metadata: " + _format_metadata(r["metadata"]))
    return "\n".join(lines)


def _format_validator(v: dict) -> str:
    if v.get("skipped"):
        return "skipped"
    if not v.get("available"):
        return f"{v['tool']} not available: {v['reason']}"
    counts = ", ".join(f"{v[k]} {k}" for k in ("errors", "warnings", "infos", "hints") if k in v)
    first = [m if isinstance(m, str) else f"{m['code']} {m.get('pointer', '')}"
             for m in v.get("messages", [])[:3]]
    return f"{v['tool']}: {counts}" + (f" (first: {'; '.join(first)})" if first else "")


def _format_metadata(m: dict) -> str:
    if not m:
        return "none"
    out = []
    for k, v in m.items():
        if k == "timeline":
            states = ", ".join(f"{s} {_num(t)} s" for s, t in v["state_seconds"].items())
            out.append(f"timeline {v['events']} events ({states})")
        elif k == "foot_contacts":
            out.append(f"foot contacts {v['feet']} feet, {v['intervals']} planted intervals")
        elif isinstance(v, dict):
            out.append(f"{k} {{" + ", ".join(f"{a} {_num(b)}" for a, b in v.items()) + "}")
        else:
            out.append(f"{k} {_num(v)}")
    return "; ".join(out)


def _format_json(r: dict) -> list[str]:
    rep = r["report"]
    lines = [f"bake: baker {rep['baker_version']}, seed {rep['seed']}, {_num(rep['seconds'])} s at "
             f"{rep['fps']} fps, rig {rep['rig']}, environment {rep['environment']}"]
    lines.append("outputs: " + ", ".join(f"{k} {v}" for k, v in rep["outputs"].items()))
    if rep["timings_s"]:
        lines.append("timings: " + ", ".join(f"{k} {_num(v)} s" for k, v in rep["timings_s"].items()))
    if r["metadata"]:
        lines.append("metadata: " + _format_metadata(r["metadata"]))
    lines.append("metrics:")
    groups: dict[str, list[str]] = {}
    for k, v in r["metrics"].items():
        g, _, name = k.rpartition(".")
        groups.setdefault(g, []).append(f"{name} {_num(v)}")
    for g, items in groups.items():
        lines.append(f"  {g or 'bake'}: " + ", ".join(items))
    return lines
