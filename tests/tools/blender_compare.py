"""Compare the triangles baker loaded from a level with a reference set of world triangles (both
(n, 3, 3) float64, metres, +Y up): the same surface, facing the same way.

    python tests/tools/blender_compare.py OUT_DIR [NAME ...]

prints one line per export of OUT_DIR/manifest.json (written by blender_levels.py, run by a
Python with bpy): its numbers and the checks it fails.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def env_triangles(env) -> np.ndarray:
    """An Environment's world triangles, (n, 3, 3) float64."""
    return np.concatenate([(m.vertices.astype(np.float64) + env.origin)[m.faces.astype(np.int64)]
                           for m in env.meshes])


def _area_normals(t: np.ndarray) -> np.ndarray:
    return 0.5 * np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def _samples(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points on every triangle (centroid and three points near the corners) and the index of
    the triangle each lies on."""
    w = np.array([[1 / 3, 1 / 3, 1 / 3], [0.8, 0.1, 0.1], [0.1, 0.8, 0.1], [0.1, 0.1, 0.8]])
    p = np.einsum("kj,njc->nkc", w, t).reshape(-1, 3)
    return p, np.repeat(np.arange(len(t)), len(w))


def _one_way(src: np.ndarray, dst: np.ndarray, tol: float, src_either=None, dst_either=None
             ) -> tuple[float, int]:
    """(largest distance from a sample point of src to the surface dst, how many of src's
    points lie on dst only where dst faces the other way). The triangles of src_either and
    dst_either (bool masks) may face either way."""
    keep = np.linalg.norm(_area_normals(src), axis=1) > 1e-12
    src = src[keep]
    src_either = np.zeros(len(src), bool) if src_either is None else src_either[keep]
    dst_either = np.zeros(len(dst), bool) if dst_either is None else dst_either
    p, owner = _samples(src)
    nsrc, ndst = _area_normals(src), _area_normals(dst)
    nsrc /= np.linalg.norm(nsrc, axis=1, keepdims=True)
    ndst /= np.maximum(np.linalg.norm(ndst, axis=1, keepdims=True), 1e-300)
    worst, flipped = 0.0, 0
    for s in range(0, len(p), 128):
        d = _pair_distance(p[s:s + 128], dst)
        worst = max(worst, float(d.min(1).max()))
        near = d <= tol
        same = ((nsrc[owner[s:s + 128]] @ ndst.T) > 0.99) | dst_either[None]
        same |= src_either[owner[s:s + 128]][:, None]
        flipped += int(np.sum(near.any(1) & ~(near & same).any(1)))
    return worst, flipped


def _pair_distance(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(m, n) distance from every point to every triangle."""
    a, b, c = (t[None, :, i] for i in range(3))
    q = p[:, None]
    ab, ac, ap = b - a, c - a, q - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp, cp = q - b, q - c
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        r = a + ab * (vb / den)[..., None] + ac * (vc / den)[..., None]
        for cond, pt in (
                ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
                 b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[..., None]),
                ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * (d2 / (d2 - d6))[..., None]),
                ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * (d1 / (d1 - d3))[..., None]),
                ((d6 >= 0) & (d5 <= d6), c), ((d3 >= 0) & (d4 <= d3), b),
                ((d1 <= 0) & (d2 <= 0), a)):
            r = np.where(cond[..., None], pt, r)
    d = np.linalg.norm(q - r, axis=-1)
    return np.where(np.isfinite(d), d, np.inf)


