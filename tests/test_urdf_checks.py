"""Issue 13, item 6: URDF encodings, joint axes, masses and inertias refused by name."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from geoddp.models.multibody import Multibody
from geoddp.models.urdf import build_checked_model, captured_stderr, read_urdf_text
from geoddp.validate import InputError

ARM = """<?xml version="1.0"{decl}?>
<robot name="arm">
  <link name="base"/>
  <link name="upper">
    <inertial><origin xyz="0 0 0.5"/><mass value="{mass}"/>
      <inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial>
  </link>
  <link name="fore{suffix}">
    <inertial><origin xyz="0 0 0.5"/><mass value="1.0"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="{axis}"/><limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore{suffix}"/>
    <origin xyz="0 0 1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
</robot>
"""


def _write(tmp_path, encoding="utf-8", decl="", **kw):
    fields = dict(mass="1.0", ixx="0.1", iyy="0.1", izz="0.1", axis="0 1 0", suffix="")
    fields.update(kw)
    path = tmp_path / "arm.urdf"
    path.write_bytes(ARM.format(decl=decl, **fields).encode(encoding))
    return path


def _refused(path, *words):
    with pytest.raises(InputError) as e:
        Multibody(path, root="fixed", dt=0.01)
    assert e.value.parameter == "urdf"
    for w in words:
        assert w in str(e.value), str(e.value)
    return e.value


def test_a_good_arm_builds_the_same_model_as_pinocchio(tmp_path):
    import pinocchio as pin

    path = _write(tmp_path)
    ours, theirs = build_checked_model(path), pin.buildModelFromUrdf(str(path))
    assert ours.nv == theirs.nv == 2 and list(ours.names) == list(theirs.names)
    for a, b in zip(ours.inertias, theirs.inertias):
        np.testing.assert_array_equal(a.matrix(), b.matrix())


def test_latin1_declared_is_decoded_and_undeclared_is_refused_by_name(tmp_path):
    path = _write(tmp_path, "latin-1", decl=' encoding="ISO-8859-1"', suffix="_\u00e9")
    text = read_urdf_text(path)
    assert "fore_\u00e9" in text and "encoding" not in text.splitlines()[0]
    m = Multibody(path, root="fixed", dt=0.01)
    assert any(f.name == "fore_\u00e9" for f in m.pin_model.frames)
    path = _write(tmp_path, "latin-1", suffix="_\u00e9")
    _refused(path, "arm.urdf", "not valid UTF-8 text (byte ", "declare the file's encoding")


@pytest.mark.parametrize("axis, words", [("0 0 0", "is zero"), ("nan 0 1", "3 finite"), ("1 0", "3 finite"),
                                         ("0 inf 0", "3 finite")])
def test_bad_joint_axis_is_refused_naming_the_joint(tmp_path, axis, words):
    _refused(_write(tmp_path, axis=axis), "joint 'shoulder'", words)


def test_massless_moving_body_and_singular_inertia_are_refused_naming_joint_and_link(tmp_path):
    # the shoulder moves both links: it has mass; a massless fore-link on the elbow does not
    bad = ARM.replace('<mass value="1.0"/>\n      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1"',
                      '<mass value="0.0"/>\n      <inertia ixx="0.0" ixy="0" ixz="0" iyy="0.0"')
    bad = bad.replace('iyy="0.1" iyz="0" izz="0.1"/></inertial>\n  </link>\n  <joint name="shoulder"',
                      'iyy="0" iyz="0" izz="0"/></inertial>\n  </link>\n  <joint name="shoulder"')
    path = tmp_path / "arm.urdf"
    path.write_text(bad.format(decl="", mass="1.0", ixx="0.1", iyy="0.1", izz="0.1", axis="0 1 0", suffix=""))
    _refused(path, "joint 'elbow'", "link 'fore'", "massless")
    # singular: a link of mass 1 on the axis of its revolute joint (z), with zero inertia about z
    single = """<robot name="s"><link name="base"/>
      <link name="rotor"><inertial><origin xyz="0 0 0"/><mass value="1.0"/>
        <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0"/></inertial></link>
      <joint name="spin" type="continuous"><parent link="base"/><child link="rotor"/><axis xyz="0 0 1"/></joint>
    </robot>"""
    path.write_text(single)
    _refused(path, "joint 'spin'", "link 'rotor'", "singular inertia")


def test_negative_mass_and_non_finite_inertia_are_refused_naming_the_link(tmp_path):
    _refused(_write(tmp_path, mass="-1"), "link 'upper'", "mass")
    _refused(_write(tmp_path, ixx="nan"), "link 'upper'", "ixx")


def test_urdfdom_stderr_is_captured_into_the_message(tmp_path):
    # a joint naming a missing link: urdfdom prints its own error lines on fd 2 and fails
    code = textwrap.dedent(f"""
        from pathlib import Path
        from geoddp.models.multibody import Multibody
        from geoddp.validate import InputError
        p = Path({str(tmp_path)!r}) / "broken.urdf"
        p.write_text('<robot name="b"><link name="a"/><joint name="j" type="revolute"><parent link="a"/>'
                     '<child link="missing"/><axis xyz="0 0 1"/><limit effort="1" velocity="1"/></joint></robot>')
        try:
            Multibody(p, root="fixed", dt=0.01)
        except InputError as e:
            print("MSG", e)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stderr == ""  # nothing but geoddp's message, which goes to stdout here
    assert "MSG urdf: expected a valid URDF model" in out.stdout


