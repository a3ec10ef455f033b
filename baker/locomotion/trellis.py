"""The cheapest path through a trellis: one sample per layer, node and edge costs (Viterbi).

swing.py's last resort for a swing that still breaks a limit samples many leg poses at each of
its frames (the layers) and looks for the sequence that keeps every frame clear and every
step between frames within the turn limit. The search itself is plain dynamic programming over
layers; the costs come from the caller.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def cheapest_path(node_cost: list[np.ndarray],
                  edge_cost: Callable[[int], np.ndarray]) -> tuple[np.ndarray, float]:
    """(the chosen sample of each layer (K,) int, the path's total cost).

    node_cost : K arrays, (n_k,) the cost of each sample of layer k
    edge_cost : k -> (n_k, n_{k+1}) the cost of going from each sample of layer k to each of
                layer k + 1
    Ties keep the lowest sample index, so a path is reproducible.
    """
    total = np.asarray(node_cost[0], dtype=np.float64)
    back = []
    for k in range(1, len(node_cost)):
        through = total[:, None] + edge_cost(k - 1)
        came = np.argmin(through, axis=0)
        back.append(came)
        total = through[came, np.arange(through.shape[1])] + node_cost[k]
    pick = [int(np.argmin(total))]
    for came in reversed(back):
        pick.append(int(came[pick[-1]]))
    return np.array(pick[::-1]), float(total.min())
