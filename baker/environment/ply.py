"""Binary PLY files whose list properties vary in length from row to row, and the index lists of
any PLY: faces and triangle strips.

trimesh reads a binary PLY's list property (a face's vertex_indices) as if every row had the
first row's length, and refuses a file whose faces mix sizes ("PLY is unexpected length!"):
Blender's PLY export (binary, polygons as modelled) of a level of triangles and quads. This
reads such a file itself: each element in the header's order, the rows of one without lists in
one go, the rows of one with lists walked row by row for their offsets, then every property
gathered at once.

A `tristrips` element (old Stanford files) holds triangle strips: strip_triangles makes them
triangles. A face or strip list declared with a float type is read only when every index is a
whole number within the vertices (list_indices).
"""

from __future__ import annotations

import numpy as np

from baker.errors import EnvironmentLoadError

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
          "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
          "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
          "float64": "f8"}
_COLOURS = ("red", "green", "blue", "alpha")


def read(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple | None]:
    """(vertices (n, 3) float64, face corner counts (m,), their vertex indices (sum counts,)
    int64, the mean colour of the vertices (else of the faces) as sRGB bytes (r, g, b, a) or
    None) of a binary PLY. The triangles of a `tristrips` element come as faces of 3 corners
    after the face element's."""
    elements, pos, order = _header(data)
    read_ = {}
    for name, count, props in elements:
        read_[name], pos = _element(data, pos, count, props, order)
    if pos != len(data):
        raise EnvironmentLoadError(f"corrupt PLY: its elements take {pos:,} bytes, the file "
                                   f"has {len(data):,}")
    vertex = read_.get("vertex", {})
    if not all(k in vertex for k in "xyz"):
        raise EnvironmentLoadError("PLY has no vertex x, y, z")
    v = np.stack([vertex[k].astype(np.float64) for k in "xyz"], axis=1)
    face = read_.get("face", {})
    counts, flat = _lists(face)
    flat = list_indices("face", counts, flat, len(v))
    strips = _lists(read_.get("tristrips", {}))
    if len(strips[1]):
        tris = strip_triangles(strips[0], list_indices("tristrips", *strips, len(v),
                                                       strips=True))
        counts = np.concatenate([counts, np.full(len(tris), 3, np.int64)])
        flat = np.concatenate([flat, tris.reshape(-1)])
    return v, counts, flat, _colour(vertex) or _colour(face)


def uniform_lists(data: bytes) -> bool:
    """Whether each element of a binary PLY with a list property has one list, of the same
    length in every row (as trimesh reads a binary list: every row as long as the first; a file
    whose rows vary is misread by it, or refused when the sizes do not add up). The rows are
    parsed in order, so a list whose every row, laid out at the first row's size, begins with
    the first row's length is that file's parse: the answer is exact. False also where the
    elements run past the file (read then raises its error)."""
    elements, pos, order = _header(data)
    for _, count, props in elements:
        lists = [k for k, (_, _, kind) in enumerate(props) if kind is not None]
        items = [np.dtype(order + t).itemsize for _, t, _ in props]
        if not lists:
            pos += count * sum(items)
            continue
        if len(lists) > 1:
            return False
        k = lists[0]
        kind = np.dtype(order + props[k][2])
        at = pos + sum(items[:k])                     # the first row's list length
        if count == 0:
            continue
        if at + kind.itemsize > len(data):
            return False
        first = int(np.frombuffer(data, kind, 1, at)[0])
        size = sum(items) - items[k] + kind.itemsize + max(first, 0) * items[k]
        if first < 0 or pos + count * size > len(data):
            return False
        lengths = np.ndarray((count,), kind, data, at, (size,))
        if not (lengths == first).all():
            return False
        pos += count * size
    return True


