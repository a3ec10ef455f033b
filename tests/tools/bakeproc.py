"""Run `python -m baker` as a real subprocess for the output and signal tests: wait for the
test hook's markers (baker/signals.py: BAKER_TEST_PAUSE_AT, BAKER_TEST_MARKS), send signals,
and collect the exit code, stderr and the child's peak memory.

Peak memory is the child's VmHWM (/proc/<pid>/status), sampled until it exits: the rusage of
a child started from pytest is no use, since its ru_maxrss keeps the high-water mark of the
(large) pytest process it was forked from."""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

#: A marker that never comes within this long means the test hook is broken (not a timing
#: limit on the bake: every wait is for an event the bake announces).
MARKER_WAIT_S = 300.0


@dataclass
class Done:
    code: int
    stdout: str
    stderr: str
    peak_mb: float

    @property
    def err_lines(self) -> list[str]:
        return [ln for ln in self.stderr.splitlines() if ln.strip()]


class Bake:
    """A `baker` subprocess; stdout is read line by line to see the hook's markers."""

    def __init__(self, args, *, pause_at: str | None = None, marks: bool = False, cwd=None):
        env = dict(os.environ)
        env.pop("BAKER_TEST_PAUSE_AT", None)
        env.pop("BAKER_TEST_MARKS", None)
        if pause_at:
            env["BAKER_TEST_PAUSE_AT"] = pause_at
        if marks:
            env["BAKER_TEST_MARKS"] = "1"
        env["PYTHONUNBUFFERED"] = "1"
        self.proc = subprocess.Popen([sys.executable, "-m", "baker", *map(str, args)], cwd=cwd,
                                     env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.out_lines: list[str] = []
        self._sel = selectors.DefaultSelector()
        self._sel.register(self.proc.stdout, selectors.EVENT_READ)
        self.peak_kb = 0
        self._watch = threading.Thread(target=self._sample_peak, daemon=True)
        self._watch.start()

    def _sample_peak(self):
        status = Path(f"/proc/{self.proc.pid}/status")
        while self.proc.returncode is None:
            try:
                for line in status.read_text().splitlines():
                    if line.startswith("VmHWM:"):
                        self.peak_kb = max(self.peak_kb, int(line.split()[1]))
            except (OSError, ValueError, IndexError):
                pass
            time.sleep(0.02)

    def wait_marker(self, phase: str) -> bool:
        """Read stdout until `baker-test: at <phase>`; False when the process ended first."""
        want = f"baker-test: at {phase}"
        end = time.monotonic() + MARKER_WAIT_S
        while time.monotonic() < end:
            if any(ln.strip() == want for ln in self.out_lines):
                return True
            if not self._sel.select(timeout=0.5):
                if self.proc.poll() is not None:
                    return False
                continue
            line = self.proc.stdout.readline()
            if not line:
                return False
            self.out_lines.append(line.decode(errors="replace"))
        raise AssertionError(f"no marker {want!r}")

    def signal(self, sig) -> None:
        self.proc.send_signal(sig)

    def wait(self) -> Done:
        out = self.proc.stdout.read().decode(errors="replace")
        err = self.proc.stderr.read().decode(errors="replace")
        self.proc.wait()
        self._watch.join()
        self.proc.stdout.close()
        self.proc.stderr.close()
        return Done(self.proc.returncode, "".join(self.out_lines) + out, err,
                    self.peak_kb / 1024.0)


def run(args, **kw) -> Done:
    return Bake(args, **kw).wait()


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every entry of `folder` (hidden ones too): name -> bytes (b'<dir>' for folders)."""
    return {p.name: (p.read_bytes() if p.is_file() else b"<dir>")
            for p in sorted(Path(folder).iterdir())}


def seeds_of(out: Path) -> dict[str, int]:
    """The seed recorded in each output of `out` (path without extension): json, glb, usd."""
    from pxr import Usd

    seeds = {"json": json.loads(out.with_suffix(".json").read_text())["seed"]}
    data = out.with_suffix(".glb").read_bytes()
    n = int.from_bytes(data[12:16], "little")
    gl = json.loads(data[20:20 + n])
    seeds["glb"] = gl["scenes"][0]["extras"]["seed"]
    stage = Usd.Stage.Open(str(out.with_suffix(".usd")))
    seeds["usd"] = stage.GetPrimAtPath("/World").GetCustomData()["seed"]
    return seeds
