"""Where the tests find a URDF by file name: the test-only models in tests/data/, else the built-in
ones shipped as package data (geoddp/data/urdf/, :func:`geoddp.data.urdf_path`)."""
from __future__ import annotations

from pathlib import Path

from geoddp.data import urdf_path

TEST_DATA = Path(__file__).resolve().parent / "data"


def urdf(name: str) -> Path:
    """Absolute path of the URDF ``name`` (``"test_all_joints.urdf"``, ``"quadrotor.urdf"``)."""
    return TEST_DATA / name if (TEST_DATA / name).is_file() else urdf_path(name)
