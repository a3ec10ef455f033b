"""`baker preview` and `bake --preview`: the map and the contact sheet of a bake, drawn from its
GLB. A short bake in a scene built in code (open ground and a floating plank whose shadow falls
where the creature walks, a prey), judged with an independent reading of the GLB
(tests/tools/glb_read.py, linear-blend skinning written here) and independent Embree queries
(trimesh's embreex intersector)."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
import trimesh
from PIL import Image

from baker.cli import main
from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.environment.model import Environment, Sun
from baker.export import preview as pv
from baker.export.gltf import build_glb
from baker.export.preview_scene import load_bake
from baker.export.render import CREATURE, ENVIRONMENT, SHADOW_BIAS_BL, environment_caster
from baker.geometry.transforms import direction_from_angles
from baker.pipeline import bake
from conftest import box_mesh, flat_ground
from glb_read import Glb

pytest.importorskip("matplotlib")

SUN = direction_from_angles(math.radians(30.0), math.radians(45.0))
#: where the plank's shadow falls on the ground (the creature starts beside it, heading in)
SHADOW = np.array([0.25, 0.0, 0.12])
PLANK_Y = 0.3


def plank_scene(tmp) -> object:
    """3 m x 3 m of ground and a 0.5 m x 0.5 m plank floating PLANK_Y up, placed so that its
    shadow is centred on SHADOW."""
    centre = SHADOW + SUN * (PLANK_Y / SUN[1])
    plank = box_mesh("plank", centre, (0.25, 0.01, 0.25), (0.30, 0.22, 0.12, 1.0))
    env = Environment(meshes=(flat_ground(3.0, 6), plank), sun=Sun(direction=SUN))
    path = tmp / "plank.glb"
    path.write_bytes(build_glb(env, None, None, extras={}))
    return path


@pytest.fixture(scope="module")
def baked(tmp_path_factory, nav_cache_dir):
    """A 2.5 s bake (legs on, one prey) starting at the plank's shadow edge; its GLB path."""
    tmp = tmp_path_factory.mktemp("preview")
    cfg = BakeConfig(environment=plank_scene(tmp), rig=load_rig_config(DEFAULT_RIG),
                     out=tmp / "bake", seconds=2.5, seed=1, prey=1, formats=("glb",),
                     tolerance=0.0,   # every frame keyed: the independent reader needs it
                     nav_cache_dir=nav_cache_dir, start=(-0.1, 0.0, 0.05),
                     start_heading=(1.0, 0.0, 0.0))
    return bake(cfg).outputs["glb"]


@pytest.fixture(scope="module")
def sheet(baked):
    scene = load_bake(baked)
    env = environment_caster(scene)
    frames = pv.sheet_frames(scene, 6)
    img, shots, cams = pv.render_sheet(scene, env, frames)
    return scene, frames, img, shots, cams


# ---------------------------------------------------------------- an independent reading