def _lists(props: dict) -> tuple[np.ndarray, np.ndarray]:
    """(counts (m,) int64, items (sum counts,) as read) of an element's vertex_indices (or
    vertex_index) list; empty when it has none."""
    lists = props.get("vertex_indices", props.get("vertex_index"))
    if isinstance(lists, tuple):
        return lists
    return np.zeros(0, np.int64), np.zeros(0, np.int64)


def list_indices(element: str, counts: np.ndarray, items: np.ndarray, n_vertices: int,
                 strips: bool = False) -> np.ndarray:
    """A face or strip list's vertex indices (`items`, `counts` per row) as int64; refused,
    naming the element and row, when one is not a whole number (a list declared float: 2.5
    was cut to 2) or lies outside the `n_vertices` vertices (a strip's -1 restarts it)."""
    items = np.asarray(items).reshape(-1)
    if items.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(items) | (items != np.trunc(items)))
        if len(bad):
            raise EnvironmentLoadError(
                f"PLY {element} {_row(counts, bad[0])} has vertex index "
                f"{_number(items[bad[0]])}, not a whole number")
    low = -1 if strips else 0
    bad = np.flatnonzero((items < low) | (items >= n_vertices))
    if len(bad):
        raise EnvironmentLoadError(
            f"PLY {element} {_row(counts, bad[0])} has vertex index {_number(items[bad[0]])}, "
            f"outside its {n_vertices:,} vertices" + (" (-1 restarts a strip)" if strips else ""))
    return items.astype(np.int64)


def _number(x) -> str:
    return f"{float(x):.9g}" if np.asarray(x).dtype.kind == "f" else str(int(x))


def _row(counts: np.ndarray, at: int) -> str:
    """'row k' (from 0) of the list item at flat position `at`."""
    return f"row {int(np.searchsorted(np.cumsum(counts), at, side='right'))}"


def strip_triangles(counts: np.ndarray, items: np.ndarray) -> np.ndarray:
    """(T, 3) int64 triangles of triangle strips (a PLY `tristrips` element, Stanford's
    convention): each row one or more strips, a -1 ending one and starting the next; strip
    corners a b c d ... make (a, b, c), (c, b, d), ...: every other triangle is reversed so
    that all are wound as the first. Degenerate triangles (a corner twice: the joins strips
    are stitched with) are left out; the parity counts through them."""
    items = np.asarray(items, dtype=np.int64).reshape(-1)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    n = len(items)
    if n == 0:
        return np.zeros((0, 3), np.int64)
    at = np.arange(n)
    start = np.zeros(n, dtype=bool)                 # where a strip starts: a row, after a -1
    start[(np.cumsum(counts) - counts)[counts > 0]] = True
    start[1:] |= items[:-1] == -1
    pos = at - np.maximum.accumulate(np.where(start, at, 0))     # corner number in its strip
    end = np.flatnonzero((pos >= 2) & (items != -1))            # each triangle's last corner
    a, b, c = items[end - 2], items[end - 1], items[end]
    odd = pos[end] % 2 == 1
    tris = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)
    return tris[(a != b) & (b != c) & (a != c)]


def _header(data: bytes) -> tuple[list, int, str]:
    """([(element, count, [(property, numpy type, list count type or None)])], where the body
    starts, '<' or '>')."""
    end = data.find(b"end_header")
    nl = data.find(b"\n", end)
    if end < 0 or nl < 0:
        raise EnvironmentLoadError("corrupt PLY: no end_header")
    order, elements = None, []
    for line in data[:end].decode("latin-1").splitlines():
        w = line.split()
        if len(w) >= 2 and w[0] == "format":
            order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(w[1])
        elif len(w) >= 3 and w[0] == "element":
            elements.append((w[1], _count(w[2]), []))
        elif len(w) >= 3 and w[0] == "property" and elements:
            if w[1] == "list" and len(w) >= 5:
                if _type(w[2])[0] == "f":     # (trimesh said "'(' was never closed")
                    raise EnvironmentLoadError(f"PLY list {w[4][:20]} has its lengths of type "
                                               f"{w[2][:20]}, not an integer type")
                elements[-1][2].append((w[4], _type(w[3]), _type(w[2])))
            else:
                elements[-1][2].append((w[2], _type(w[1]), None))
    if order is None:
        raise EnvironmentLoadError("PLY is not binary")
    return elements, nl + 1, order


