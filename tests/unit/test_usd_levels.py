"""USD levels as packed and instanced: .usdz packages load like the layers they hold (the
package's root layer, with sublayers and references resolved inside the package; bad packages
are in the bad-input corpus, usd_usdz_*), and a UsdGeom.PointInstancer's prototypes are drawn
where it places them."""

from __future__ import annotations

import random
import subprocess
import sys

import numpy as np
import pytest

from bad_inputs import deep_usd_text, usd_text, usdz
from baker.environment.load import load_environment
from baker.errors import EnvironmentLoadError

BOX = usd_text(points="[(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]").replace(
    'def Mesh "floor"', 'def Mesh "box"')


def test_usdz_loads_as_its_layers(tmp_path):
    plain = tmp_path / "level.usda"
    plain.write_text(usd_text())
    packed = tmp_path / "level.usdz"
    packed.write_bytes(usdz({"level.usda": usd_text()}))
    a, b = load_environment(plain), load_environment(packed)
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.faces, b.mesh.faces)


def test_usdz_sublayer_inside_the_package(tmp_path):
    root = usd_text(extra="    subLayers = [@parts/box.usda@]\n")
    packed = tmp_path / "level.usdz"
    packed.write_bytes(usdz({"level.usda": root, "parts/box.usda": BOX}))
    env = load_environment(packed)
    assert len(env.meshes) == 2 and len(env.mesh.faces) == 4


def test_usdz_written_by_usd_itself(tmp_path):
    """A package made by UsdUtils (crate layers, its own alignment) with a crate sublayer."""
    from pxr import Sdf, Usd, UsdUtils

    part = Usd.Stage.CreateInMemory()
    part.GetRootLayer().ImportFromString(BOX)
    part.GetRootLayer().Export(str(tmp_path / "box.usdc"))
    (tmp_path / "level.usda").write_text(usd_text(extra="    subLayers = [@box.usdc@]\n"))
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(tmp_path / "level.usda")),
                                         str(tmp_path / "level.usdz"))
    (tmp_path / "box.usdc").unlink()          # the package must carry it
    env = load_environment(tmp_path / "level.usdz")
    assert len(env.meshes) == 2 and len(env.mesh.faces) == 4


