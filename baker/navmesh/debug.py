"""Debug output of a navigation surface: a triangle mesh layer and a top-down PNG map."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baker.navmesh.query import NavSurface


def walkable_mesh(s: NavSurface, lift: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
    """The walkable samples as a triangle mesh: one quad per sample (its cell, on the sample's
    tangent plane), lifted `lift` metres to avoid z-fighting with the environment.

    Returns vertices (4N, 3) float32 metres world, faces (2N, 3) uint32 (counter-clockwise
    seen from above, so normals point up)."""
    n = s.n_samples
    h = 0.5 * s.cell_size
    p = s.positions.astype(np.float64)
    nrm = s.normals.astype(np.float64)
    corners = np.array([(-h, -h), (-h, h), (h, h), (h, -h)])
    v = np.repeat(p[:, None, :], 4, axis=1)
    v[:, :, 0] += corners[:, 0]
    v[:, :, 2] += corners[:, 1]
    v[:, :, 1] -= (nrm[:, None, 0] * corners[:, 0] + nrm[:, None, 2] * corners[:, 1]) / nrm[:, None, 1]
    v[:, :, 1] += lift
    base = (np.arange(n, dtype=np.uint32) * 4)[:, None]
    f = np.concatenate([base + np.array([0, 1, 2], np.uint32), base + np.array([0, 2, 3], np.uint32)],
                       axis=1).reshape(-1, 3)
    return v.reshape(-1, 3).astype(np.float32), f


def draw_map(s: NavSurface, path_png, paths=(), points=(), *, dpi: int = 150,
             title: str | None = None, extent=None, origin=None) -> Path:
    """Draw a top-down map (X right, Z down as seen from above with +Y toward the viewer) of the
    walkable samples coloured by component, with optional paths ((k, 3) arrays or PathResults)
    and points ((3,) or (k, 3)), all in the surface's frame. origin: (3,) metres, world
    position of that frame (Environment.origin; None: zeros): the axes are labelled in world
    coordinates. extent: optional (xmin, xmax, zmin, zmax) zoom window in metres, world.
    Needs matplotlib (optional dependency)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    path_png = Path(path_png)
    nx, nz = s.shape
    img = np.full((nz, nx), np.nan)
    # top layer per column decides the colour
    order = np.argsort(s.positions[:, 1])
    img[s.cells[order, 1], s.cells[order, 0]] = s.component[order] % 20
    ox, oz = (0.0, 0.0) if origin is None else (float(origin[0]), float(origin[2]))
    x0, z0 = s.origin[0] + ox, s.origin[1] + oz
    ext = (x0, x0 + nx * s.cell_size, z0 + nz * s.cell_size, z0)
    fig, ax = plt.subplots(figsize=(8, 8 * nz / max(nx, 1) if nx else 8))
    ax.imshow(img, extent=ext, cmap="tab20", vmin=0, vmax=19, interpolation="nearest")
    for p in paths:
        pts = np.asarray(getattr(p, "points", p), dtype=float).reshape(-1, 3) + [ox, 0.0, oz]
        ax.plot(pts[:, 0], pts[:, 2], "-", color="k", lw=1.2)
        if len(pts):
            ax.plot(pts[0, 0], pts[0, 2], "o", color="g", ms=4)
            ax.plot(pts[-1, 0], pts[-1, 2], "s", color="r", ms=4)
    for q in points:
        q = np.asarray(q, dtype=float).reshape(-1, 3) + [ox, 0.0, oz]
        ax.plot(q[:, 0], q[:, 2], ".", color="m", ms=5)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(title or f"walkable area {s.walkable_area:.2f} m^2, {s.n_components} components")
    ax.set_aspect("equal")
    if extent is not None:
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[3], extent[2])
    path_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path_png, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path_png
