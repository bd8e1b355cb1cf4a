"""Visualisation of a solved :class:`geoddp.result.Result` (reads it, never calls the solver)."""
