"""Command line: ``geoddp run SCENE``, ``geoddp compare SCENE`` and ``geoddp simulate SCENE``,
where SCENE is a scene file (satellite or multibody) or a built-in scene's name
(``satellite_paper``, ``quadrotor``, ...);
``geoddp multibody NAME`` is an alias of ``geoddp run NAME`` for the built-in multibody scenes.

Exit codes: 0 converged (a verified local minimum, see the README's status table), 1 stopped
without converging (stalled, max_iter, saddle, non-finite, ...), 2 bad input (one line on stderr,
no traceback; outputs are checked before the solve), 3 an internal error (one line; a bug to
report), 128 + N on signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP: the solve stops, the line says
which outputs were written; a sweep first writes every case that finished, and the line says how
many cases are on disk and the command that resumes it). Every output file is written atomically
(geoddp.output_files).
"""
from .commands import EXIT_BAD_INPUT, EXIT_CONVERGED, EXIT_INTERNAL, EXIT_NOT_CONVERGED
from .main import main

__all__ = ["main", "EXIT_CONVERGED", "EXIT_NOT_CONVERGED", "EXIT_BAD_INPUT", "EXIT_INTERNAL"]
