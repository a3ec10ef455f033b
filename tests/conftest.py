"""Shared fixtures, built in code: a rig, a small environment and a synthetic trajectory; one
navigation cache per session; the hypothesis profiles.

Hypothesis profiles (property tests in tests/unit): `ci`, the default, is derandomized (the same
examples on every run, so CI never passes or fails by chance) with no deadline; `dev`
(`HYPOTHESIS_PROFILE=dev python -m pytest tests/unit`) draws new random examples on every run, to
look for failures. A failing example found that way is kept in its test as an `@example`.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

sys.path.insert(0, str(Path(__file__).resolve().parent / "tools"))

settings.register_profile("ci", derandomize=True, deadline=None, database=None, print_blob=True)
settings.register_profile("dev", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

from baker.config import DEFAULT_RIG, load_rig_config  # noqa: E402
from baker.environment.model import EnvMesh, Environment, Sun  # noqa: E402
from baker.geometry.transforms import frames_to_quat, normalize  # noqa: E402
from baker.solve.trajectory import Trajectory  # noqa: E402


def box_mesh(name: str, centre, half, color) -> EnvMesh:
    """An axis-aligned box as an EnvMesh (outward CCW faces, no normals)."""
    c = np.asarray(centre, float)
    h = np.asarray(half, float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    v = (c + corners * h).astype(np.float32)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32)
    return EnvMesh(name=name, vertices=v, faces=f, color=color)


def flat_ground(size: float = 2.0, n: int = 4) -> EnvMesh:
    xs = np.linspace(-size / 2, size / 2, n + 1)
    gx, gz = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], -1).astype(np.float32)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + 1, i + n + 1, i + n + 2
    f = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                        np.stack([a, d, c], -1).reshape(-1, 3)]).astype(np.uint32)
    normals = np.tile(np.array([[0, 1, 0]], np.float32), (len(v), 1))
    return EnvMesh(name="ground", vertices=v, faces=f, normals=normals,
                   color=(0.066, 0.05, 0.04, 1.0), roughness=1.0, metallic=0.0)


@pytest.fixture(scope="session")
def nav_cache_dir(tmp_path_factory) -> Path:
    """One navigation cache for the whole session: bakes of the same environment and agent
    share its surface instead of each building it (the default scene's is ~192 MB and a few
    seconds to build). Tests about the cache itself (cold vs warm, lazy windows) use their own."""
    return tmp_path_factory.mktemp("navcache")


@pytest.fixture(scope="session")
def rig_config():
    return load_rig_config(DEFAULT_RIG)


@pytest.fixture(scope="session")
def rig(rig_config):
    """The default rig, with legs, antennae, ultimate legs and forcipules."""
    from baker.rig import build_rig

    return build_rig(rig_config)


@pytest.fixture(scope="session")
def spine_rig_config(rig_config):
    """The default rig without limbs (legs.enabled = false): spine joints and leg stubs only."""
    from dataclasses import replace

    return replace(rig_config, legs=replace(rig_config.legs, enabled=False))


@pytest.fixture(scope="session")
def spine_rig(spine_rig_config):
    from baker.rig import build_rig

    return build_rig(spine_rig_config)


@pytest.fixture(scope="session")
def small_env() -> Environment:
    meshes = (flat_ground(),
              box_mesh("rock 1", (0.3, 0.05, 0.4), (0.05, 0.05, 0.08), (0.2, 0.2, 0.2, 1.0)),
              box_mesh("log-A", (-0.4, 0.03, -0.2), (0.3, 0.03, 0.06), (0.005, 0.05, 0.013, 1.0)))
    sun = Sun(direction=normalize(np.array([0.3, 0.9, 0.2])))
    return Environment(meshes=meshes, sun=sun, source="", name="test_env")


def sine_trajectory(spacing: float, n_spine: int, seconds: float = 3.0, fps: int = 30,
                    speed: float = 0.2, clearance: float = 0.0075, bumpy: bool = True
                    ) -> Trajectory:
    """A creature following z -> (A sin(kz), h(z), z) on (optionally bumpy) ground.

    Spine joints sit at exact arc lengths s_head - i*spacing along a dense polyline; each joint's
    +Z points at the joint ahead (the head along the path tangent), +Y along the ground normal.
    """
    f_count = int(round(seconds * fps)) + 1
    times = np.arange(f_count) / fps
    amp, k = 0.05, 2 * np.pi / 0.4
    bump, kb = (0.02, 2 * np.pi / 0.7) if bumpy else (0.0, 1.0)
    z_end = 1.0 + 1.2 * speed * seconds                 # the path is longer than its z extent
    z = np.linspace(-0.5, z_end, int(20000 * (z_end + 0.5)) + 1)
    pts = np.stack([amp * np.sin(k * z), bump * np.sin(kb * z) + clearance, z], -1)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s_head = arc[np.searchsorted(z, 0.0)] + speed * times                     # (F,)
    s = s_head[:, None] - spacing * np.arange(n_spine)[None, :]              # (F, S)
    pos = np.stack([np.interp(s, arc, pts[:, c]) for c in range(3)], -1)
    ahead = np.empty_like(pos)
    ahead[:, 1:] = pos[:, :-1] - pos[:, 1:]
    head_next = np.stack([np.interp(s[:, 0] + 1e-4, arc, pts[:, c]) for c in range(3)], -1)
    ahead[:, 0] = head_next - pos[:, 0]
    zz = pos[..., 2]
    up = np.stack([np.zeros_like(zz), np.ones_like(zz), -bump * kb * np.cos(kb * zz)], -1)
    rot = frames_to_quat(ahead, normalize(up))
    ground = pos[..., 1] - clearance
    return Trajectory(times=times, spine_positions=pos, spine_rotations=rot,
                      head_surface_normal=normalize(up[:, 0]), ground_heights=ground,
                      events=({"start": 0.0, "end": float(seconds), "state": "wander",
                               "details": {"target": [0.1, 0.0, 1.0]}},))


@pytest.fixture(scope="session")
def trajectory(rig) -> Trajectory:
    return sine_trajectory(rig.spacing, len(rig.spine), clearance=rig.config.body.clearance)


@pytest.fixture(scope="session")
def clip(trajectory, rig):
    from baker.clip import build_clip

    return build_clip(trajectory, rig)


@pytest.fixture(scope="session")
def bake_extras() -> dict:
    return {"seed": np.int64(7), "rig": "scolopendra", "fps": 30,
            "spacing": np.float32(0.0125), "events": [], "note": None,
            "timeline": [{"state": "wander", "start": 0.0, "end": 3.0}]}
