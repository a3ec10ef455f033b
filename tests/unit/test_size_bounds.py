"""Files whose sizes a hostile input inflates (sparse files of gigabytes, with a header or a
name that points at them) are refused or skipped before they are read whole."""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest

from bad_inputs import GOOD_OBJ
from baker.errors import BakerError


def _sparse(path, size: int):
    with open(path, "wb") as f:
        f.truncate(size)


def test_glb_header_checked_before_the_file_is_read(tmp_path):
    from baker.inspect import InspectError, glb_bytes

    p = tmp_path / "big.glb"
    with open(p, "wb") as f:
        f.write(b"glTF" + struct.pack("<III", 2, 10**9, 0) + b"JSON")
    with pytest.raises(InspectError, match="header says 1,000,000,000 bytes"):
        glb_bytes(p)
    _sparse(p, 3 << 30)                 # the total agrees, the JSON chunk is empty
    with open(p, "r+b") as f:
        f.write(b"glTF" + struct.pack("<III", 2, 3 << 30, 0) + b"JSON")
    with pytest.raises(InspectError, match="0-byte JSON chunk"):
        glb_bytes(p)


def test_binary_stl_size_checked_from_its_header(tmp_path):
    from baker.environment.load import load_environment

    p = tmp_path / "sparse.stl"
    _sparse(p, 1 << 32)
    with pytest.raises(BakerError, match="header says 0 triangles"):
        load_environment(p)


def test_oversized_rig_and_jobs_files_refused_unread(tmp_path, monkeypatch):
    from baker import batch
    from baker.config import read_rig_table

    rig = tmp_path / "rig.toml"
    _sparse(rig, 3 << 30)
    with pytest.raises(BakerError, match="rig file is 3221225472 bytes"):
        read_rig_table(rig)
    monkeypatch.setattr(batch, "MAX_JOBS_FILE_BYTES", 100)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text("[[job]]\nseed = 1\n" + "# padding\n" * 20)
    with pytest.raises(BakerError, match="jobs file is 217 bytes; expected at most"):
        batch.load_plan(jobs, tmp_path / "out")


def test_oversized_material_library_read_as_missing(tmp_path, monkeypatch):
    from baker.environment import load

    (tmp_path / "m.mtl").write_text("newmtl red\nKd 0.8 0.1 0.1\n")
    (tmp_path / "level.obj").write_text("mtllib m.mtl\nusemtl red\n" + GOOD_OBJ)
    red = load.load_environment(tmp_path / "level.obj").meshes[0].color
    assert red[0] > 0.5 > red[1]
    monkeypatch.setattr(load, "MAX_SIDE_FILE_BYTES", 10)
    grey = load.load_environment(tmp_path / "level.obj").meshes[0].color
    assert np.allclose(grey[:3], grey[0]) and grey != red


def test_oversized_report_refused_unread(tmp_path, monkeypatch):
    from baker import inspect_file

    p = tmp_path / "r.json"
    _sparse(p, 2 << 30)
    with pytest.raises(BakerError, match="not a baker report: 2,147,483,648 bytes"):
        inspect_file._json_report(p)
    assert os.path.getsize(p) == 2 << 30
