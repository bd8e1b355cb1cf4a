"""Visualisation of a solved :class:`geoddp.result.Result`.

Reads Results only; never imports the solver.

- :func:`replay`: live meshcat viewer (loopback server), time-synchronised animation.
- :func:`export_html`: self-contained static HTML replay (no server, no network).
- :func:`plot_trajectory`, :func:`plot_convergence`: matplotlib PNG figures.
"""
from .figures import FigureData, plot_convergence, plot_trajectory
from .html import animation_frame_count, export_html
from .meshcat_replay import ViewerUnavailable, build_satellite, replay

__all__ = [
    "FigureData",
    "ViewerUnavailable",
    "animation_frame_count",
    "build_satellite",
    "export_html",
    "plot_convergence",
    "plot_trajectory",
    "replay",
]
