"""Minimal GLB reader for tests: the JSON document and accessors decoded to numpy arrays.

Independent of the writer (plain struct/json/numpy), so tests check the bytes that were written.
"""

from __future__ import annotations

import json
import struct

import numpy as np

_COMP = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
         5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class Glb:
    def __init__(self, data: bytes) -> None:
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        assert magic == b"glTF" and version == 2 and length == len(data)
        jlen, jtype = struct.unpack_from("<I4s", data, 12)
        assert jtype == b"JSON" and jlen % 4 == 0
        self.doc = json.loads(data[20:20 + jlen])
        self.bin = b""
        off = 20 + jlen
        if off < len(data):
            blen, btype = struct.unpack_from("<I4s", data, off)
            assert btype == b"BIN\0" and blen % 4 == 0
            self.bin = data[off + 8: off + 8 + blen]

    def accessor(self, index: int) -> np.ndarray:
        acc = self.doc["accessors"][index]
        view = self.doc["bufferViews"][acc["bufferView"]]
        dt = np.dtype(_COMP[acc["componentType"]])
        width = _WIDTH[acc["type"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        assert "byteStride" not in view
        a = np.frombuffer(self.bin, dtype=dt, count=acc["count"] * width, offset=start)
        return a.reshape(acc["count"], width) if width > 1 else a

    def node_index(self, name: str) -> int:
        return [n.get("name") for n in self.doc["nodes"]].index(name)

    def animation_tracks(self, anim: int = 0) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
        """{(node name, path): (times, values)} for one animation."""
        a = self.doc["animations"][anim]
        out = {}
        for ch in a["channels"]:
            s = a["samplers"][ch["sampler"]]
            name = self.doc["nodes"][ch["target"]["node"]]["name"]
            out[(name, ch["target"]["path"])] = (self.accessor(s["input"]), self.accessor(s["output"]))
        return out

    def world_matrices(self, anim: int | None = 0) -> tuple[list[str], np.ndarray]:
        """Every node's world matrix (column vectors), composed in float64 from the node
        hierarchy (JSON translations are doubles) and, when `anim` is given, that animation's
        keys (LINEAR keys, sampled at the keys themselves).

        returns (node names, (F, N, 4, 4) float64); F = 1 without an animation."""
        from scipy.spatial.transform import Rotation

        nodes = self.doc["nodes"]
        tracks = {}
        n_frames = 1
        if anim is not None:
            a = self.doc["animations"][anim]
            for ch in a["channels"]:
                s = a["samplers"][ch["sampler"]]
                tracks[(ch["target"]["node"], ch["target"]["path"])] = \
                    self.accessor(s["output"]).astype(np.float64)
                n_frames = len(self.accessor(s["input"]))

        def trs(i: int) -> np.ndarray:
            n = nodes[i]
            assert "matrix" not in n
            t = tracks.get((i, "translation"), np.array([n.get("translation", [0.0, 0.0, 0.0])]))
            q = tracks.get((i, "rotation"), np.array([n.get("rotation", [0.0, 0.0, 0.0, 1.0])]))
            s = tracks.get((i, "scale"), np.array([n.get("scale", [1.0, 1.0, 1.0])]))
            m = np.zeros((n_frames, 4, 4))
            r = Rotation.from_quat(np.broadcast_to(q, (n_frames, 4))).as_matrix()
            m[:, :3, :3] = r * np.broadcast_to(s, (n_frames, 3))[:, None, :]
            m[:, :3, 3] = np.broadcast_to(t, (n_frames, 3))
            m[:, 3, 3] = 1.0
            return m

        world = np.zeros((n_frames, len(nodes), 4, 4))
        stack = [(r, np.broadcast_to(np.eye(4), (n_frames, 4, 4)))
                 for r in self.doc["scenes"][self.doc.get("scene", 0)]["nodes"]]
        while stack:
            i, parent = stack.pop()
            world[:, i] = parent @ trs(i)
            stack.extend((c, world[:, i]) for c in nodes[i].get("children", []))
        return [n.get("name") for n in nodes], world
