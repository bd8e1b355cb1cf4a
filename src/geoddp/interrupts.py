"""Interruptions (SIGINT, SIGTERM, SIGHUP) that Python could not deliver as an exception.

The CLI turns these signals into :class:`Interrupted`, raised from its signal handler, so every
cleanup path runs. But Python drops an exception raised while a garbage-collector callback or a
``__del__`` method runs ("Exception ignored in ..."), and Dask's client installs such a callback
(``distributed.gc.GCDiagnosis``): a Ctrl-C landing there was lost, and a sweep ran on to its end
(seen once in CI: tests/test_sweep_dask.py). The handler therefore also records the signal here,
and long loops call :func:`check` at their safe points, which raises it again.

Work that must finish once an interruption has begun (writing the finished rows of a sweep) runs
in :func:`deferred`: a further signal there is recorded, not raised, so a second Ctrl-C cannot
cut the write short.

This module imports nothing from geoddp.
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["Interrupted", "record", "clear", "check", "received", "deferred", "deferring"]

_RECEIVED: list[int] = []
_DEFERRING = 0  # depth of nested deferred() blocks


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP during a run (a KeyboardInterrupt, so every cleanup path runs).

    ``note``: what the run left behind, for the exit message (e.g. the rows a sweep wrote), or "".
    """

    def __init__(self, signum: int, note: str = "") -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.note = note


def record(signum: int) -> None:
    """Note that signal ``signum`` arrived (the CLI's handler, before it raises)."""
    _RECEIVED.append(int(signum))


def clear() -> None:
    """Forget earlier signals (at the start of a CLI run)."""
    _RECEIVED.clear()


def received() -> list[int]:
    """The signals recorded since :func:`clear`, oldest first."""
    return list(_RECEIVED)


def check() -> None:
    """Raise :class:`Interrupted` for the first recorded signal, if any: at a loop's safe point,
    an interruption whose exception was swallowed (or not yet seen) ends the run there."""
    if _RECEIVED:
        raise Interrupted(_RECEIVED[0])


def deferring() -> bool:
    """True inside :func:`deferred`: a signal handler should record the signal and return."""
    return _DEFERRING > 0


@contextmanager
def deferred() -> Iterator[None]:
    """Run the block to its end whatever signal arrives: the CLI's handler only records signals
    while :func:`deferring`, and Python's own SIGINT handler (a library user's Ctrl-C) is replaced
    for the block by one that notes the signal. A signal noted in the block is raised when it
    ends (unless the block is already ending by an exception, an interruption being handled)."""
    global _DEFERRING
    first = len(_RECEIVED)
    noted: list[int] = []
    swapped = None
    main = threading.current_thread() is threading.main_thread()
    if main and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        swapped = signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    _DEFERRING += 1
    try:
        yield
    finally:
        _DEFERRING -= 1
        if swapped is not None:
            signal.signal(signal.SIGINT, swapped)
    if noted:
        raise KeyboardInterrupt
    if len(_RECEIVED) > first:
        raise Interrupted(_RECEIVED[first])
