"""``geoddp`` itself: parse, run the command, map what ended it to an exit code and one line."""
from __future__ import annotations

import signal
import sys

from .. import interrupts
from ..interrupts import Interrupted
from ..validate import InputError
from .commands import COMMANDS, EXIT_BAD_INPUT, EXIT_INTERNAL, WRITTEN
from .parser import parser


def _on_signal(signum, frame) -> None:
    # recorded first: if the exception lands in a gc callback, Python drops it, and the sweep's
    # loop raises it again from the record (geoddp.interrupts)
    interrupts.record(signum)
    if not interrupts.deferring():  # else: finished work is being written; raised when that ends
        raise Interrupted(signum)


MAX_MESSAGE = 2000  # characters of an error line; a message quoting a huge value keeps its two ends


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if len(text) > MAX_MESSAGE:  # the start names the parameter, the end the file: both kept
        cut = len(text) - MAX_MESSAGE
        text = f"{text[:MAX_MESSAGE // 2]} [... {cut} characters ...] {text[-MAX_MESSAGE // 2:]}"
    return text


def _written() -> str:
    return "wrote " + ", ".join(WRITTEN) if WRITTEN else "no output written"


def main(argv: list[str] | None = None) -> int:
    """Run ``geoddp`` with ``argv`` (sys.argv[1:] when None); returns the exit code."""
    args = parser().parse_args(argv)
    WRITTEN.clear()
    interrupts.clear()
    previous = {}
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        if sig == signal.SIGINT and signal.getsignal(sig) is not signal.default_int_handler:
            continue  # SIGINT ignored (a background job) or handled by the caller: leave it so
        try:
            previous[sig] = signal.signal(sig, _on_signal)
        except (ValueError, OSError):  # not the main thread
            pass
    try:
        handler = COMMANDS[args.command]
        import numpy as np

        # Backstop: every numeric path checks finiteness itself (the solver's status, the
        # validators' messages); numpy's warnings would put lines on stderr before geoddp's own.
        with np.errstate(all="ignore"):
            return handler(args)
    except (InputError, OSError) as exc:
        # OSError: a missing, unreadable or unwritable file (the message names it)
        print(f"geoddp: error: {_one_line(exc)}" + (f" ({_written()})" if WRITTEN else ""), file=sys.stderr)
        return EXIT_BAD_INPUT
    except MemoryError:
        print("geoddp: error: out of memory (the problem is too large for this machine)"
              + (f" ({_written()})" if WRITTEN else ""), file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
        # a sweep's note: the cases on disk and the command that resumes it
        note = getattr(exc, "note", "") or _written()
        print(f"geoddp: interrupted by {signal.Signals(signum).name}; {note}", file=sys.stderr)
        return 128 + int(signum)
    except Exception as exc:  # a bug: one line, not a traceback (GEODDP_TRACEBACK=1 shows it)
        import os

        got = interrupts.received()
        if got:  # a library turned the interrupt into another exception (a meshcat/zmq call cut short)
            print(f"geoddp: interrupted by {signal.Signals(got[0]).name}; {_written()}", file=sys.stderr)
            return 128 + int(got[0])

        if os.environ.get("GEODDP_TRACEBACK"):
            raise
        print(f"geoddp: internal error: {type(exc).__name__}: {_one_line(exc)}; {_written()}", file=sys.stderr)
        return EXIT_INTERNAL
    finally:
        viewer = sys.modules.get("geoddp.viz.meshcat_replay")
        if viewer is not None:  # --view: no meshcat server outlives the run, whatever ended it
            viewer.stop_servers()
        for sig, h in previous.items():
            signal.signal(sig, h)
        interrupts.clear()  # a record outliving the run would stop a later sweep in this process
