"""The top-down map of a bake (matplotlib, Agg): the walkable area, shade at the start and at
the end, the head's trail coloured by behaviour, foot contacts, prey paths, the contact sheet's
frames, and the behaviour timeline as a strip under the map. The level is seen cut a body
length above the trail (section_heights): a roof, an upper storey or a canopy over the floor
walked does not hide it, and the solids cut show as not walkable.

Seen from above: x to the right, z down (+Y toward the viewer), in world metres.
"""

from __future__ import annotations

import io

import numpy as np

from baker.environment.rays import RayCaster
from baker.export.preview_scene import PreviewScene
from baker.export.render import SHADOW_BIAS_BL

#: map cells along the longer side of the window
MAP_CELLS = 480
#: the map shows the level cut this many body lengths above the head's nearest trail point
SECTION_BL = 1.0
#: trail colours of the brain's states (baker.behaviour.brain.STATES); others cycle OTHERS
STATE_COLORS = {"wander": "#1f77b4", "seek_shade": "#17becf", "rest_in_shade": "#2ca02c",
                "cobra": "#9467bd", "hunt": "#d62728", "strike": "#ff7f0e", "feed": "#8c564b",
                "warning": "#e377c2"}
OTHERS = ("#7f7f7f", "#bcbd22", "#393b79", "#637939", "#843c39", "#7b4173")
#: ground categories: walkable in sun, shade at start and end, start only, end only; not walkable
GROUND = {"sun": (0.93, 0.89, 0.78), "shade": (0.55, 0.60, 0.71),
          "start": (0.72, 0.81, 0.93), "end": (0.86, 0.76, 0.89), "blocked": (0.60, 0.60, 0.58)}


def state_color(name: str, states) -> str:
    """Matplotlib colour of a behaviour state (fixed for the brain's states)."""
    if name in STATE_COLORS:
        return STATE_COLORS[name]
    extra = [s for s in states if s not in STATE_COLORS]
    return OTHERS[extra.index(name) % len(OTHERS)] if name in extra else OTHERS[0]


def map_window(scene: PreviewScene) -> tuple[float, float, float, float]:
    """(x0, x1, z0, z1) world metres: the trail and the prey paths with a margin, within the
    environment's bounds."""
    pts = [scene.baked.positions[:, scene.baked.index("head")][:, [0, 2]]]
    pts += [p.world[:, [0, 2], 3] for p in scene.prey]
    p = np.concatenate(pts)
    lo, hi = p.min(axis=0), p.max(axis=0)
    span = max(float((hi - lo).max()), 8.0 * scene.body_length)
    centre = (lo + hi) / 2.0
    half = 0.5 * span + max(0.12 * span, 2.0 * scene.body_length)
    elo = scene.env.vertices[:, [0, 2]].min(axis=0)
    ehi = scene.env.vertices[:, [0, 2]].max(axis=0)
    lo = np.maximum(centre - half, elo)
    hi = np.minimum(centre + half, ehi)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def ground_grid(scene: PreviewScene, env: RayCaster, window) -> dict:
    """Down rays over the window's cell centres (rows along z, columns along x).

    returns {"hit", "walkable", "shade_start", "shade_end": (nz, nx) bool,
             "relief": (nz, nx) float in [0, 1] (a hill shade), "cell": metres}"""
    x0, x1, z0, z1 = window
    cell = max(x1 - x0, z1 - z0) / MAP_CELLS
    nx, nz = max(int(np.ceil((x1 - x0) / cell)), 1), max(int(np.ceil((z1 - z0) / cell)), 1)
    gx, gz = np.meshgrid(x0 + (np.arange(nx) + 0.5) * cell, z0 + (np.arange(nz) + 0.5) * cell)
    top = float(scene.env.vertices[:, 1].max()) + 1.0
    cut = np.minimum(section_heights(scene, gx.ravel(), gz.ravel()), top)
    o = np.stack([gx.ravel(), cut, gz.ravel()], axis=1)
    d = np.tile([0.0, -1.0, 0.0], (len(o), 1))
    t, prim, uv = env.cast_uv(o, d)
    hit = prim >= 0
    # a cut through a solid (a wall, a stone) meets its underside from within first: the
    # solid's footprint, not ground
    solid = hit & (cut < top) & (env.face_normals[np.maximum(prim, 0), 1] < 0.0)
    p = o + np.where(hit, t, 0.0)[:, None] * d
    f = env.faces[np.maximum(prim, 0)]
    bary = np.column_stack([1.0 - uv[:, 0] - uv[:, 1], uv])
    n = np.einsum("kj,kjc->kc", bary, scene.env.normals[f])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    n[n[:, 1] < 0] *= -1.0
    ng = env.face_normals[np.maximum(prim, 0)] * np.where(
        env.face_normals[np.maximum(prim, 0), 1:2] < 0, -1.0, 1.0)
    walk = _walkable(scene, p, n, hit) & ~solid
    eps = SHADOW_BIAS_BL * scene.body_length
    shade = []
    for sun in (scene.sun[0], scene.sun[-1]):
        s = np.zeros(len(o), bool)
        s[hit] = env.cast(p[hit] + ng[hit] * eps, np.broadcast_to(sun, (int(hit.sum()), 3)))[1] >= 0
        s |= hit & (n @ sun <= 0)
        shade.append(s)
    light = np.array([-0.5, 0.75, -0.45]) / np.linalg.norm([-0.5, 0.75, -0.45])
    relief = np.clip(n @ light, 0.0, 1.0)
    shape = (nz, nx)
    return {"hit": hit.reshape(shape), "walkable": walk.reshape(shape),
            "shade_start": shade[0].reshape(shape), "shade_end": shade[1].reshape(shape),
            "relief": relief.reshape(shape), "cell": cell}


