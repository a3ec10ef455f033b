"""USDZ packages load like the layers they hold: the package's root layer, with sublayers and
references resolved inside the package (bad packages are in the bad-input corpus, usd_usdz_*)."""

from __future__ import annotations

import numpy as np

from bad_inputs import usd_text, usdz
from baker.environment.load import load_environment

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