def _count(word: str) -> int:
    try:
        n = int(word)
    except ValueError:
        n = -1
    if n < 0:
        raise EnvironmentLoadError(f"PLY element count '{word[:20]}' is not a count")
    return n


def _type(word: str) -> str:
    if word not in _TYPES:
        raise EnvironmentLoadError(f"PLY property type '{word[:20]}' is not a PLY type")
    return _TYPES[word]


def _element(data: bytes, pos: int, count: int, props: list, order: str) -> tuple[dict, int]:
    """({property: values (count,), or for a list (counts, values)}, where the next element
    starts) of one element's `count` rows from `pos`."""
    if not any(kind for _, _, kind in props):
        dtype = np.dtype([(name, order + t) for name, t, _ in props])
        if pos + count * dtype.itemsize > len(data):
            raise EnvironmentLoadError("corrupt PLY: truncated")
        rows = np.frombuffer(data, dtype, count, pos)
        return {name: rows[name] for name, _, _ in props}, pos + count * dtype.itemsize
    least = sum(np.dtype(t if kind is None else kind).itemsize for _, t, kind in props)
    if count * least > len(data) - pos:                      # before allocating for the rows
        raise EnvironmentLoadError(f"corrupt PLY: {count:,} rows of at least {least} bytes "
                                   f"in {len(data) - pos:,} bytes")
    starts = np.empty((len(props), count), dtype=np.int64)   # each property's offset per row
    lengths = np.zeros((len(props), count), dtype=np.int64)
    sizes = [(np.dtype(t).itemsize, None if kind is None else np.dtype(order + kind))
             for _, t, kind in props]
    for r in range(count):
        for k, (size, kind) in enumerate(sizes):
            if kind is None:
                starts[k, r] = pos
                pos += size
                continue
            if pos + kind.itemsize > len(data):
                raise EnvironmentLoadError("corrupt PLY: truncated")
            n = data[pos] if kind.itemsize == 1 and kind.kind == "u" else int.from_bytes(
                data[pos:pos + kind.itemsize], "little" if order == "<" else "big",
                signed=kind.kind == "i")
            if n < 0:
                raise EnvironmentLoadError(f"corrupt PLY: a list of {n} items")
            starts[k, r], lengths[k, r] = pos + kind.itemsize, n
            pos += kind.itemsize + n * size
    if pos > len(data):
        raise EnvironmentLoadError("corrupt PLY: truncated")
    buf = np.frombuffer(data, np.uint8)
    out = {}
    for k, ((name, t, kind), (size, _)) in enumerate(zip(props, sizes)):
        n = lengths[k] if kind is not None else np.ones(count, np.int64)
        at = np.repeat(starts[k], n) + size * (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))
        values = buf[at[:, None] + np.arange(size)].copy().view(order + t).reshape(-1)
        out[name] = (n, values) if kind is not None else values   # (indices: list_indices)
    return out, pos


def _colour(props: dict) -> tuple | None:
    """The mean of an element's red, green, blue (alpha) as bytes, or None."""
    if not all(c in props and not isinstance(props[c], tuple) for c in _COLOURS[:3]):
        return None
    cols = [props[c].astype(np.float64) for c in _COLOURS if c in props
            and not isinstance(props[c], tuple)]
    if not len(cols[0]):
        return None
    scale = 255.0 if all(props[c].dtype.kind == "f" for c in _COLOURS[:3]) else 1.0
    mean = [float(np.mean(c)) * scale for c in cols]
    return tuple(mean) if len(mean) == 4 else (*mean, 255.0)