def section_heights(scene: PreviewScene, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(n,) the height [m] the map cuts the level at over points (x, z) (n,) each: SECTION_BL
    body lengths above the head's trail where it passed nearest, so a roof, an upper storey or
    a canopy over the walked floor does not hide it."""
    from scipy.spatial import cKDTree

    head = scene.baked.positions[:, scene.baked.index("head")]
    _, i = cKDTree(head[:, [0, 2]]).query(np.column_stack([x, z]))
    return head[i, 1] + SECTION_BL * scene.body_length


def _walkable(scene: PreviewScene, p, n, hit) -> np.ndarray:
    """(k,) bool per down ray hitting p (k, 3) with normal n (k, 3): the top sample of the
    file's navmesh layer in that navmesh cell is within a fifth of a body length of p, or
    (without the layer) the slope is within the rig's max_slope (60 degrees unless the extras
    say otherwise)."""
    if scene.navmesh is not None and scene.navmesh_cell > 0:
        # the navmesh cell under each ray, by its integer grid coordinates
        s, nc = scene.navmesh, scene.navmesh_cell
        ref = s[0, [0, 2]]

        def keys(xz):
            k = np.round((xz - ref) / nc).astype(np.int64)
            return (k[:, 0] << 32) + (k[:, 1] & 0xFFFFFFFF)

        order = np.lexsort((s[:, 1], keys(s[:, [0, 2]])))
        k_s = keys(s[order][:, [0, 2]])
        last = np.r_[k_s[1:] != k_s[:-1], True]             # the top sample of each cell
        k_top, y_top = k_s[last], s[order][last, 1]
        k_p = keys(p[:, [0, 2]])
        i = np.clip(np.searchsorted(k_top, k_p), 0, len(k_top) - 1)
        return hit & (k_top[i] == k_p) & (y_top[i] >= p[:, 1] - 0.2 * scene.body_length)
    nav = ((scene.baked.extras.get("rig") or {}).get("navigation") or {})
    slope = float(nav.get("max_slope", np.radians(60.0)))
    return hit & (n[:, 1] >= np.cos(slope))


def ground_image(g: dict) -> np.ndarray:
    """(nz, nx, 3) float RGB of the ground categories (GROUND) times the hill shade."""
    walk, a, b = g["walkable"], g["shade_start"], g["shade_end"]
    img = np.ones(walk.shape + (3,))
    for key, mask in (("blocked", g["hit"] & ~walk), ("sun", walk & ~a & ~b),
                      ("shade", walk & a & b), ("start", walk & a & ~b), ("end", walk & ~a & b)):
        img[mask] = GROUND[key]
    shade = 0.72 + 0.28 * g["relief"]
    return np.where(g["hit"][..., None], img * shade[..., None], 1.0)


def _sun_text(scene: PreviewScene) -> str:
    def az_el(d):
        return (np.degrees(np.arctan2(d[0], d[2])) % 360.0,
                np.degrees(np.arcsin(np.clip(d[1], -1.0, 1.0))))

    (a0, e0), (a1, e1) = az_el(scene.sun[0]), az_el(scene.sun[-1])
    if np.allclose(scene.sun[0], scene.sun[-1], atol=1e-6):
        return f"sun az {a0:.0f}\N{DEGREE SIGN} el {e0:.0f}\N{DEGREE SIGN}"
    return (f"sun az {a0:.0f}\N{DEGREE SIGN} el {e0:.0f}\N{DEGREE SIGN} \N{RIGHTWARDS ARROW} "
            f"az {a1:.0f}\N{DEGREE SIGN} el {e1:.0f}\N{DEGREE SIGN}")


def draw_map(scene: PreviewScene, env: RayCaster, sheet_frames=(), dpi: int = 100) -> bytes:
    """The map as PNG bytes (same scene, same bytes). sheet_frames: frames of the contact
    sheet, numbered on the trail and on the timeline strip."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    window = map_window(scene)
    g = ground_grid(scene, env, window)
    x0, x1, z0, z1 = window
    nz, nx = g["hit"].shape
    aspect = (nz / nx) if nx else 1.0
    fig = Figure(figsize=(9.6, 7.2 * min(max(aspect, 0.5), 1.6) + 1.3), dpi=dpi)
    gs = fig.add_gridspec(2, 1, height_ratios=[7.2 * min(max(aspect, 0.5), 1.6), 0.55],
                          hspace=0.28, left=0.07, right=0.74, top=0.93, bottom=0.07)
    ax, strip = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    ax.imshow(ground_image(g), extent=(x0, x0 + nx * g["cell"], z0 + nz * g["cell"], z0),
              interpolation="nearest")
    handles = _draw_paths(ax, scene, sheet_frames)
    ax.set_xlim(x0, x1)
    ax.set_ylim(z1, z0)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    walked = float(np.linalg.norm(np.diff(scene.baked.positions[:, scene.baked.index("head")],
                                          axis=0), axis=1).sum())
    seed = scene.baked.extras.get("seed")
    ax.set_title(f"{scene.name}: {scene.seconds:g} s, head walked {walked:.1f} m"
                 + (f", seed {seed}" if seed is not None else "") + f"\n{_sun_text(scene)}",
                 fontsize=10)
    handles += _ground_legend(g)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False)
    _draw_strip(strip, scene, sheet_frames)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return buf.getvalue()