def compare(got: np.ndarray, want: np.ndarray, rel_tol: float = 1e-5, either=None) -> dict:
    """Numbers and failed checks of got against want (world triangles): total area, per-axis
    bounds, the set of distinct vertices, the largest point-to-surface distance each way, and
    the sample points lying on the other surface only where it faces the other way (but for
    want's triangles of the mask `either`, which may face either way)."""
    size = float(np.ptp(want.reshape(-1, 3), axis=0).max())
    tol = rel_tol * size
    area_got = float(np.linalg.norm(_area_normals(got), axis=1).sum())
    area_want = float(np.linalg.norm(_area_normals(want), axis=1).sum())
    lo = np.abs(got.reshape(-1, 3).min(0) - want.reshape(-1, 3).min(0)).max()
    hi = np.abs(got.reshape(-1, 3).max(0) - want.reshape(-1, 3).max(0)).max()
    key = lambda t: {tuple(x) for x in np.round(t.reshape(-1, 3) / tol).astype(np.int64)}  # noqa
    vg, vw = key(got), key(want)
    # (rounding may put one point either side of a cell boundary: count only points with no
    # neighbour cell in the other set)
    near = lambda s, o: sum(1 for x in s if not any(                                      # noqa
        (x[0] + i, x[1] + j, x[2] + k) in o for i in (-1, 0, 1) for j in (-1, 0, 1)
        for k in (-1, 0, 1)))
    d_gw, flip_gw = _one_way(got, want, tol, dst_either=either)
    d_wg, flip_wg = _one_way(want, got, tol, src_either=either)
    r = dict(size=size, triangles=(len(got), len(want)), area=(area_got, area_want),
             bounds=float(max(lo, hi)), extra_vertices=near(vg, vw), missing_vertices=near(vw, vg),
             got_to_want=d_gw, want_to_got=d_wg, flipped=(flip_gw, flip_wg))
    fails = []
    if abs(area_got - area_want) > rel_tol * area_want:
        fails.append(f"area {area_got:.6f} != {area_want:.6f} m2")
    if r["bounds"] > tol:
        fails.append(f"bounds off by {r['bounds']:.6g} m")
    if r["extra_vertices"] or r["missing_vertices"]:
        fails.append(f"vertices: {r['extra_vertices']} extra, {r['missing_vertices']} missing")
    if d_gw > tol or d_wg > tol:
        fails.append(f"surface distance {d_gw:.6g} m (loaded to Blender's), {d_wg:.6g} m back")
    if flip_gw or flip_wg:
        fails.append(f"facing the other way: {flip_gw} loaded points, {flip_wg} of Blender's")
    r["fails"] = fails
    return r


def check_entry(out: Path, e: dict, env) -> dict:
    """compare() of a loaded manifest entry with its reference, and its sun (a manifest's
    `sun` is the direction toward the sun the file holds, or None)."""
    want = np.load(out / f"ref_{e['ref']}.npy")
    either = np.load(out / f"mirrored_{e['ref']}.npy") if e["mirrored_as_is"] else None
    r = compare(env_triangles(env), want, either=either)
    if e["sun"] is not None:
        off = float(np.degrees(np.arccos(np.clip(np.dot(env.sun.direction, e["sun"]), -1, 1))))
        r["sun_deg"] = off
        if off > 0.01:
            r["fails"].append(f"sun {off:.3f} deg off ({np.round(env.sun.direction, 4)} "
                              f"!= {np.round(e['sun'], 4)})")
    return r


def main(argv: list[str]) -> int:
    from baker.environment import load_environment

    out = Path(argv[0])
    manifest = json.loads((out / "manifest.json").read_text())
    bad = 0
    for e in manifest:
        if argv[1:] and e["name"] not in argv[1:]:
            continue
        want = np.load(out / f"ref_{e['ref']}.npy")
        try:
            env = load_environment(out / e["file"], up_axis=e["up"], units=e["units"])
        except Exception as exc:    # noqa: BLE001 (reported per file)
            print(f"{e['name']:22s} LOAD ERROR {exc}")
            bad += 1
            continue
        r = check_entry(out, e, env)
        bad += bool(r["fails"])
        print(f"{e['name']:22s} tris {r['triangles'][0]:4d}/{r['triangles'][1]:4d} "
              f"area {r['area'][0]:9.4f}/{r['area'][1]:9.4f} "
              f"d {r['got_to_want']:.2g}/{r['want_to_got']:.2g} flip {r['flipped']} "
              f"{'; '.join(r['fails']) or 'ok'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
