"""Run context: logging, per-stage timers (which end up in the report) and progress display."""

from __future__ import annotations

import logging
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

from baker.signals import checkpoint

log = logging.getLogger("baker")


@dataclass
class Context:
    """Carries timers and a progress callback through one bake. Not shared between bakes.

    progress : callable(stage: str, fraction: float) or None; the CLI draws a bar on a terminal
    """

    progress: Callable[[str, float], None] | None = None
    timings: dict[str, float] = field(default_factory=dict)
    notes: dict[str, object] = field(default_factory=dict)
    _t0: float = field(default_factory=time.perf_counter)

    @contextmanager
    def stage(self, name: str):
        """Time a named stage; repeated names accumulate."""
        checkpoint(name)
        log.debug("stage %s: start", name)
        self.report_progress(name, 0.0)
        t = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t
            self.timings[name] = self.timings.get(name, 0.0) + dt
            log.debug("stage %s: %.3f s", name, dt)
        self.report_progress(name, 1.0)

    def report_progress(self, stage: str, fraction: float) -> None:
        if self.progress is not None:
            self.progress(stage, fraction)

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self._t0


class TerminalProgress:
    """A one-line progress display for interactive terminals; silent when not a TTY."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.enabled = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last = ""

    def __call__(self, stage: str, fraction: float) -> None:
        if not self.enabled:
            return
        width = 24
        filled = int(round(width * min(max(fraction, 0.0), 1.0)))
        line = f"\r{stage:<12} [{'#' * filled}{'.' * (width - filled)}] {100 * fraction:5.1f}%"
        if line != self._last:
            self.stream.write(line)
            self.stream.flush()
            self._last = line

    def close(self) -> None:
        if self.enabled and self._last:
            self.stream.write("\r" + " " * len(self._last) + "\r")
            self.stream.flush()