def posed_meshes(glb_path, frame: int):
    """(environment mesh, ground face count, moving mesh: creature + prey) at `frame`, from
    the GLB with tests/tools/glb_read.py and linear-blend skinning written here."""
    g = Glb(glb_path.read_bytes())
    doc = g.doc
    names, world = g.world_matrices(0)
    w = world[frame]
    env_v, env_f, ground_faces, dyn = [], [], 0, []
    env_root = names.index("Environment")
    for i in doc["nodes"][env_root]["children"]:
        node = doc["nodes"][i]
        for prim in doc["meshes"][node["mesh"]]["primitives"]:
            v = g.accessor(prim["attributes"]["POSITION"]).astype(np.float64)
            f = g.accessor(prim["indices"]).astype(np.int64).reshape(-1, 3)
            env_f.append(f + sum(len(x) for x in env_v))
            env_v.append(v @ w[i, :3, :3].T + w[i, :3, 3])
            if node["name"] == "ground":
                ground_faces = len(f)
    env = trimesh.Trimesh(np.concatenate(env_v), np.concatenate(env_f), process=False)
    skin_node = next(n for n in doc["nodes"] if "skin" in n)
    skin = doc["skins"][skin_node["skin"]]
    ibm = g.accessor(skin["inverseBindMatrices"]).astype(np.float64).reshape(-1, 4, 4)
    joint_m = w[skin["joints"]] @ ibm.transpose(0, 2, 1)
    for prim in doc["meshes"][skin_node["mesh"]]["primitives"]:
        a = prim["attributes"]
        v = g.accessor(a["POSITION"]).astype(np.float64)
        j = g.accessor(a["JOINTS_0"]).astype(np.int64)
        wt = g.accessor(a["WEIGHTS_0"]).astype(np.float64)
        vh = np.concatenate([v, np.ones((len(v), 1))], axis=1)
        posed = np.einsum("nk,nkij,nj->ni", wt, joint_m[j], vh)[:, :3]
        dyn.append((posed, g.accessor(prim["indices"]).astype(np.int64).reshape(-1, 3)))
    for i, node in enumerate(doc["nodes"]):
        if node.get("name", "").startswith("prey_") and abs(np.linalg.det(w[i, :3, :3])) > 1e-12:
            prim = doc["meshes"][node["mesh"]]["primitives"][0]
            v = g.accessor(prim["attributes"]["POSITION"]).astype(np.float64)
            dyn.append((v @ w[i, :3, :3].T + w[i, :3, 3],
                        g.accessor(prim["indices"]).astype(np.int64).reshape(-1, 3)))
    offs = np.cumsum([0] + [len(v) for v, _ in dyn[:-1]])
    moving = trimesh.Trimesh(np.concatenate([v for v, _ in dyn]),
                             np.concatenate([f + o for (_, f), o in zip(dyn, offs)]),
                             process=False)
    return env, ground_faces, moving


def test_skinned_mesh_is_posed_as_an_independent_reading_poses_it(baked, sheet):
    scene, frames = sheet[0], sheet[1]
    for f in frames[[0, -1]]:
        _, _, moving = posed_meshes(baked, int(f))
        v, _ = scene.skin.pose(scene.joint_matrices(int(f)))
        assert np.abs(v - moving.vertices[: len(v)]).max() < 2e-5


def test_the_creature_appears_in_every_frame(sheet):
    """Every sheet frame is 640x360 and its primary rays hit the creature's mesh on at least
    2% of the pixels, around the middle of the picture."""
    scene, frames, img, shots, cams = sheet
    assert img.size == (3 * 640 + 2 * 6, 2 * 360 + 6)
    for f, shot, cam in zip(frames, shots, cams):
        assert shot.rgb.shape == (360, 640, 3)
        creature = shot.ids == CREATURE
        print(f"frame {f}: creature on {100 * creature.mean():.1f}% of the pixels")
        assert creature.mean() > 0.02
        rows, cols = np.nonzero(creature)
        assert 100 < cols.mean() < 540 and 60 < rows.mean() < 300
        # the body's centre projects inside the picture
        c = scene.baked.positions[f, scene.spine].mean(axis=0)
        x, y = cam.project(c[None], 640, 360)[0]
        assert 0 <= x < 640 and 0 <= y < 360


