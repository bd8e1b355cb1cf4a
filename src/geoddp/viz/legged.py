"""A legged robot's solve: replay with the ground, contact points and force arrows, and figures of
its contact forces and friction-cone margins.

Everything here takes the Result of a :class:`geoddp.problem.legged.ContactProblem` solve together
with that problem (its contact schedule and node dynamics give the forces:
:func:`geoddp.problem.legged_forces.contact_forces`):

- :func:`legged_forces`: the :class:`~geoddp.problem.legged_forces.ContactForces` of the result.
- :func:`export_legged_html` / :func:`replay_legged`: the static HTML replay / the live meshcat
  replay, with the scene of :mod:`geoddp.viz.contact_shapes`.
- :func:`plot_legged`: ``contact_forces.png`` and ``friction_margin.png``;
  :func:`legged_figures`: those and the multibody figures (:func:`geoddp.viz.plot_multibody`),
  every figure of a legged result in one folder.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..output_files import output_folder
from ..problem.legged_forces import ContactForces, contact_forces
from ..solver.result import Result, as_result
from ..validate import InputError
from .contact_shapes import ContactScene
from .figures import Figures, _color, _figure
from .html import export_html
from .meshcat_replay import replay
from .multibody_figures import plot_multibody
from .scene import MAX_MESH_MB

__all__ = ["LEGGED_FIGURES", "export_legged_html", "legged_figures", "legged_forces", "plot_legged",
           "replay_legged"]

#: The figures :func:`plot_legged` writes, in order (``<name>.png``).
LEGGED_FIGURES = ("contact_forces", "friction_margin")


def legged_forces(result: Result, problem, *, mu: float | None = None, facets: int = 4) -> ContactForces:
    """The contact forces, impulses and friction-cone margins along ``result``'s trajectory
    (:func:`geoddp.problem.legged_forces.contact_forces` of its configurations, velocities and
    controls; ``mu`` None: the problem's).

    Raises:
        InputError: ``problem`` not a ContactProblem (naming ``problem``), or the result's arrays
            not the problem's shapes (naming ``configurations``, ``velocities``, ``controls``).
    """
    result = as_result(result)
    if not all(hasattr(problem, a) for a in ("nodes", "terminal_node", "dyn")):
        raise InputError("problem", f"expected a geoddp.problem.legged.ContactProblem, got {type(problem).__name__}")
    return contact_forces(problem, result.configurations, result.velocities, result.controls, mu=mu, facets=facets)


def _scene(result, problem, force_scale, impulse_scale, ground, mu) -> ContactScene:
    return ContactScene(legged_forces(result, problem, mu=mu), force_scale=force_scale, impulse_scale=impulse_scale,
                        ground=ground)


def export_legged_html(result: Result, problem, path: str | Path, *, force_scale: float = 1e-3,
                       impulse_scale: float = 1.0, ground: bool = True, mu: float | None = None,
                       scale: float = 1.0, geometry: str = "visual", trail: str | None = None,
                       max_mesh_mb: float | None = MAX_MESH_MB) -> Path:
    """Write the self-contained HTML replay of a legged ``result`` (see
    :func:`geoddp.viz.export_html`) with the ground, the contact points and the force arrows
    (:mod:`geoddp.viz.contact_shapes`).

    Args:
        result: the Result of solving ``problem``; problem: its ContactProblem.
        path: output file.
        force_scale: arrow length per newton of contact force, m/N (1e-3: 1 mm per N).
        impulse_scale: arrow length per newton second of a touch-down impulse, m/(N s).
        ground: draw the ground plane.
        mu: friction coefficient (None: the problem's); unused by the drawing, kept for the forces.
        scale, geometry, trail, max_mesh_mb: as :func:`geoddp.viz.export_html` (ANYmal's visual
            meshes are 30 MB of files: pass ``max_mesh_mb=None`` to embed them, about 16 MB of
            page, or ``geometry="collision"`` for its primitives, about 2 MB).

    Returns:
        The path written.
    """
    contacts = _scene(result, problem, force_scale, impulse_scale, ground, mu)
    return export_html(result, path, scale, geometry=geometry, trail=trail, max_mesh_mb=max_mesh_mb,
                       contacts=contacts)


def replay_legged(result: Result, problem, vis=None, open_browser: bool = False, zmq_url: str | None = None, *,
                  force_scale: float = 1e-3, impulse_scale: float = 1.0, ground: bool = True,
                  mu: float | None = None, **options):
    """The live meshcat replay of a legged ``result`` (:func:`geoddp.viz.replay`, whose
    ``vis``, ``open_browser``, ``zmq_url`` and keyword ``options`` it takes) with the ground, the
    contact points and the force arrows (as :func:`export_legged_html`).

    Returns:
        The visualizer (see :func:`geoddp.viz.replay`).
    """
    contacts = _scene(result, problem, force_scale, impulse_scale, ground, mu)
    return replay(result, vis, open_browser, zmq_url, contacts=contacts, **options)


def _mark_impulses(ax, c: ContactForces, label: bool) -> None:
    for j, t in enumerate(c.times[c.impulse]):
        ax.axvline(t, color="0.35", linestyle=":", linewidth=1.2,
                   label="impulse node (touch-down)" if label and j == 0 else None)


def _feet_figure(c: ContactForces, path: Path, kind: str):
    """One axes per foot (forces: f_z and |f_t| at contact nodes, a landing foot's impulse written
    at its impulse node, N s; margins: circular and facet margins), plus for forces a top
    axes with the total vertical force and the weight."""
    nf = len(c.feet)
    top = 1 if kind == "forces" else 0
    fig = Figure(figsize=(8.0, 1.2 + 2.0 * (nf + top)))
    axes = fig.subplots(nf + top, 1, sharex=True, squeeze=False)[:, 0]
    t = c.times
    contact = ~c.impulse
    arrays: dict = {"t": t, "impulse_times": t[c.impulse], "feet": list(c.feet)}
    if top:
        ax = axes[0]
        total = np.where(contact, c.total[:, 2], np.nan)
        needed = np.where(contact, c.momentum_change[:, 2], np.nan)
        weight = c.mass * float(np.linalg.norm(c.gravity))
        ax.plot(t, total, color="k", label=r"$\sum_f f_z$")
        ax.plot(t, needed, color="tab:orange", linestyle="--", label=r"$m\,(a_{com,z} - g_z)$")
        ax.axhline(weight, color="0.5", linewidth=1.0, label=f"weight m g = {weight:.1f} N")
        _mark_impulses(ax, c, True)
        ax.set(ylabel="force [N]", title="total vertical contact force (contact nodes)")
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")
        ax.grid(alpha=0.3)
        arrays.update(total_z=total, momentum_change_z=needed, weight=weight)
    margin, facet = c.cone_margin, c.facet_margin
    normal, tangential = c.normal, c.tangential
    for i, (ax, foot) in enumerate(zip(axes[top:], c.feet)):
        col = _color(i, nf)
        if kind == "forces":
            fz = np.where(contact, normal[:, i], np.nan)
            ft = np.where(contact, tangential[:, i], np.nan)
            ax.plot(t, fz, color=col, label="normal $f_z$")
            ax.plot(t, ft, color=col, linestyle="--", label=r"tangential $|f_t|$")
            _mark_impulses(ax, c, True)
            ax.set(ylabel="force [N]", title=f"{foot}: contact force (world)")
            arrays[f"{foot}/normal"], arrays[f"{foot}/tangential"] = fz, ft
            hit = c.impulse & c.active[:, i]
            for k in np.flatnonzero(hit):  # a landing foot's impulse, written at its node
                ax.annotate(rf"$\Lambda_z$ = {normal[k, i]:.3g} N s", (t[k], 0.97), xycoords=("data", "axes fraction"),
                            xytext=(-4, 0), textcoords="offset points", ha="right", va="top", fontsize="x-small",
                            color="0.25")
            if hit.any():
                arrays[f"{foot}/impulse_normal"] = normal[hit, i]
                arrays[f"{foot}/impulse_tangential"] = tangential[hit, i]
        else:
            cm = np.where(contact, margin[:, i], np.nan)
            fm = np.where(contact, facet[:, i], np.nan)
            ax.plot(t, cm, color=col, label=r"cone: $\mu f_z - |f_t|$")
            ax.plot(t, fm, color=col, linestyle="--", label=f"{c.facets} facets: " + r"$\min_i\,\mu f_z - t_i\cdot f$")
            ax.axhline(0.0, color="tab:red", linewidth=1.0)
            _mark_impulses(ax, c, True)
            ax.set(ylabel="margin [N]", title=f"{foot}: friction-cone margin (mu = {c.mu:g}; < 0: outside)")
            arrays[f"{foot}/cone_margin"], arrays[f"{foot}/facet_margin"] = cm, fm
        ax.grid(alpha=0.3)
        if i == 0:  # the same entries on every foot's axes
            ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Contact forces" if kind == "forces" else "Friction-cone margins")
    return _figure(fig, path, arrays)


def plot_legged(result: Result, problem, out_dir: str | Path, *, mu: float | None = None,
                forces: ContactForces | None = None) -> Figures:
    """The contact figures of a legged ``result``, written into ``out_dir`` (created if needed).

    - ``contact_forces.png``: on top, the total vertical force of the feet at every contact node
      against m (a_com,z - g_z) (equal: Newton's law) and the weight m g; then one axes per foot:
      its normal force f_z and tangential force |(f_x, f_y)| (N, world frame) at the contact
      nodes where it is on the ground (gaps elsewhere), the impulse nodes as dotted vertical lines
      with the vertical impulse of each foot that lands written beside them (N s).
    - ``friction_margin.png``: per foot, mu f_z - |f_t| (the circular cone) and the facet margin
      (Crocoddyl's linearised cone), N, with zero (the cone's boundary) in red.

    Args:
        result: the Result of solving ``problem``; problem: its ContactProblem.
        out_dir: output folder.
        mu: friction coefficient of the margins (None: the problem's).
        forces: the result's :func:`legged_forces` if already computed.

    Returns:
        :class:`~geoddp.viz.figures.Figures` (names :data:`LEGGED_FIGURES`), with ``.data[name].arrays``:
        ``t`` (H,) node times, ``impulse_times``, ``feet``, per foot ``<foot>/normal``,
        ``<foot>/tangential`` (NaN off the ground and at impulse nodes), ``<foot>/impulse_normal``,
        ``<foot>/impulse_tangential`` (the landing impulses), ``total_z``, ``momentum_change_z``,
        ``weight``; ``<foot>/cone_margin``, ``<foot>/facet_margin``.
    """
    c = forces if forces is not None else legged_forces(result, problem, mu=mu)
    out = output_folder(out_dir)
    figs = Figures()
    figs.add("contact_forces", _feet_figure(c, out / "contact_forces.png", "forces"))
    figs.add("friction_margin", _feet_figure(c, out / "friction_margin.png", "margins"))
    return figs


def legged_figures(result: Result, problem, out_dir: str | Path) -> list[Path]:
    """Every figure of a legged ``result`` in ``out_dir``: the multibody ones
    (:func:`geoddp.viz.plot_multibody`: joints, controls, solver history) and :func:`plot_legged`'s;
    returns their paths."""
    return [*plot_multibody(result, out_dir).values(), *plot_legged(result, problem, out_dir).values()]
