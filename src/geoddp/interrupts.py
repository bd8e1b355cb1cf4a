"""Interruptions (SIGINT, SIGTERM, SIGHUP) that Python could not deliver as an exception.

The CLI turns these signals into :class:`Interrupted`, raised from its signal handler, so every
cleanup path runs. But Python drops an exception raised while a garbage-collector callback or a
``__del__`` method runs ("Exception ignored in ..."), and Dask's client installs such a callback
(``distributed.gc.GCDiagnosis``): a Ctrl-C landing there was lost, and a sweep ran on to its end
(seen once in CI: tests/test_sweep_dask.py). The handler therefore also records the signal here,
and long loops call :func:`check` at their safe points, which raises it again.

This module imports nothing from geoddp.
"""
from __future__ import annotations

import signal

__all__ = ["Interrupted", "record", "clear", "check", "received"]

_RECEIVED: list[int] = []


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP during a run (a KeyboardInterrupt, so every cleanup path runs)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


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
