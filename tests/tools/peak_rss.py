"""Run a Python module as __main__ and, at exit, write the process's peak resident memory
(VmHWM from /proc/self/status, in bytes) to the file named by $PEAK_RSS_FILE.

    python tests/tools/peak_rss.py baker.cli bake ...

getrusage's ru_maxrss is no good for a child of a big process: Linux carries the parent's
high-water mark across fork and exec, so a child of a 2 GB pytest reports at least 2 GB.
VmHWM belongs to the process's own address space, which exec makes new."""

import atexit
import os
import runpy
import sys


def peak_rss_bytes() -> int:
    """VmHWM of this process, bytes (0 where /proc is missing)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _write():
    target = os.environ.get("PEAK_RSS_FILE")
    if target:
        with open(target, "w") as fh:
            fh.write(str(peak_rss_bytes()))


if __name__ == "__main__":
    atexit.register(_write)
    module = sys.argv[1]
    sys.argv = [module, *sys.argv[2:]]
    runpy.run_module(module, run_name="__main__", alter_sys=True)