def test_captured_stderr_restores_fd2(capfd):
    import os

    with captured_stderr() as lines:
        os.write(2, b"from C++\n")
    os.write(2, b"after\n")
    assert lines == ["from C++"] and capfd.readouterr().err == "after\n"


def _same_model(a, b):
    assert (a.nq, a.nv, a.njoints, list(a.names)) == (b.nq, b.nv, b.njoints, list(b.names))
    for x, y in zip(a.inertias, b.inertias):
        np.testing.assert_array_equal(x.matrix(), y.matrix())
    for x, y in zip(a.jointPlacements, b.jointPlacements):
        np.testing.assert_array_equal(x.homogeneous, y.homogeneous)
    np.testing.assert_array_equal(a.gravity.vector, b.gravity.vector)


def test_a_urdf_built_before_is_copied_and_an_edited_one_is_built_again(tmp_path, monkeypatch):
    """The per-process memo of build_checked_model (a sweep builds one robot for every case):
    a second call builds nothing and returns an equal, separate model, which the caller may edit;
    an edited file, another root joint or a root joint with parameters is built anew, and a
    refused file is refused on every call."""
    import pinocchio as pin

    import geoddp.models.urdf as uc

    builds = []
    real = pin.buildModelFromXML
    monkeypatch.setattr(uc.pin, "buildModelFromXML", lambda *a: builds.append(len(a)) or real(*a))
    path = _write(tmp_path, ixx="0.125")  # a text no other test builds
    first = build_checked_model(path)
    assert len(builds) == 1
    first.gravity = pin.Motion.Zero()  # the caller's edits stay in its copy
    first.inertias[1] = pin.Inertia.Identity()
    second = build_checked_model(path)
    assert len(builds) == 1 and second is not first
    _same_model(second, pin.buildModelFromUrdf(str(path)))
    third = build_checked_model(path)
    assert third is not second
    _same_model(third, second)
    # another root joint: another model (free flyer: nq 7 + 2)
    ff = build_checked_model(path, pin.JointModelFreeFlyer())
    assert len(builds) == 2 and (ff.nq, ff.nv) == (9, 8)
    assert build_checked_model(path, pin.JointModelFreeFlyer()).nq == 9 and len(builds) == 2
    # a root joint with parameters (its axis) is not told apart by its type's name: built each time
    axis = pin.JointModelRevoluteUnaligned(np.array([0.0, 0.6, 0.8]))
    build_checked_model(path, axis)
    build_checked_model(path, axis)
    assert len(builds) == 4
    # the file edited in place: its new text is a new model
    path = _write(tmp_path, ixx="0.125", mass="2.5")
    assert build_checked_model(path).inertias[1].mass == 2.5 and len(builds) == 5
    # a refused file is refused every time, and once mended it builds
    _write(tmp_path, ixx="0.125", mass="2.5", axis="0 0 0")
    for _ in range(2):
        _refused(path, "joint 'shoulder'", "is zero")
    _write(tmp_path, ixx="0.125", mass="2.5")
    assert build_checked_model(path).inertias[1].mass == 2.5
