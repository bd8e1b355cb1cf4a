"""The three scenes' URDFs and the thruster / rotor actuation helpers."""

import numpy as np
import pinocchio as pin
import pytest

from geoddp.data import urdf_dir
from geoddp.models.actuation import quadrotor_actuation, thruster_actuation
from geoddp.models.multibody import Multibody
from geoddp.validate import InputError

MODELS = urdf_dir()  # the built-in URDFs (package data)


# ---------------------------------------------------------------------------- thrusters
def test_a_thruster_through_the_origin_gives_pure_force():
    Hm = thruster_actuation([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [[0.0, 3.0, 0.0], [4.0, 0.0, 0.0]])
    assert Hm.shape == (6, 2)
    assert np.array_equal(Hm[:, 0], [0, 1, 0, 0, 0, 0])  # direction normalised, no torque
    assert np.array_equal(Hm[:, 1], [1, 0, 0, 0, 0, 0])  # along its own lever arm: no torque


def test_offset_thrusters_torque_and_a_couple_is_pure_torque():
    Hm = thruster_actuation([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]], [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    assert np.allclose(Hm[:, 0], [1, 0, 0, 0, 0, -1])  # r x F = e_y x e_x = -e_z
    couple = Hm @ np.array([2.0, 2.0])
    assert np.allclose(couple, [0, 0, 0, 0, 0, -4])


def test_thruster_wrench_accelerates_a_free_body_as_newton_euler_says():
    """Through Pinocchio: a thruster at p along d on a body at rest (CoM at the origin) gives
    linear acceleration d/m and angular acceleration I^-1 (p x d)."""
    mb = Multibody(MODELS / "spacecraft.urdf", root="free_flyer", gravity=False, dt=0.1,
                   actuation=thruster_actuation([[0.3, -0.2, 0.9]], [[0.0, 1.0, 0.2]]))
    inertia = mb.pin_model.inertias[1]
    _, v = mb.step(mb.neutral(), np.zeros(6), np.array([50.0]))
    d = np.array([0.0, 1.0, 0.2]) / np.linalg.norm([0.0, 1.0, 0.2])
    assert np.allclose(v[:3], 0.1 * 50.0 * d / inertia.mass, atol=1e-14)
    assert np.allclose(v[3:], 0.1 * 50.0 * np.linalg.solve(inertia.inertia, np.cross([0.3, -0.2, 0.9], d)), atol=1e-14)


@pytest.mark.parametrize(
    "positions, directions, param",
    [
        (np.zeros((2, 2)), np.zeros((2, 2)), "positions"),
        (np.zeros((2, 3)), np.ones((3, 3)), "directions"),
        (np.zeros((2, 3)), [[1, 0, 0], [0, 0, 0]], "directions"),
        ([[np.nan, 0, 0]], [[1, 0, 0]], "positions"),
    ],
)
def test_thruster_actuation_refuses_bad_input(positions, directions, param):
    with pytest.raises(InputError) as info:
        thruster_actuation(positions, directions)
    assert info.value.parameter == param


# ---------------------------------------------------------------------------- quadrotor
def test_quadrotor_equal_thrusts_lift_without_torque():
    Hm = quadrotor_actuation(0.25, 0.02)
    assert Hm.shape == (6, 4)
    assert np.allclose(Hm @ np.full(4, 3.0), [0, 0, 12.0, 0, 0, 0])


def test_quadrotor_opposite_rotors_cancel_roll_and_pitch_and_spin_pairs_cancel_yaw():
    Hm = quadrotor_actuation(0.25, 0.02)
    front_back = Hm @ np.array([1.0, 0.0, 1.0, 0.0])
    left_right = Hm @ np.array([0.0, 1.0, 0.0, 1.0])
    assert np.allclose(front_back[3:5], 0) and np.isclose(front_back[5], 0.04)
    assert np.allclose(left_right[3:5], 0) and np.isclose(left_right[5], -0.04)
    assert np.isclose((front_back + left_right)[5], 0.0)  # the two spin directions cancel yaw
    # more thrust on the +y rotor rolls positively about x, on the +x rotor pitches negatively about y
    assert Hm[3, 1] == pytest.approx(0.25) and Hm[4, 0] == pytest.approx(-0.25)


def test_quadrotor_hovers_at_a_quarter_of_its_weight_per_rotor():
    mb = Multibody(MODELS / "quadrotor.urdf", root="free_flyer", gravity=True, dt=0.01,
                   actuation=quadrotor_actuation(0.25, 0.02))
    weight = mb.pin_model.inertias[1].mass * 9.81
    q, v = mb.step(mb.neutral(), np.zeros(6), np.full(4, weight / 4))
    assert np.abs(v).max() < 1e-13 and np.abs(q - mb.neutral()).max() < 1e-15


@pytest.mark.parametrize("kw, param", [({"arm_length": 0.0}, "arm_length"), ({"torque_coefficient": -0.1}, "torque_coefficient")])
def test_quadrotor_actuation_refuses_bad_input(kw, param):
    with pytest.raises(InputError) as info:
        quadrotor_actuation(**{"arm_length": 0.25, "torque_coefficient": 0.02, **kw})
    assert info.value.parameter == param


# ---------------------------------------------------------------------------- scene URDFs
def test_spacecraft_urdf_is_one_500kg_body():
    m = pin.buildModelFromUrdf(str(MODELS / "spacecraft.urdf"), pin.JointModelFreeFlyer())
    assert (m.nq, m.nv, m.njoints) == (7, 6, 2)
    I = m.inertias[1]  # noqa: E741
    assert I.mass == 500.0 and np.allclose(I.lever, 0.0)
    eig = np.linalg.eigvalsh(I.inertia)
    assert np.all(eig > 0) and eig[0] + eig[1] > eig[2]  # a physical rigid body


def test_quadrotor_urdf_is_one_1p5kg_body():
    m = pin.buildModelFromUrdf(str(MODELS / "quadrotor.urdf"), pin.JointModelFreeFlyer())
    assert (m.nq, m.nv, m.njoints) == (7, 6, 2)
    assert m.inertias[1].mass == 1.5 and np.allclose(m.inertias[1].lever, 0.0)


def test_space_manipulator_urdf_is_a_base_and_a_three_joint_arm_with_an_ee_frame():
    mb = Multibody(MODELS / "space_manipulator.urdf", root="free_flyer", gravity=False, dt=0.05)
    m = mb.pin_model
    assert (m.nq, m.nv) == (10, 9)
    shorts = [m.joints[j].shortname() for j in range(1, m.njoints)]
    assert shorts == ["JointModelFreeFlyer", "JointModelRZ", "JointModelRY", "JointModelRY"]
    assert [g.kind for g in mb.groups] == ["se3", "vector", "vector", "vector"]
    assert m.existFrame("ee")
    data = m.createData()
    pin.framesForwardKinematics(m, data, pin.neutral(m))
    assert np.allclose(data.oMf[m.getFrameId("ee")].translation, [2.6, 0.0, 0.8])  # arm stretched along x