def test_shadows_on_the_ground_near_the_creature_match_ray_casts(baked, sheet):
    """For the ground pixels within 1.5 body lengths of the creature (and, apart, those within
    0.3 body lengths of its spine: its own shadow), a pixel is dark iff an independent Embree
    query (trimesh/embreex on the GLB read by glb_read, the creature skinned here) finds the
    ray from its ground point toward the sun blocked: > 99% agreement, with both sun and shade
    in every frame. The ray starts SHADOW_BIAS_BL body lengths above the ground, as the
    renderer's shadow rays do (against self-shadowing)."""
    scene, frames, _, shots, cams = sheet
    bl = scene.body_length
    counts = np.zeros((2, 2), np.int64)                  # [near, under] x [pixels, agreeing]
    for f, shot, cam in zip(frames, shots, cams):
        env, n_ground, moving = posed_meshes(baked, int(f))
        both = trimesh.util.concatenate([env, moving])
        caster = trimesh.ray.ray_pyembree.RayMeshIntersector(both)
        o, d = cam.rays(640, 360)
        tri, ray, loc = caster.intersects_id(np.ascontiguousarray(o), d, multiple_hits=False,
                                             return_locations=True)
        spine = scene.baked.positions[f, scene.spine]
        gap = np.linalg.norm((loc[:, None, :] - spine[None])[..., [0, 2]], axis=2).min(axis=1)
        pick = (tri < n_ground) & (gap < 1.5 * bl)       # the ground mesh comes first
        pix, pts, gap = ray[pick], loc[pick], gap[pick]
        blocked = caster.intersects_any(pts + [0.0, SHADOW_BIAS_BL * bl, 0.0],
                                        np.tile(SUN, (len(pts), 1)))
        lum = shot.rgb.reshape(-1, 3).astype(float) @ [0.2126, 0.7152, 0.0722]
        g = lum[pix]
        dark = g < 0.5 * (g.min() + g.max())
        assert (shot.ids.reshape(-1)[pix] == ENVIRONMENT).mean() > 0.99
        under = gap < 0.3 * bl
        print(f"frame {f}: {len(pix)} ground pixels near the creature ({under.sum()} under "
              f"it), {100 * blocked.mean():.1f}% shaded ({100 * blocked[under].mean():.1f}%), "
              f"agreement {100 * np.mean(dark == blocked):.3f}% "
              f"({100 * np.mean(dark[under] == blocked[under]):.3f}%)")
        assert 0.02 < blocked.mean() < 0.98 and blocked[under].any()
        counts += [[len(pix), np.sum(dark == blocked)],
                   [under.sum(), np.sum(dark[under] == blocked[under])]]
    assert counts[0, 0] > 100_000 and counts[1, 0] > 20_000
    assert counts[0, 1] / counts[0, 0] > 0.99
    assert counts[1, 1] / counts[1, 0] > 0.99


def test_in_place_bake_is_previewed_where_it_walked(tmp_path, nav_cache_dir):
    """An in-place bake (root held still, the motion in `root_motion`) reads back as the world
    bake of the same seed: every joint within 1e-6 m."""
    env = plank_scene(tmp_path)
    pos = {}
    for mode in ("world", "in-place"):
        cfg = BakeConfig(environment=env, rig=load_rig_config(DEFAULT_RIG), out=tmp_path / mode,
                         seconds=1.0, seed=2, prey=0, formats=("glb",), nav_cache_dir=nav_cache_dir,
                         root_motion=mode, tolerance=0.0)   # the same keys in both
        scene = load_bake(bake(cfg).outputs["glb"])
        pos[mode] = {n: scene.baked.positions[:, i] for i, n in enumerate(scene.baked.names)}
    assert np.ptp(pos["world"]["head"][:, 0]) > 0.02          # it walked
    for name, p in pos["world"].items():
        assert np.abs(pos["in-place"][name] - p).max() < 1e-6, name


def test_sheet_frames_show_every_state():
    class Scene:
        n_frames, fps = 601, 30
        states = ("wander", "hunt", "strike", "feed")
        segments = ((0.0, 8.0, "wander"), (8.0, 9.0, "hunt"), (9.0, 9.3, "strike"),
                    (9.3, 20.0, "feed"))
        state = np.zeros(601, np.int64)

    Scene.state[240:270], Scene.state[270:279], Scene.state[279:] = 1, 2, 3
    frames = pv.sheet_frames(Scene(), 6)
    assert len(frames) == 6 and np.all(np.diff(frames) > 0)
    assert set(Scene.state[frames]) == {0, 1, 2, 3}


def _colour_pixels(png: bytes, hexa: str, tol: int = 30) -> int:
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    want = np.array([int(hexa[i:i + 2], 16) for i in (1, 3, 5)])
    return int(np.sum(np.abs(rgb - want).max(axis=-1) <= tol))


def test_map_has_the_trail_contacts_prey_and_timeline(baked):
    from baker.export.preview_map import STATE_COLORS

    scene = load_bake(baked)
    png = pv.preview_images(baked, frames=6)["map"]
    img = Image.open(io.BytesIO(png))
    assert img.format == "PNG" and img.size[0] >= 800
    states = set(scene.states)
    assert "wander" in states
    for s in states:      # the trail and the timeline strip in each state's colour
        assert _colour_pixels(png, STATE_COLORS[s]) > 200, s
    assert _colour_pixels(png, "#4d7a1a", 20) > 50          # the prey's path
    assert _colour_pixels(png, "#3a3a3a", 25) > 50          # foot contacts


