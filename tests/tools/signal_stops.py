"""Signals during compiled (numba) calls: a script that sends itself SIGTERMs (20 unless told) at
staggered moments while it repeats some calls, each raising in the main thread, must stop
cleanly every time (a handler that raised while numba boxed a result crashed the process; the
calls run off the main thread, parallel.off_main_thread, or return only numbers)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

_SCRIPT = '''
import os, signal, threading, numpy as np
{setup}
class Stop(BaseException):
    pass
def handler(s, frame):
    raise Stop()
signal.signal(signal.SIGTERM, handler)
stops = 0
for k in range({times}):
    try:
        threading.Timer(0.011 * (k % 7), os.kill, (os.getpid(), signal.SIGTERM)).start()
        while True:
{calls}
    except Stop:
        stops += 1
print("stops", stops)
'''


def assert_signals_stop_cleanly(setup: str, calls: str, times: int = 20) -> None:
    """Run `setup` once, then `calls` (statements) in a loop that `times` SIGTERMs interrupt;
    the script must exit 0 having stopped `times` times."""
    script = _SCRIPT.format(setup=textwrap.dedent(setup), times=times,
                            calls=textwrap.indent(textwrap.dedent(calls), " " * 12))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["stops", str(times)]
