"""What a crowd's creatures compete for (issue 15): a shade spot holds one creature, a prey has
one hunter. One Claims is shared by every brain of a crowd (run.crowd); a lone creature has
none, and its brain behaves as it always has."""

from __future__ import annotations

import numpy as np


class Claims:
    """Shade spots and prey held by creatures (numbered 0..n-1).

    spot_radius : [m] a held spot covers this far around its point (behaviour's
                  shade_spot_spacing: remembered spots are at least this far apart)
    """

    def __init__(self, spot_radius: float):
        self.spot_radius = float(spot_radius)
        self._spots: dict[int, np.ndarray] = {}    # creature -> the spot it goes to or rests in
        self._prey: dict[str, int] = {}            # prey name -> its hunter

    def spot_taken(self, p: np.ndarray, who: int) -> bool:
        """True when another creature holds a spot within spot_radius of p."""
        r2 = self.spot_radius ** 2
        return any(w != who and float(np.sum((q - p) ** 2)) < r2 for w, q in self._spots.items())

    def take_spot(self, who: int, p: np.ndarray) -> None:
        self._spots[who] = np.asarray(p, dtype=np.float64).copy()

    def free_spot(self, who: int) -> None:
        self._spots.pop(who, None)

    def hunter(self, prey: str) -> int | None:
        return self._prey.get(prey)

    def take_prey(self, who: int, prey: str) -> None:
        self._prey[prey] = who

    def free_prey(self, who: int) -> None:
        for name in [n for n, w in self._prey.items() if w == who]:
            del self._prey[name]