def _draw_paths(ax, scene: PreviewScene, sheet_frames) -> list:
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    head = scene.baked.positions[:, scene.baked.index("head")][:, [0, 2]]
    handles = []
    if scene.contacts:
        feet = [scene.baked.positions[np.minimum(iv[:, 0], scene.n_frames - 1), j][:, [0, 2]]
                for j, iv in sorted(scene.contacts.items())]
        pts = np.concatenate(feet)
        ax.scatter(pts[:, 0], pts[:, 1], s=0.6, c="#3a3a3a", alpha=0.45, linewidths=0,
                   rasterized=True)
        handles.append(Line2D([], [], ls="", marker=".", color="#3a3a3a",
                              label=f"foot contacts ({len(pts)})"))
    for p in scene.prey:
        seen = np.abs(np.linalg.det(p.world[:, :3, :3])) > 1e-12
        xy = p.world[seen][:, [0, 2], 3]
        if len(xy):
            ax.plot(xy[:, 0], xy[:, 1], "--", color="#4d7a1a", lw=1.0)
            ax.plot(xy[-1, 0], xy[-1, 1], "x" if not seen[-1] else "o", color="#4d7a1a", ms=6)
    if scene.prey:
        handles.append(Line2D([], [], ls="--", color="#4d7a1a",
                              label=f"prey paths ({len(scene.prey)}; x: eaten)"))
    seg = np.stack([head[:-1], head[1:]], axis=1)
    state = scene.state[:-1]
    colors = [state_color(scene.states[s], scene.states) if s >= 0 else "#000000" for s in state]
    ax.add_collection(LineCollection(seg, colors=colors, linewidths=1.6))
    ax.plot(*head[0], "o", color="k", ms=5, mfc="white")
    ax.plot(*head[-1], "s", color="k", ms=5)
    for s in scene.states:
        handles.append(Line2D([], [], color=state_color(s, scene.states), lw=2.5, label=s))
    handles.append(Line2D([], [], ls="", marker="o", mfc="white", color="k", label="start"))
    handles.append(Line2D([], [], ls="", marker="s", color="k", label="end"))
    for k, f in enumerate(sheet_frames, 1):
        ax.annotate(str(k), head[f], xytext=(6, 6), textcoords="offset points", fontsize=8,
                    ha="center", va="center",
                    bbox=dict(boxstyle="circle,pad=0.15", fc="white", ec="k", lw=0.6))
    if len(sheet_frames):
        handles.append(Line2D([], [], ls="", marker="$1$", color="k",
                              label="contact sheet frames"))
    return handles


def _ground_legend(g: dict) -> list:
    from matplotlib.patches import Patch

    walk, a, b = g["walkable"], g["shade_start"], g["shade_end"]
    moving = bool(np.any(a != b))
    entries = [("sun", "walkable, in sun")]
    entries += ([("shade", "shade at start and end"), ("start", "shade at the start only"),
                 ("end", "shade at the end only")] if moving else [("shade", "walkable, in shade")])
    entries.append(("blocked", "not walkable"))
    share = (walk & a).sum() / max(walk.sum(), 1)
    out = [Patch(color=GROUND[k], label=t) for k, t in entries]
    out.append(Patch(color="white", label=f"shade at start: {100 * share:.1f}% of walkable"))
    return out


def _draw_strip(ax, scene: PreviewScene, sheet_frames) -> None:
    for t0, t1, s in scene.segments:
        ax.broken_barh([(t0, max(t1 - t0, 1e-6))], (0, 1), color=state_color(s, scene.states))
    for k, f in enumerate(sheet_frames, 1):
        t = f / scene.fps
        ax.plot([t, t], [0, 1], color="k", lw=0.6)
        ax.text(t, 1.12, str(k), ha="center", va="bottom", fontsize=7)
    ax.set_xlim(0, max(scene.seconds, 1e-6))
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.set_xlabel("time [s]  (behaviour timeline)", fontsize=9)
