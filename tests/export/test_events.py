"""Per-clip events (baker/export/events.py): the committed JSON Schema, contact intervals and
behaviour changes, and the events a real bake writes into each glTF animation's extras and each
USD SkelAnimation's customData."""

import json

import numpy as np
import pytest

from baker.export.events import (SCHEMA_FILE, ClipEvents, behaviour_events, clip_events,
                                 contact_intervals, marker, schema_text)


def test_the_committed_schema_is_the_models_schema():
    assert SCHEMA_FILE.read_text() == schema_text(), \
        "docs/clip_events.schema.json is stale: regenerate it from baker.export.events.schema_text()"


def test_contact_intervals_are_half_open_and_cover_both_ends():
    c = np.array([[1, 0], [1, 0], [0, 1], [0, 1], [1, 1], [1, 0]], dtype=bool)
    assert contact_intervals(c, ["a_foot", "b_foot"]) == {
        "a_foot": [[0, 2], [4, 6]], "b_foot": [[2, 5]]}
    with pytest.raises(ValueError):
        contact_intervals(c, ["a_foot"])


def test_behaviour_events_are_the_states_of_the_clip_frames():
    timeline = [{"start": 0.0, "end": 1.0, "state": "wander", "details": {"t": 1}},
                {"start": 1.0, "end": 2.0, "state": "hunt"},
                {"start": 2.0, "end": 3.0, "state": "feed"}]
    full = behaviour_events(timeline, 10, 0, 31)
    assert [(e["frame"], e["state"]) for e in full] == [(0, "wander"), (10, "hunt"), (20, "feed")]
    part = behaviour_events(timeline, 10, 15, 21)        # frames 15..20 of the bake
    assert [(e["frame"], e["state"]) for e in part] == [(0, "hunt"), (5, "feed")]
    assert part[1]["time"] == pytest.approx(0.5)


def test_clip_events_validate_and_sort():
    doc = clip_events(30, 61, contacts=np.ones((100, 1), bool), feet=["x_foot"], f0=40,
                      timeline=[{"start": 0.0, "end": 4.0, "state": "idle"}],
                      markers=[marker("loop_end", 60, 30), marker("loop_start", 0, 30)], loop=True)
    ClipEvents.model_validate(doc)
    assert doc["contacts"] == {"x_foot": [[0, 60]]}
    assert [(e["frame"], e["type"]) for e in doc["events"]] == [
        (0, "behaviour"), (0, "marker"), (60, "marker")]
    assert doc["duration"] == pytest.approx(2.0) and doc["loop"] is True
    with pytest.raises(Exception):
        ClipEvents.model_validate({**doc, "events": [{"frame": -1, "time": 0, "type": "marker",
                                                      "name": "x"}]})


@pytest.fixture(scope="module")
def bake_with_clips(tmp_path_factory, nav_cache_dir):
    from baker.config import BakeConfig
    from baker.pipeline import bake

    out = tmp_path_factory.mktemp("events") / "ev"
    return bake(BakeConfig(seconds=6.0, seed=3, prey=1, clips=True, out=out,
                           nav_cache_dir=nav_cache_dir))


def test_every_clip_of_a_bake_carries_its_events(bake_with_clips):
    from pxr import Usd

    res = bake_with_clips
    data = res.outputs["glb"].read_bytes()
    doc = json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])
    anims = doc["animations"]
    assert len(anims) >= 2
    contacts = res.trajectory.foot_contacts
    stage = Usd.Stage.Open(str(res.outputs["usd"]))
    for a in anims:
        ev = ClipEvents.model_validate(a["extras"]).model_dump(by_alias=True)
        assert ev == a["extras"]
        frames = int(round(max(doc["accessors"][s["input"]]["max"][0] for s in a["samplers"])
                           * 30)) + 1
        assert ev["frames"] == frames
        assert ev["events"][0]["frame"] == 0 and ev["events"][0]["type"] == "behaviour"
        # the intervals rebuild the trajectory's contacts over the clip's frames
        t0 = 0.0 if a["name"] == "bake" else next(
            e["start"] for i, e in enumerate(res.trajectory.events)
            if f"{e['state']}_{i:02d}" == a["name"])
        f0 = int(round(t0 * 30))
        foot = "leg_L_03_foot"
        flags = np.zeros(frames, bool)
        for d, u in ev["contacts"][foot]:
            flags[d:u] = True
        assert np.array_equal(flags, contacts[f0:f0 + frames, 4])
        # the same events in the USD
        path = "/World/Centipede/Animation" if a["name"] == "bake" \
            else f"/World/Centipede/Clips/{a['name']}"
        cd = stage.GetPrimAtPath(path).GetCustomData()
        assert json.loads(cd["events"]) == ev["events"]
        assert {k: json.loads(v) for k, v in cd["contacts"].items()} == ev["contacts"]
        assert cd["frames"] == frames and cd["schema"] == ev["schema"]
