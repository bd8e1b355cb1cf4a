"""The one-body shortcut for RNEA's second-order tensors (cpp/rigid_body/one_body.hpp) against Pinocchio's
ComputeRNEASecondOrderDerivatives.

For one rigid body on a free-flyer or spherical root, the expansions take d2tau/dv2 (constant),
d2tau/dqdv = dM/dq = 0 and d2tau/dq2 = sum_c g_b,c T_c (g_b the gravity seen from the body) from
tensors Pinocchio computes once per expansion. Here every tensor equals Pinocchio's own at random
states: near the identity, at moderate rotations and near pi; gravity on and off; a centre of mass
off the joint; a rotated, translated root placement; armature. Models it must not take (two joints,
a fixed or revolute root, gravity with an angular part) are refused, and the expansions of those
that it takes still equal differences of Pinocchio's analytic first derivatives
(tests/test_core_dynamics.py, test_velocity_second_derivatives_exact, runs through it on the
quadrotor, the spacecraft and the satellite).
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from urdfs import urdf as urdf_file


core = compiled._core


def _body(rng):
    """A random rigid body: mass 0.5..5 kg, centre of mass up to 0.4 m off the joint, a random
    positive-definite rotational inertia."""
    A = rng.normal(size=(3, 3))
    return pin.Inertia(float(rng.uniform(0.5, 5.0)), 0.4 * rng.normal(size=3), A @ A.T + 0.1 * np.eye(3))


def _one_body(joint, seed, placed=True, gravity=True, armature=True):
    rng = np.random.default_rng(seed)
    model = pin.Model()
    plc = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3)) if placed else pin.SE3.Identity()
    j = model.addJoint(0, joint, plc, "root")
    model.appendBodyToJoint(j, _body(rng), pin.SE3.Identity())
    if armature:
        model.armature = rng.uniform(0.0, 0.3, size=model.nv)
    model.gravity = pin.Motion(np.array([0.3, -1.2, -9.81]) if gravity else np.zeros(3), np.zeros(3))
    return model


def _rotation_coords(model):
    return slice(3, 6) if model.nv == 6 else slice(0, 3)


def _states(model, rng):
    """(q, v, a): rotations of 1e-7 rad, 0.5 rad, 2 rad and pi - 1e-6 rad about random axes."""
    for angle in (1e-7, 0.5, 2.0, np.pi - 1e-6):
        axis = rng.normal(size=3)
        dq = rng.normal(size=model.nv)
        dq[_rotation_coords(model)] = angle * axis / np.linalg.norm(axis)
        q = pin.integrate(model, pin.neutral(model), dq)
        yield q, 3.0 * rng.normal(size=model.nv), 3.0 * rng.normal(size=model.nv)


MODELS = {
    "free_flyer-placed-g": lambda s: _one_body(pin.JointModelFreeFlyer(), s),
    "free_flyer-nog": lambda s: _one_body(pin.JointModelFreeFlyer(), s, placed=False, gravity=False),
    "free_flyer-no_armature": lambda s: _one_body(pin.JointModelFreeFlyer(), s, armature=False),
    "spherical-placed-g": lambda s: _one_body(pin.JointModelSpherical(), s),
    "spherical-nog": lambda s: _one_body(pin.JointModelSpherical(), s, gravity=False),
}


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("name", list(MODELS))
def test_one_body_tensors_equal_pinocchio(name, seed):
    model = MODELS[name](seed)
    assert core.testing.one_body_applies(model)
    rng = np.random.default_rng(100 + seed)
    for q, v, a in _states(model, rng):
        ref = core.rnea_second_order(model, q, v, a, False)
        got = core.rnea_second_order(model, q, v, a, True)
        for label, x, y in zip(("d2tau_dqdq", "d2tau_dvdv", "d2tau_dqdv", "d2tau_dadq"), got, ref):
            assert x.shape == y.shape == (model.nv,) * 3
            assert np.abs(x - y).max() <= 1e-13 * max(1.0, np.abs(y).max()), label
        # not vacuous: the velocity tensor is the body's, and gravity makes the q tensor nonzero
        assert np.abs(ref[1]).max() > 0.1
        if np.any(model.gravity.linear != 0) and name.startswith("free_flyer"):
            assert np.abs(ref[0]).max() > 0.1


def test_spherical_tensor_under_gravity_is_not_zero():
    """A spherical root with its centre of mass off the joint: gravity's torque depends on the
    rotation, so d2tau/dq2 is not zero, and the shortcut gives Pinocchio's."""
    model = _one_body(pin.JointModelSpherical(), 4)
    q, v, a = next(_states(model, np.random.default_rng(9)))
    ref = core.rnea_second_order(model, q, v, a, False)[0]
    assert np.abs(ref).max() > 0.1
    assert np.abs(core.rnea_second_order(model, q, v, a, True)[0] - ref).max() <= 1e-13 * np.abs(ref).max()


def test_shortcut_refuses_other_models():
    two = _one_body(pin.JointModelFreeFlyer(), 5)
    two.appendBodyToJoint(1, _body(np.random.default_rng(0)), pin.SE3.Identity())  # still one joint: applies
    assert core.testing.one_body_applies(two)
    j2 = two.addJoint(1, pin.JointModelRZ(), pin.SE3.Identity(), "wheel")
    two.appendBodyToJoint(j2, _body(np.random.default_rng(1)), pin.SE3.Identity())
    revolute = pin.Model()
    revolute.appendBodyToJoint(revolute.addJoint(0, pin.JointModelRX(), pin.SE3.Identity(), "r"),
                               _body(np.random.default_rng(2)), pin.SE3.Identity())
    angular = _one_body(pin.JointModelFreeFlyer(), 6)
    angular.gravity = pin.Motion(np.array([0.0, 0.0, -9.81]), np.array([0.0, 0.1, 0.0]))
    fixed = Multibody(urdf_file("space_manipulator.urdf"), root="fixed", dt=0.01).pin_model
    for model in (two, revolute, angular, fixed):
        assert not core.testing.one_body_applies(model)
        nq, nv = model.nq, model.nv
        with pytest.raises(ValueError, match="one-body"):
            core.rnea_second_order(model, pin.neutral(model), np.zeros(nv), np.zeros(nv), True)
    assert core.rnea_second_order(two, pin.neutral(two), np.ones(two.nv), np.ones(two.nv), False)[0].shape == (7, 7, 7)


@pytest.mark.parametrize("urdf, root, gravity, applies", [
    ("quadrotor.urdf", "free_flyer", True, True),
    ("spacecraft.urdf", "free_flyer", False, True),
    ("satellite.urdf", "spherical", True, True),
    ("space_manipulator.urdf", "free_flyer", False, False),
])
def test_built_in_models_that_take_it(urdf, root, gravity, applies):
    """Which of the scenes' models the expansions take the shortcut for (the speed-up the README
    reports for the docking and quadrotor scenes rests on it)."""
    mb = Multibody(urdf_file(urdf), root=root, dt=0.01, gravity=gravity)
    assert core.testing.one_body_applies(mb.pin_model) == applies
