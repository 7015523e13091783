"""The last guard of every command (cosim-orchestrate, cosim-node, cosim-sweep): an exception
nobody expected leaves with an exit code of its own, never with one that means something
else (1 is "the goal was not met", 3 "a node failed").

What the user can fix is checked at load time and exits 2 with a message naming it; what is
left is cosim's fault. It exits ``EXIT_INTERNAL_ERROR`` (70, EX_SOFTWARE in sysexits.h),
prints the traceback and says where a copy of it was written, to go with a report.
"""

from __future__ import annotations

import functools
import os
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable
from pathlib import Path

EXIT_INTERNAL_ERROR = 70
EXIT_INTERRUPTED = 130

Main = Callable[[list[str] | None], int]


def interruptible() -> None:
    """Make SIGINT and SIGTERM end this command as Ctrl-C does (KeyboardInterrupt: exit 130,
    outputs kept), even where it was started with them ignored or blocked (a script's
    background job, a test runner's worker): the exit code is part of the command's contract.
    Main thread only."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _raise_interrupt)


def _raise_interrupt(signum, _frame):
    raise KeyboardInterrupt


def guarded(prog: str) -> Callable[[Main], Main]:
    """Decorate a command's ``main(argv)``: what escapes it becomes an exit code that says
    so (Ctrl-C 130, anything else :data:`EXIT_INTERNAL_ERROR` with the traceback kept)."""
    def wrap(main: Main) -> Main:
        @functools.wraps(main)
        def entry(argv: list[str] | None = None) -> int:
            try:
                return main(argv)
            except SystemExit:  # argparse's exit 2 on a bad option, or an explicit exit
                raise
            except KeyboardInterrupt:
                print(f"{prog}: interrupted", file=sys.stderr)
                return EXIT_INTERRUPTED
            except Exception as exc:  # noqa: BLE001 - the point: nothing leaves with code 1
                return internal_error(prog, exc)
        return entry
    return wrap


def internal_error(prog: str, exc: BaseException) -> int:
    """Report ``exc`` as cosim's own fault: the traceback on stderr and in a file, a last line
    naming both; returns :data:`EXIT_INTERNAL_ERROR`."""
    text = "".join(traceback.format_exception(exc))
    where = _keep(prog, text)
    print(text, file=sys.stderr, end="")
    kept = f"the traceback above is also in {where}" if where else "the traceback is above"
    print(f"{prog}: internal error (exit {EXIT_INTERNAL_ERROR}): {type(exc).__name__}: {exc}. "
          f"This is a fault of cosim, not of your scenario or options; {kept}: please "
          "report it with that file.", file=sys.stderr, flush=True)
    return EXIT_INTERNAL_ERROR


def _keep(prog: str, text: str) -> Path | None:
    """Write the traceback to a file of its own in the temporary directory; None if even
    that fails (a full disk)."""
    try:
        fd, name = tempfile.mkstemp(prefix=f"{prog}-internal-error-{os.getpid()}-",
                                    suffix=".txt")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        return Path(name)
    except OSError:
        return None
