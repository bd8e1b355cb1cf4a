"""Static HTML export: self-contained, carries H+1 keyframes, and renders in headless Chromium."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest

from geoddp.viz import animation_frame_count, export_html
from geoddp.viz.html import STATUS_ID, decode_commands
from geoddp.viz.scene import BACKGROUND_RGB, ROBOT
from viz_fixtures import OFFLINE_FLAG, changed_fraction, chromium_or_skip, run_chromium, screenshot, synthetic_result

BACKGROUND_U8 = np.round(255 * np.asarray(BACKGROUND_RGB)).astype(int)


@pytest.mark.parametrize("horizon", [1, 17, 40])
def test_frame_count_is_horizon_plus_one(tmp_path, horizon):
    result = synthetic_result(horizon=horizon, dt=0.1)
    text = export_html(result, tmp_path / "replay.html").read_text()
    assert animation_frame_count(text) == horizon + 1


def test_animation_is_time_synchronised_and_ends_at_final_attitude(tmp_path):
    result = synthetic_result(horizon=25, dt=0.04)
    cmds = decode_commands(export_html(result, tmp_path / "r.html").read_text())
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    (clip,) = [a["clip"] for a in anim["animations"] if a["path"] == f"/meshcat/{ROBOT}/bus_0"]  # the bus
    assert clip["fps"] == pytest.approx(1.0 / result.dt)  # keyframe k plays at k * dt seconds
    quat = next(t for t in clip["tracks"] if t["name"] == ".quaternion")
    assert [k["time"] for k in quat["keys"]] == list(range(result.horizon + 1))
    for k in (0, result.horizon):
        q_page = np.asarray(quat["keys"][k]["value"])  # three.js order (x, y, z, w)
        q_res = result.quaternions[k]
        assert min(np.abs(q_page - q_res).max(), np.abs(q_page + q_res).max()) < 1e-9


def test_export_is_self_contained(tmp_path):
    text = export_html(synthetic_result(), tmp_path / "r.html").read_text()
    # No external resources in the markup (script bodies removed: the bundle's own code
    # mentions "href=" when it builds download links at run time).
    markup = re.sub(r"(<script[^>]*>).*?(</script>)", r"\1\2", text, flags=re.DOTALL | re.IGNORECASE)
    assert markup.count("<script") == 3  # commands (JSON), viewer bundle, scene loader
    assert not re.search(r"""\b(?:src|href)\s*=""", markup, flags=re.IGNORECASE), markup
    assert "<link" not in markup.lower()
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", text))
    assert urls <= {"http://www.w3.org/1999/xhtml"}, urls  # an XML namespace name, never fetched
    assert "MeshCat" in text and len(text) > 500_000  # the 0.85 MB viewer bundle is inlined


def test_frame_count_rejects_foreign_html():
    with pytest.raises(ValueError):
        animation_frame_count("<html><body>no scene</body></html>")


def test_renders_in_headless_chromium_offline(tmp_path):
    chromium_or_skip()
    result = synthetic_result(horizon=30, dt=0.05)
    page = export_html(result, tmp_path / "replay.html")
    url = page.resolve().as_uri()

    # The page's own report of what the viewer loaded (written by its script after the
    # commands ran), read back from the DOM.
    dom = run_chromium(url, "--dump-dom", OFFLINE_FLAG).stdout
    m = re.search(r'<pre id="%s"[^>]*>(.*?)</pre>' % STATUS_ID, dom, flags=re.DOTALL)
    assert m, "status element missing from the dumped DOM"
    status = json.loads(m.group(1))
    assert status["loaded"] is True, "viewer script did not run to the end"
    # one clip per visual of satellite.urdf (bus, two panels, three axes): position + quaternion tracks
    assert status["frames"] == [[result.horizon + 1, result.horizon + 1]] * 6
    assert status["duration"] == pytest.approx(result.horizon * result.dt)

    img = screenshot(url, tmp_path / "shot.png", OFFLINE_FLAG)
    corner = img[-5, 5]  # bottom-left: away from the satellite and the controls bar
    assert np.abs(corner.astype(int) - BACKGROUND_U8).max() <= 3, f"background {corner} is not the scene's"
    fraction = changed_fraction(img, BACKGROUND_U8)
    assert fraction > 0.02, f"only {fraction:.1%} of the centre differs from the background"


def test_pixel_check_detects_an_empty_page(tmp_path):
    """Negative control: a page of plain background colour must fail the pixel check."""
    chromium_or_skip()
    r, g, b = BACKGROUND_U8
    page = tmp_path / "empty.html"
    page.write_text(f'<html><body style="margin:0;background:rgb({r},{g},{b})"></body></html>')
    img = screenshot(page.resolve().as_uri(), tmp_path / "empty.png", OFFLINE_FLAG)
    assert changed_fraction(img, BACKGROUND_U8) < 0.001