@pytest.mark.slow
def test_same_glb_same_bytes(baked):
    a = pv.preview_images(baked, frames=6, gif=True)
    b = pv.preview_images(baked.read_bytes(), frames=6, gif=True, name=baked.stem)
    assert a == b
    gif = Image.open(io.BytesIO(a["gif"]))
    assert gif.size == (320, 180) and gif.n_frames == load_bake(baked).n_frames


# ---------------------------------------------------------------- the command line


def _run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_bad_files_exit_2_with_one_line(tmp_path, capsys, monkeypatch, small_env, rig):
    cases = {"missing.glb": None, "empty.glb": b"", "text.glb": b"hello, not a GLB\n",
             "truncated.glb": build_glb(small_env, None, None, extras={})[:300],
             "no_skin.glb": build_glb(small_env, None, None, extras={}),
             "no_animation.glb": build_glb(small_env, rig, None, extras={})}
    for name, data in cases.items():
        if data is not None:
            (tmp_path / name).write_bytes(data)
    before = sorted(p.name for p in tmp_path.iterdir())
    for name in cases:
        code, out, err = _run(["preview", str(tmp_path / name)], capsys)
        assert code == 2 and out == "", (name, out)
        assert err.count("\n") == 1 and err.startswith("Error: ") and name in err
    code, _, err = _run(["preview", str(tmp_path / "no_skin.glb"), "--frames", "5"], capsys)
    assert code == 2 and err.startswith("Error: --frames must be") and err.count("\n") == 1
    # an empty --out named the current folder
    code, _, err = _run(["preview", str(tmp_path / "no_skin.glb"), "--out", ""], capsys)
    assert code == 2 and err.startswith("Error: --out is empty") and err.count("\n") == 1
    # without matplotlib: one line naming the extra to install
    monkeypatch.setattr(pv.importlib.util, "find_spec",
                        lambda name, *a: None if name == "matplotlib" else object())
    code, _, err = _run(["preview", str(tmp_path / "no_skin.glb")], capsys)
    assert code == 2 and "pip install 'baker[preview]'" in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_outputs_that_would_replace_what_is_not_a_picture_are_refused(baked, tmp_path, capsys):
    """Refused before anything is drawn, one line, nothing written or replaced: --out a device
    (wrote /dev/null_map.png beside it), an output that is the GLB read (a GLB named
    x_map.png, --out x: the map was written over it), an output that is a FIFO (renamed over)."""
    import os
    import shutil

    glb = tmp_path / "x_map.png"
    shutil.copy(baked, glb)
    os.mkfifo(tmp_path / "q_map.png")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    for argv, word in ((["--out", "/dev/null"], "device"),
                       (["--out", str(tmp_path / "x")], "the GLB file"),
                       (["--out", str(tmp_path / "q")], "pipe")):
        code, out, err = _run(["preview", str(glb), *argv], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert err.startswith("Error: ") and word in err, err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["q_map.png", "x_map.png"]


@pytest.mark.slow
def test_bake_preview_writes_the_pictures_of_its_glb(tmp_path, capsys, nav_cache_dir):
    """`bake --preview` writes PATH_map.png and PATH_sheet.png with the other files, the same
    bytes as `baker preview` on the GLB it wrote; without a GLB it is refused up front."""
    env = plank_scene(tmp_path)
    out = tmp_path / "out" / "c"
    code, _, err = _run(["bake", str(env), "--seconds", "1", "--format", "usd", "--preview",
                         "--out", str(out), "--cache-dir", str(nav_cache_dir)], capsys)
    assert code == 2 and err.startswith("Error: --preview") and err.count("\n") == 1
    assert not out.parent.exists() or not any(out.parent.iterdir())
    code, stdout, err = _run(["bake", str(env), "--seconds", "1", "--format", "glb",
                              "--preview", "--out", str(out), "--cache-dir",
                              str(nav_cache_dir)], capsys)
    assert code == 0, err
    files = sorted(p.name for p in out.parent.iterdir())
    assert files == ["c.glb", "c.json", "c_map.png", "c_sheet.png"]
    assert "c_sheet.png" in stdout
    sheet = Image.open(out.parent / "c_sheet.png")
    assert sheet.size == (3 * 640 + 2 * 6, 3 * 360 + 2 * 6)
    again = tmp_path / "again"
    code, _, err = _run(["preview", str(out.parent / "c.glb"), "--out", str(again)], capsys)
    assert code == 0, err
    for key in ("map", "sheet"):
        assert (tmp_path / f"again_{key}.png").read_bytes() == \
            (out.parent / f"c_{key}.png").read_bytes()


@pytest.mark.slow
def test_readme_pictures_are_what_the_code_draws(tmp_path, capsys, nav_cache_dir):
    """docs/preview_map.png and docs/preview_sheet.png (the README's) are the default bake's
    pictures as the current code draws them: `python docs/make_pictures.py` after a change that
    moves them. Compared pixel by pixel (99.5 % equal), not byte by byte, so that another CPU's
    Embree may round an edge differently."""
    import sys
    from pathlib import Path

    docs = Path(__file__).resolve().parents[2] / "docs"
    sys.path.insert(0, str(docs))
    try:
        from make_pictures import small_png
    finally:
        sys.path.remove(str(docs))
    code, _, err = _run(["bake", "--format", "glb", "--out", str(tmp_path / "centipede"),
                         "--cache-dir", str(nav_cache_dir)], capsys)
    assert code == 0, err
    now = pv.preview_images(tmp_path / "centipede.glb")
    for key, data in (("map", now["map"]), ("sheet", small_png(now["sheet"]))):
        old = np.asarray(Image.open(docs / f"preview_{key}.png").convert("RGB"))
        new = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
        assert old.shape == new.shape, f"docs/preview_{key}.png: run python docs/make_pictures.py"
        same = np.all(old == new, axis=-1).mean()
        assert same > 0.995, (f"docs/preview_{key}.png differs from what the code draws "
                              f"({100 * same:.2f}% equal): run python docs/make_pictures.py")


def test_the_map_shows_the_floor_walked_under_a_roof_and_cut_solids_as_not_walkable():
    """preview_map.ground_grid sees the level cut a body length above the head's trail
    (section_heights): the floor under a roof the creature walked beneath is drawn (in the
    roof's shade), not the roof's top in the sun (Recast's dungeon level: the map showed an
    upper storey's sunlit deck over the shaded floor the creature rested on); a stone the cut
    passes through shows as not walkable; open ground as walkable in the sun."""
    from types import SimpleNamespace

    from baker.environment.rays import RayCaster
    from baker.export.preview_map import ground_grid

    ground = flat_ground(4.0, 8)
    roof = box_mesh("roof", (-1.0, 1.0, 0.0), (1.0, 0.02, 2.0), (1, 1, 1, 1))   # over x < 0
    stone = box_mesh("stone", (1.0, 0.25, 0.0), (0.25, 0.25, 0.25), (1, 1, 1, 1))
    parts = (ground, roof, stone)
    v = np.concatenate([p.vertices for p in parts]).astype(np.float64)
    f = np.concatenate([p.faces.astype(np.int64) + o for p, o in
                        zip(parts, np.cumsum([0] + [len(p.vertices) for p in parts[:-1]]))])
    mesh = trimesh.Trimesh(v, f, process=False)
    trail = np.column_stack([np.linspace(-1.8, 1.8, 50), np.full(50, 0.02), np.full(50, -1.0)])
    baked = SimpleNamespace(positions=trail[:, None, :], index=lambda name: 0, extras={})
    sun = np.array([[0.1, 0.99, 0.1]]) / np.linalg.norm([0.1, 0.99, 0.1])
    scene = SimpleNamespace(env=SimpleNamespace(vertices=v, normals=mesh.vertex_normals),
                            baked=baked, body_length=0.25, sun=np.repeat(sun, 2, axis=0),
                            navmesh=None, navmesh_cell=0.0)
    g = ground_grid(scene, RayCaster(mesh), (-1.9, 1.9, -1.9, 1.9))

    def at(x, z):
        cell = g["cell"]
        return int((z + 1.9) / cell), int((x + 1.9) / cell)

    under_roof, on_stone, open_ground = at(-1.0, 0.5), at(1.0, 0.0), at(1.0, 1.5)
    assert g["walkable"][under_roof] and g["shade_start"][under_roof]
    assert g["hit"][on_stone] and not g["walkable"][on_stone]
    assert g["walkable"][open_ground] and not g["shade_start"][open_ground]
