"""Console entry point (`baker = "baker.entry:main"`).

It installs the SIGINT/SIGTERM handlers (baker/signals.py) before anything heavy is imported,
then imports the CLI lazily, so Ctrl-C at any moment, even while numpy is still being imported,
gives one line on stderr and exit code 130 (SIGTERM: 143) instead of a traceback.
"""

from __future__ import annotations

import sys


def main(argv=None) -> int:
    from baker import signals

    signals.install()
    try:
        signals.checkpoint("start")
        with signals.deferred():    # a signal here is raised once the import is complete
            from baker.cli import main as cli_main

        code = cli_main(argv)
        if signals.stopping():      # a signal whose Interrupted a library swallowed
            raise signals.Interrupted(signals.stopping(), signals.phase())
        signals.finished()          # done: a signal now changes nothing
        return code
    except BaseException as exc:
        # An Interrupted, or what a library made of it (some catch BaseException around
        # optional imports and fail later): either way the process is stopping on a signal.
        if isinstance(exc, signals.Interrupted):
            e = exc
        elif signals.stopping() and not isinstance(exc, SystemExit):
            e = signals.Interrupted(signals.stopping(), signals.phase())
        else:
            raise
        where = f"during {e.phase if e.phase != 'start' else 'startup'}"
        try:
            sys.stderr.write(f"Error: interrupted by {e.name} ({where})\n")
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        if signals.native_busy():   # a USD read still running: finalization would crash
            signals.exit_now(e.exit_code)
        return e.exit_code


if __name__ == "__main__":
    sys.exit(main())
