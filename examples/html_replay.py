"""
Replaying a result in the browser
=================================

:func:`geoddp.viz.export_html` writes one self-contained HTML file: meshcat's viewer, the scene and
every mesh it draws are inside it, so it opens from disk with no server and no network, and plays
one keyframe per time step at 1/dt frames per second (play, pause and a time scrubber under
"Animations" in the viewer's controls). :func:`geoddp.viz.replay` shows the same scene live in a
meshcat server on 127.0.0.1; ``geoddp run SCENE --html OUT.html`` and ``--view`` do the same from
the command line.

Every replay rebuilds the model from the Result alone (its URDF text, root and, for a model
handed over in Python, Pinocchio's archive of it) and places each visual by forward kinematics.
"""

# %%
# Write the pages
# ---------------
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from geoddp import Result, solve_scene
from geoddp.viz import animation_frame_count, export_html, visual_placements

satellite = solve_scene("satellite_paper")
quadrotor = solve_scene("quadrotor")
with tempfile.TemporaryDirectory() as tmp:
    tmp = Path(tmp)
    pages = {"satellite": export_html(satellite, tmp / "satellite.html"),
             "quadrotor": export_html(quadrotor, tmp / "quadrotor.html", trail="root")}
    for name, page in pages.items():
        text = page.read_text()
        print(f"{name}: {page.stat().st_size / 1e6:.1f} MB, {animation_frame_count(text)} keyframes")
    # One keyframe per state, H + 1, and no script or style loaded from anywhere else.
    for name, result in (("satellite", satellite), ("quadrotor", quadrotor)):
        text = pages[name].read_text()
        assert animation_frame_count(text) == result.horizon + 1
        assert 'src="http' not in text and 'href="http' not in text

    # A result saved as JSON replays the same: the file holds the model description.
    satellite.write_json(tmp / "satellite.json")
    again = Result.read_json(tmp / "satellite.json")

# %%
# What the page animates
# ----------------------
# :func:`geoddp.viz.visual_placements` returns the world placement of every visual object at
# every time step, (H+1, n_objects, 4, 4): here the satellite's bus, its two panels and the three
# body axes, and the quadrotor's hub, arms and rotors. Their rotations are the solution's
# attitudes, to round-off; the JSON round trip gives the same placements.
P = visual_placements(satellite)
assert np.abs(P[:, 0, :3, :3] - satellite.rotations).max() < 1e-12
assert np.abs(visual_placements(again) - P).max() < 1e-12

Q = visual_placements(quadrotor)
fig = plt.figure(figsize=(11, 3.8))
ax = fig.add_subplot(1, 2, 1)
ax.plot(satellite.times, P[:, 0, :3, 0], label=["x", "y", "z"])
ax.set(xlabel="t [s]", title="satellite: the body x axis in the world frame")
ax.legend(fontsize=8)
ax = fig.add_subplot(1, 2, 2, projection="3d")
ax.plot(*Q[:, 0, :3, 3].T, "C1")
ax.scatter(*Q[0, 0, :3, 3], color="k", label="start")
ax.scatter(*Q[-1, 0, :3, 3], color="C3", label="end")
ax.set(xlabel="x [m]", ylabel="y [m]", zlabel="z [m]", title="quadrotor: the hub's path (the trail)")
ax.legend(fontsize=8)
fig.tight_layout()