def _instancer_stage(path, invisible=()):
    """A floor, and a PointInstancer placing a 0.5 m tile (prototype root translated 1 m up,
    the tile 0.1 m above its root) at x = 10, 20, 30."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    floor = UsdGeom.Mesh.Define(stage, "/World/floor")
    floor.CreatePointsAttr([(-40, 0, -5), (40, 0, -5), (40, 0, 5), (-40, 0, 5)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    inst = UsdGeom.PointInstancer.Define(stage, "/World/tiles")
    root = UsdGeom.Xform.Define(stage, "/World/tiles/Prototypes/tile")
    root.AddTranslateOp().Set(Gf.Vec3d(0, 1, 0))
    tile = UsdGeom.Mesh.Define(stage, "/World/tiles/Prototypes/tile/mesh")
    tile.AddTranslateOp().Set(Gf.Vec3d(0, 0.1, 0))
    tile.CreatePointsAttr([(0, 0, 0), (0.5, 0, 0), (0.5, 0, 0.5), (0, 0, 0.5)])
    tile.CreateFaceVertexCountsAttr([4])
    tile.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    inst.CreatePrototypesRel().SetTargets([root.GetPath()])
    inst.CreateProtoIndicesAttr([0, 0, 0])
    inst.CreatePositionsAttr([(10, 0, 0), (20, 0, 0), (30, 0, 0)])
    if invisible:
        inst.CreateInvisibleIdsAttr(list(invisible))
    stage.GetRootLayer().Save()


def test_point_instancer_places_its_prototypes(tmp_path):
    """A prototype is drawn where the instancer places it (its root's transform included) and
    nowhere else; hidden instances are not drawn."""
    _instancer_stage(tmp_path / "level.usda", invisible=[1])
    env = load_environment(tmp_path / "level.usda")
    world = env.mesh.vertices.astype(np.float64) + env.origin
    tiles = world[world[:, 1] > 0.5]
    assert len(env.mesh.faces) == 2 + 2 * 2                    # floor + two visible tiles
    assert np.allclose(np.unique(tiles[:, 1]), [1.1])
    assert set(np.unique(np.round(tiles[:, 0], 6))) == {10.0, 10.5, 30.0, 30.5}
    # the prototype itself, under the instancer, is not drawn where it is defined
    assert not np.any((world[:, 0] < 1.0) & (world[:, 1] > 0.5))


def test_point_instancer_bounded(tmp_path, monkeypatch):
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_TRIANGLES", 5)
    _instancer_stage(tmp_path / "level.usda")
    with pytest.raises(EnvironmentLoadError, match="places a 2-triangle, 4-vertex mesh 3 times"):
        load_environment(tmp_path / "level.usda")


def test_usd_mesh_count_bounded(tmp_path, monkeypatch):
    """Instanced references can multiply a small file into millions of meshes: the traversal
    stops at MAX_MESHES."""
    from baker.environment import load
    from baker.errors import EnvironmentLoadError

    monkeypatch.setattr(load, "MAX_MESHES", 5)
    refs = "".join(f'def Xform "c{i}" (\n    instanceable = true\n    prepend references = '
                   f'</proto>\n)\n{{\n    double3 xformOp:translate = ({5 * i}, 0, 0)\n'
                   '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
                   for i in range(8))
    text = usd_text().replace('def Mesh "floor"', 'class Xform "proto"\n{\ndef Mesh "floor"')
    (tmp_path / "level.usda").write_text(text + "}\n" + refs)
    with pytest.raises(EnvironmentLoadError, match="more than 5 meshes"):
        load_environment(tmp_path / "level.usda")
    monkeypatch.setattr(load, "MAX_MESHES", 50)
    assert len(load_environment(tmp_path / "level.usda").meshes) == 8


@pytest.mark.parametrize("attr", [
    "float[] primvars:displayColor = [0.1, 0.2, 0.3, 0.4]",
    "color3f[] primvars:displayColor = [(0.1, 0.2, 0.3), (0.4, 0.5, 0.6)]\n"
    "    float[] primvars:displayOpacity = [0.5, 0.7]",
])
def test_usd_colour_of_an_odd_type_does_not_refuse_the_level(tmp_path, attr):
    """Colours are cosmetic: a displayColor of the wrong shape keeps the level (the default
    colour); a well-formed one is averaged."""
    text = usd_text().replace("point3f[] points", attr + "\n    point3f[] points")
    (tmp_path / "level.usda").write_text(text)
    env = load_environment(tmp_path / "level.usda")
    assert len(env.mesh.faces) == 2
    if attr.startswith("float[]"):
        assert env.meshes[0].color == (0.5, 0.5, 0.5, 1.0)
    else:
        assert np.allclose(env.meshes[0].color, (0.25, 0.35, 0.45, 0.6))


@pytest.mark.parametrize("parent", ["over", "class"])
def test_point_instancer_prototypes_under_a_hidden_parent(tmp_path, parent):
    """Prototypes kept under an `over` or `class` parent (hidden from ordinary traversals)
    are drawn where the instancer places them, and only there."""
    text = usd_text(body=(
        'def PointInstancer "pi"\n{\n    point3f[] positions = [(0, 0, 0), (10, 0, 0)]\n'
        '    int[] protoIndices = [0, 0]\n    rel prototypes = [</Protos/a>]\n}\n'
        f'{parent} "Protos"\n{{\ndef Mesh "a"\n{{\n    int[] faceVertexCounts = [3, 3]\n'
        '    int[] faceVertexIndices = [0, 2, 1, 0, 3, 2]\n'
        '    point3f[] points = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]\n}\n}\n'))
    (tmp_path / "level.usda").write_text(text)
    env = load_environment(tmp_path / "level.usda")
    world = env.mesh.vertices.astype(np.float64) + env.origin
    assert len(env.mesh.faces) == 4
    assert set(np.unique(np.round(world[:, 0]))) == {-1.0, 1.0, 9.0, 11.0}


QUAD = ('def Mesh "m"\n{\n    int[] faceVertexCounts = [3, 3]\n'
        '    int[] faceVertexIndices = [0, 2, 1, 0, 3, 2]\n'
        '    point3f[] points = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]\n}\n')


def _instancer(name: str, positions: str, proto: str, protos_body: str) -> str:
    return (f'def PointInstancer "{name}"\n{{\n    point3f[] positions = [{positions}]\n'
            f'    int[] protoIndices = [{", ".join("0" * (positions.count("(")))}]\n'
            f'    rel prototypes = [<{proto}>]\n    def Scope "Protos"\n    {{\n{protos_body}'
            '    }\n}\n')


def test_nested_point_instancers(tmp_path):
    """An instancer of (an instancer of quads): every quad at every outer x inner place."""
    inner = _instancer("inner", "(0, 0, 0), (100, 0, 0)", "/outer/Protos/a/inner/Protos/m",
                       QUAD)
    outer = _instancer("outer", "(0, 0, 0), (0, 0, 50)", "/outer/Protos/a",
                       'def Xform "a"\n{\n' + inner + '}\n')
    (tmp_path / "level.usda").write_text(usd_text(body=outer))
    env = load_environment(tmp_path / "level.usda")
    world = env.mesh.vertices.astype(np.float64) + env.origin
    assert len(env.mesh.faces) == 2 * 4
    centres = {(round(x), round(z)) for x, z in world[:, [0, 2]] // 10 * 10}
    assert centres == {(-10, -10), (0, -10), (-10, 0), (0, 0), (90, -10), (100, -10),
                       (90, 0), (100, 0), (-10, 40), (0, 40), (-10, 50), (0, 50),
                       (90, 40), (100, 40), (90, 50), (100, 50)}


@pytest.mark.parametrize("hidden", ['token visibility = "invisible"',
                                    'uniform token purpose = "guide"'])
def test_point_instancer_prototype_hidden_parts(tmp_path, hidden):
    """A prototype's invisible or guide parts are not drawn in any instance."""
    extra = QUAD.replace('"m"', '"helper"').replace("{\n", "{\n    " + hidden + "\n", 1)
    body = _instancer("pi", "(0, 0, 0), (10, 0, 0)", "/pi/Protos/a",
                      'def Xform "a"\n{\n' + QUAD + extra + '}\n')
    (tmp_path / "level.usda").write_text(usd_text(body=body))
    assert len(load_environment(tmp_path / "level.usda").mesh.faces) == 2 * 2


def test_usdz_dependency_outside_the_package_named(tmp_path):
    from baker.errors import EnvironmentLoadError

    (tmp_path / "outside.usda").write_text(usd_text())
    root = usd_text(extra="    subLayers = [@../outside.usda@]\n")
    (tmp_path / "level.usdz").write_bytes(usdz({"level.usda": root}))
    with pytest.raises(EnvironmentLoadError, match="'../outside.usda', outside its .usdz"):
        load_environment(tmp_path / "level.usdz")


PURPOSES = """#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 1
)
def Xform "set"
{{
    def Mesh "floor"
    {{
        {purpose}
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(0, 0, 0), (0, 0, 4), (4, 0, 4), (4, 0, 0)]
    }}
    def Mesh "floor_proxy"
    {{
        uniform token purpose = "proxy"
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(0, 0.3, 0), (0, 0.3, 4), (4, 0.3, 4), (4, 0.3, 0)]
    }}
}}
"""


@pytest.mark.parametrize("purpose, drawn", [
    ('uniform token purpose = "render"', ["floor"]),
    ("", ["floor"]),                                          # default purpose
    ('uniform token purpose = "guide"', ["floor_proxy"]),     # the proxy is all there is
])
def test_usd_proxy_stand_ins_are_not_drawn_over_the_level(tmp_path, purpose, drawn):
    """A proxy (a stand-in for render geometry, here a box 0.3 m over the floor) is drawn only
    on a stage that draws nothing else, as a final render draws it."""
    p = tmp_path / "set.usda"
    p.write_text(PURPOSES.format(purpose=purpose))
    assert [m.name for m in load_environment(p).meshes] == drawn


@pytest.mark.parametrize("swap, message", [
    (("int[] faceVertexCounts = [3]", 'string[] faceVertexCounts = ["three"]'),
     "faceVertexCounts holds text values"),
    (("int[] faceVertexIndices = [0, 1, 2]", "float[] faceVertexIndices = [0.5, 1, 2]"),
     "faceVertexIndices holds fractional values"),
    (("point3f[] points = [(0, 0, 0), (0, 0, 1), (1, 0, 0)]", 'string[] points = ["a", "b"]'),
     "points holds text values"),
    (("int[] faceVertexCounts = [3]",
      'int[] faceVertexCounts = [3]\n    string[] holeIndices = ["x"]'),
     "holeIndices holds text values"),
])
def test_usd_mesh_arrays_of_another_type_refused(tmp_path, swap, message):
    """A layer may author a mesh's arrays with another type than the schema's (the attribute
    still reports the schema's): refused by name, not read wrong or as 'invalid literal'."""
    text = ('#usda 1.0\ndef Mesh "m"\n{\n    int[] faceVertexCounts = [3]\n'
            "    int[] faceVertexIndices = [0, 1, 2]\n"
            "    point3f[] points = [(0, 0, 0), (0, 0, 1), (1, 0, 0)]\n}\n")
    assert swap[0] in text
    p = tmp_path / "typed.usda"
    p.write_text(text.replace(*swap))
    with pytest.raises(EnvironmentLoadError, match=message):
        load_environment(p)


def test_a_deep_usd_hierarchy_loads(tmp_path):
    """The floor under 20,000 nested Xforms loads, whole (a text layer over 1,000 levels was
    refused: on the main thread's 8 MB stack USD's C++ code crashed 18,500 deep; the level is
    read on a thread of its own with a 64 MB stack). In a process of its own: a crash would be
    a SIGSEGV."""
    p = tmp_path / "level.usda"
    p.write_text(deep_usd_text(20_000))
    code = ("import numpy as np; from baker.environment.load import load_environment; "
            f"env = load_environment({str(p)!r}); "
            "print(len(env.meshes), env.mesh.vertices[np.lexsort(env.mesh.vertices.T)].tolist(),"
            " len(env.mesh.faces))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr[-2000:]
    corners = sorted([[x, 0.0, z] for x in (-2.0, 2.0) for z in (-2.0, 2.0)],
                     key=lambda v: (v[2], v[1], v[0]))
    assert r.stdout.strip() == f"1 {corners} 2"


def _random_stage(seed: int):
    """A stage of 200 prims (Xform, Scope, Mesh, typeless) in a random tree, some with
    visibility or purpose authored, and an instanced copy of one branch."""
    from pxr import Sdf, Usd, UsdGeom

    rng = random.Random(seed)
    stage = Usd.Stage.CreateInMemory()
    parents = [Sdf.Path("/")]
    for i in range(200):
        kind = rng.choice(["Xform", "Scope", "", "Mesh", "Xform", "Mesh"])
        prim = stage.DefinePrim(rng.choice(parents).AppendChild(f"p{i}"), kind)
        if rng.random() < 0.2:
            prim.CreateAttribute("visibility", Sdf.ValueTypeNames.Token).Set(
                rng.choice(["invisible", "inherited"]))
        if rng.random() < 0.3:
            prim.CreateAttribute("purpose", Sdf.ValueTypeNames.Token, variability=(
                Sdf.VariabilityUniform)).Set(rng.choice(["default", "render", "proxy", "guide"]))
        if kind != "Mesh":
            parents.append(prim.GetPath())
    inst = stage.DefinePrim("/inst", "Xform")
    inst.GetReferences().AddInternalReference(rng.choice(parents[1:]))
    inst.SetInstanceable(True)
    return stage


@pytest.mark.parametrize("seed", range(40))
def test_visibility_and_purpose_as_usd_computes_them(seed):
    """load._usd_inherited (a prim's state from its parent's) gives what UsdGeom.Imageable's
    ComputeVisibility and ComputePurpose (each walking up to the root) give, instance proxies
    and typeless prims included."""
    from pxr import Usd, UsdGeom

    from baker.environment.load import _usd_inherited

    stage = _random_stage(seed)
    seen, time = {}, Usd.TimeCode.EarliestTime()
    for prim in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(
            Usd.PrimDefaultPredicate)):
        invisible, info = _usd_inherited(prim, seen, time)
        if prim.IsA(UsdGeom.Imageable):
            img = UsdGeom.Imageable(prim)
            assert invisible == (img.ComputeVisibility(time) == UsdGeom.Tokens.invisible)
            assert info.purpose == img.ComputePurpose()
