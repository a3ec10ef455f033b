"""Random streams of a bake, one per subsystem, all made from the bake's `--seed`.

Each stream is a `np.random.Generator` on its own `SeedSequence(seed, spawn_key=...)`
child, addressed by name and index rather than by the order of creation (as
`SeedSequence.spawn` would do). A subsystem's draws therefore never shift another's: adding a
prey leaves every wander target the brain draws before it sees the prey unchanged, and a
creature added to a crowd leaves the others' choices alone. The same seed gives the same
streams, so the same bytes.
"""

from __future__ import annotations

import numpy as np

#: subsystem -> first spawn-key word. Never renumber: that would change every bake's output.
SUBSYSTEMS = {
    "start": 0,    # start point and heading (run.start.choose_start)
    "brain": 1,    # the d10 rolls, wander targets and shade spot choices (behaviour.brain)
    "gait": 2,     # gait phase jitter (reserved: today's gait is deterministic)
    "prey": 3,     # index: the prey's number; its spawn point and flee targets
}


class Streams:
    """The bake's random streams for one creature (index 0 for a single creature)."""

    def __init__(self, seed: int, creature: int = 0):
        self.seed = int(seed)
        self.creature = int(creature)

    def get(self, name: str, index: int = 0) -> np.random.Generator:
        """A fresh generator for subsystem `name` (number `index` of its kind: a prey's
        number). Asking twice gives two generators with the same sequence."""
        key = (self.creature, SUBSYSTEMS[name], int(index))
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=key))
