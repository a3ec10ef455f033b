"""A crowd's followers stepped in groups at once: one in this process, the others on forked
peer processes (baker.parallel.Peer), so that a crowd's run uses the cores (--workers).

Within a step of the crowd's run (run.crowd.run_crowd), the brains decide one after another
(they share the claims on shade spots and prey), and then each follower walks its creature's
intent (Follower.apply, Follower.step). The followers' steps read nothing another follower's
step writes: each reads its own state, the navigation surface, the rays and the other bodies'
points handed to it before the step. So they can be shared between processes, and each gives
the same bits wherever it runs: the files are the same bytes whatever --workers.

After each step the run reads every follower's state from one array (`States`): its head
point, heading, whether its agent has arrived, the head's speed and slither phase, and its
replans.

A lazily built navigation surface (navmesh.lazy.LazyNav) grows its window with the queries it
is asked, so the followers of a crowd on one are stepped in this process only: two processes
would grow different windows.
"""

from __future__ import annotations

import numpy as np

import logging

from baker.parallel import Peer, available_cpus, can_fork
from baker.run.follow import Follower, measure_levers

log = logging.getLogger(__name__)

#: the fewest followers a process steps: smaller crowds are stepped in this process (a step's
#: exchange with a peer costs about what a few followers' steps do)
PER_PROCESS = 4
#: the most processes a run uses: the brains, the neighbours and the prey are this process's
#: alone, a quarter or more of a step, so more would mostly wait (and poll)
MAX_PROCESSES = 8
#: the columns of a follower's state row
_COLUMNS = 10


class States:
    """Every follower's state after the last step, (n, _COLUMNS) float64 rows: position (3),
    heading (3), arrived, the head's speed and slither phase, replans."""

    def __init__(self, n: int):
        self.rows = np.zeros((n, _COLUMNS))

    @property
    def positions(self) -> np.ndarray:
        return self.rows[:, 0:3]

    @property
    def speeds(self) -> np.ndarray:
        return self.rows[:, 7]

    def phase(self, i: int) -> float:
        return float(self.rows[i, 8])

    def replans(self, i: int) -> int:
        return int(self.rows[i, 9])


def state_rows(follows: list[Follower]) -> np.ndarray:
    """(len(follows), _COLUMNS) the rows of States for these followers."""
    out = np.empty((len(follows), _COLUMNS))
    for r, f in enumerate(follows):
        h = f.head
        out[r, 0:3] = f.position
        out[r, 3:6] = h.heading
        out[r, 6:] = (f.agent.arrived, h.speed, h.phase, f.replans)
    return out


class Group:
    """Some of the crowd's followers (`rows`: their creatures), stepped together."""

    def __init__(self, follows: list[Follower], rows, dt: float):
        self.rows = np.asarray(rows, dtype=np.intp)
        self.follows = [follows[i] for i in self.rows]
        self.dt = dt
        self.intents = [None] * len(self.rows)

    def step(self, request: tuple) -> np.ndarray:
        """One step: request = (intents, others). intents: {k: Intent} for the group's k-th
        follower whose intent is new (the rest keep theirs); others: None (as they were) or,
        for every follower of the group, (other bodies' points near its head or None, whether
        their creatures all walk). Returns the followers' state rows."""
        intents, others = request
        for k, intent in intents.items():
            self.intents[k] = intent
        if others is not None:
            for f, (pts, moving) in zip(self.follows, others):
                f.others, f.others_move = pts, moving
        measure_levers(self.follows)      # the legs' levers these steps measure, in one batch
        for f, intent in zip(self.follows, self.intents):
            f.apply(intent)
            f.step(self.dt)
        return state_rows(self.follows)


class Followers:
    """All of a crowd's followers, in one group here and, with two or more workers, one more
    on each of up to workers - 1 peer processes (one per CPU, at least PER_PROCESS followers
    each, at most MAX_PROCESSES processes; the creatures dealt out in turn).
    `step(intents, others)` steps every one; `states` then holds their rows."""

    def __init__(self, follows: list[Follower], dt: float, workers: int = 1, lazy: bool = False):
        n = len(follows)
        self.states = States(n)
        self.states.rows[:] = state_rows(follows)
        self._sent = [None] * n
        groups = 1
        if not lazy and can_fork():
            groups = max(1, min(int(workers), available_cpus(), n // PER_PROCESS,
                                MAX_PROCESSES))
        which = np.arange(n) % groups          # each process waits for the slowest: an even deal
        here = np.flatnonzero(which == 0)
        self.far, self.peers = [], []
        try:
            for g in range(1, groups):
                rows = np.flatnonzero(which == g)
                try:
                    self.peers.append(Peer(Group(follows, rows, dt).step, share=groups))
                    self.far.append(rows)
                except OSError as e:        # no more processes, or no memory for one
                    log.warning("a worker process could not start (%s): its %d creatures "
                                "step in this one", e.strerror or e, len(rows))
                    here = np.union1d(here, rows)
        except BaseException:
            self.close()
            raise
        self.near = Group(follows, here, dt)

    def step(self, intents: list, others: list | None) -> None:
        """Step every follower by its creature's intent; `others`: None, or every creature's
        (points, moving) (Group.step)."""
        for peer, rows in zip(self.peers, self.far):
            peer.send(self._request(rows, intents, others))
        near = self.near.step(self._request(self.near.rows, intents, others))
        self.states.rows[self.near.rows] = near
        for peer, rows in zip(self.peers, self.far):
            self.states.rows[rows] = peer.receive()

    def _request(self, rows: np.ndarray, intents: list, others: list | None) -> tuple:
        new = {}
        for k, i in enumerate(rows.tolist()):
            if intents[i] is not self._sent[i]:
                new[k] = self._sent[i] = intents[i]
        return new, None if others is None else [others[i] for i in rows.tolist()]

    def close(self) -> None:
        for peer in self.peers:
            peer.close()
        self.peers = []
