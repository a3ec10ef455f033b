"""Per-clip animation events: foot contacts, behaviour changes and markers, in one documented
schema (docs/clip_events.schema.json, generated from the models below).

Every clip the project writes carries them: in its glTF animation's `extras` and in its USD
SkelAnimation's `customData` (there `contacts` and `events` are JSON strings: USD dictionaries
hold no lists of lists). Frames are the clip's own (time = frame / fps, from the clip's start):

    {"schema": "baker.clip_events/1", "fps": 30, "frames": 181, "duration": 6.0, "loop": false,
     "contacts": {"leg_L_01_foot": [[0, 12], [20, 33], ...], ...},
     "events": [{"frame": 0, "time": 0.0, "type": "behaviour", "state": "wander", ...},
                {"frame": 180, "time": 6.0, "type": "marker", "name": "loop_end"}, ...]}

`contacts` lists, per foot end joint, its planted intervals [down, up): the foot touches down at
frame `down` and is in the air again at frame `up` (`up` == frames when it is still planted at
the clip's end). The state at frame 0 gets a `behaviour` event, so each clip's events stand on
their own. Events are sorted by frame, then by type and name.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

SCHEMA_ID = "baker.clip_events/1"
#: the committed JSON Schema (tests check it matches the models)
SCHEMA_FILE = Path(__file__).resolve().parents[2] / "docs" / "clip_events.schema.json"


class _Event(BaseModel):
    model_config = ConfigDict(extra="forbid")
    frame: int = Field(ge=0, description="frame index in the clip")
    time: float = Field(ge=0, description="[s] from the clip's start, frame / fps")


class BehaviourEvent(_Event):
    """The brain's state from this frame on (wander, shade, hunt, strike, feed, warning, ...)."""
    type: Literal["behaviour"]
    state: str
    details: dict = Field(default_factory=dict, description="state-specific data (targets...)")


class MarkerEvent(_Event):
    """A named time: `loop_start` / `loop_end` on looping cycles, phases of one-shots."""
    type: Literal["marker"]
    name: str


Event = Annotated[Union[BehaviourEvent, MarkerEvent], Field(discriminator="type")]
Interval = Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=2, max_length=2)]


class ClipEvents(BaseModel):
    """The events of one animation clip (glTF animation extras / USD SkelAnimation customData)."""
    model_config = ConfigDict(extra="forbid", title="baker clip events")
    schema_: Literal["baker.clip_events/1"] = Field(alias="schema")
    fps: int = Field(gt=0, description="[Hz] frame rate of `frame`")
    frames: int = Field(gt=0, description="frames in the clip, both ends included")
    duration: float = Field(ge=0, description="[s] (frames - 1) / fps")
    loop: bool = Field(description="the clip repeats seamlessly: its last frame equals its first")
    contacts: dict[str, list[Interval]] = Field(
        description="per foot end joint, planted intervals [down, up) in frames")
    events: list[Event]


def json_schema() -> dict:
    """The JSON Schema of ClipEvents (what docs/clip_events.schema.json holds)."""
    s = ClipEvents.model_json_schema(by_alias=True)
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = SCHEMA_ID
    return s


def schema_text() -> str:
    return json.dumps(json_schema(), indent=2, sort_keys=True) + "\n"


def contact_intervals(contacts: np.ndarray, feet) -> dict[str, list[list[int]]]:
    """{foot: [[down, up), ...]} of contacts (F, L) bool (planted per frame and leg, the clip's
    own frames) for the L foot joint names `feet`."""
    c = np.asarray(contacts, dtype=np.int8)
    if c.ndim != 2 or c.shape[1] != len(feet):
        raise ValueError(f"contacts {c.shape} do not match {len(feet)} feet")
    pad = np.zeros((1, c.shape[1]), np.int8)
    d = np.diff(np.concatenate([pad, c, pad]), axis=0)
    out = {}
    for k, name in enumerate(feet):
        down, up = np.nonzero(d[:, k] > 0)[0], np.nonzero(d[:, k] < 0)[0]
        out[str(name)] = [[int(a), int(b)] for a, b in zip(down, up)]
    return out


def behaviour_events(timeline, fps: int, f0: int, f1: int) -> list[dict]:
    """behaviour events for the frames [f0, f1) of a bake whose timeline is a list of
    {"start": s, "end": s, "state": str, "details": {...}} (seconds from the bake's start)."""
    out = []
    for e in timeline:
        a, b = int(round(e["start"] * fps)), int(round(e["end"] * fps))
        if a >= f1 or (b <= f0 and not a == b == f0):
            continue
        f = max(a, f0) - f0
        out.append({"frame": f, "time": float(np.float32(f / fps)), "type": "behaviour",
                    "state": str(e["state"]), "details": dict(e.get("details") or {})})
    return out


def marker(name: str, frame: int, fps: int) -> dict:
    return {"frame": int(frame), "time": float(np.float32(frame / fps)), "type": "marker",
            "name": name}


def clip_events(fps: int, frames: int, *, contacts=None, feet=(), timeline=(), f0: int = 0,
                markers=(), loop: bool = False) -> dict:
    """The events dict of a clip of `frames` frames that starts at frame f0 of the bake.

    contacts : (F, L) bool over the whole bake (or None), feet the L foot joint names
    timeline : the bake's behaviour timeline (see behaviour_events)
    markers  : extra marker events (see marker), in clip frames
    """
    events = list(markers) + behaviour_events(timeline, fps, f0, f0 + frames)
    events.sort(key=lambda e: (e["frame"], e["type"], e.get("name", e.get("state", ""))))
    feet_down = {} if contacts is None or not len(feet) else contact_intervals(
        np.asarray(contacts)[f0:f0 + frames], feet)
    doc = {"schema": SCHEMA_ID, "fps": int(fps), "frames": int(frames),
           "duration": float(np.float32((frames - 1) / fps)), "loop": bool(loop),
           "contacts": feet_down, "events": events}
    ClipEvents.model_validate(doc)
    return doc
