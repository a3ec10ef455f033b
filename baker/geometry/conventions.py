"""Project-wide conventions, written once.

- Units are metres and seconds.
- Right-handed frame, +Y up (as glTF). The creature's forward axis in its rest pose is +Z,
  its left is +X (right-handed: X = Y x Z).
- Quaternions are xyzw (scipy and glTF order). Only export/usd.py converts to USD's (w, x, y, z).
- Angles are radians in code; degrees only appear in config files and on the CLI.
- Joint and node names match NAME_RE: [A-Za-z0-9_], unique, at most 63 bytes.
"""

import re

import numpy as np

UP = np.array([0.0, 1.0, 0.0])
FORWARD = np.array([0.0, 0.0, 1.0])
LEFT = np.array([1.0, 0.0, 0.0])

NAME_RE = re.compile(r"^[A-Za-z0-9_]{1,63}$")

#: Simulation step rate. Export fps must divide it (checked in config).
SIM_RATE_HZ = 240


def is_valid_name(name: str) -> bool:
    """True when `name` is a legal joint/node name for every importer we target."""
    return bool(NAME_RE.match(name)) and len(name.encode()) <= 63
