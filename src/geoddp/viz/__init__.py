"""Visualisation of a solved :class:`geoddp.solver.result.Result`.

Reads Results only; never imports the solver.

- :func:`replay`: live meshcat viewer (loopback server), time-synchronised animation.
- :func:`export_html`: self-contained static HTML replay (no server, no network).

Both go through one path (:func:`geoddp.viz.scene.build_scene`): the result's model is rebuilt
from a URDF (:mod:`geoddp.viz.model`: the multibody model of the solve, or the built-in
satellite.urdf on a spherical root) and its visuals (primitives, and DAE/STL/OBJ meshes found
through ``package_dirs``; or with ``geometry="collision"`` its collision geometry) are animated by
forward kinematics (:func:`visual_placements` gives the per-frame world placements), with the
target pose as a translucent ghost, frame targets as triads, an optional ``trail`` and a camera
framing the whole trajectory.

- :func:`plot_trajectory`, :func:`plot_convergence`: matplotlib PNG figures of a satellite result and
  of several solves' convergence; :func:`plot_multibody`: a multibody result's joints, controls,
  frame-target errors and solver history; :func:`plot_solver_history`: any result's cost and
  gradient norm per iteration; :func:`plot_keep_out`: a body axis's path on the sphere around a
  pointing keep-out cone; :func:`plot_simulation`: the Monte Carlo bundles and error
  histograms.
- :func:`export_legged_html`, :func:`replay_legged`: a legged robot's replay with the ground, the
  contact points and the force arrows; :func:`plot_legged`: its contact forces and friction-cone
  margins; :func:`legged_figures`: those and the multibody figures; :func:`legged_forces`: the
  forces themselves (:mod:`geoddp.viz.legged`).
"""
import warnings

# meshcat 0.3.2 imports zmq.eventloop.ioloop, which pyzmq >= 17 flags as deprecated; that is
# meshcat's business, not a warning our users can act on.
with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message="zmq.eventloop.ioloop is deprecated", category=DeprecationWarning)
    import meshcat  # noqa: F401

from .figures import FigureData, Figures, plot_convergence, plot_trajectory
from .html import animation_frame_count, export_html
from .keep_out import plot_keep_out
from .legged import LEGGED_FIGURES, export_legged_html, legged_figures, legged_forces, plot_legged, replay_legged
from .meshcat_replay import ViewerUnavailable, build_satellite, replay
from .model import load_model, load_visual_model, visual_placements
from .multibody_figures import MULTIBODY_FIGURES, plot_multibody, plot_solver_history
from .simulation import plot_simulation

__all__ = [
    "FigureData",
    "Figures",
    "LEGGED_FIGURES",
    "MULTIBODY_FIGURES",
    "ViewerUnavailable",
    "animation_frame_count",
    "build_satellite",
    "export_html",
    "export_legged_html",
    "legged_figures",
    "legged_forces",
    "load_model",
    "load_visual_model",
    "plot_convergence",
    "plot_keep_out",
    "plot_legged",
    "plot_multibody",
    "plot_simulation",
    "plot_solver_history",
    "plot_trajectory",
    "replay",
    "replay_legged",
    "visual_placements",
]
