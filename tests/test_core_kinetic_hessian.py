"""The kinetic energy's configuration Hessian and gradient by spatial-vector recursions
(cpp/rigid_body/kinetic_hessian.hpp).

H = 1/2 d2/dq2 (y^T M(q) y), trivialised (entry (k, l): the gradient's k-th entry differenced
along q exp(eps e_l)), is what the variational step's second order takes from it. Checked against

* Pinocchio's second-order RNEA contracted with y, 1/2 sum_p y_p d2tau_p/dq_k dq_l at (q, 0, y)
  on the gravity-free model (what it replaces), to 1e-12 relative;
* central differences of Pinocchio's analytic first derivative 1/2 D(q, y)^T y along
  q exp(+-h e_l) (D = dtau/dq at (q, 0, y)), to 1e-7 relative;

on a free-flyer arm, a fixed base with every URDF joint type, a spherical root carrying a chain, a
branching tree built joint by joint (spherical, translation, prismatic and unaligned revolute
joints mid-tree) and, from example-robot-data, the UR5 and Solo12; near the identity and at
random configurations; the columns of a joint on the universe are exactly zero. The gradient
1/2 D(q, y)^T y (the variational step's residual) equals Pinocchio's RNEA derivative contracted
with y and differences of the kinetic energy on the same models, and the tensors dM/dq and
d/dq D(q, y) (the variational step's base points) equal Pinocchio's second-order RNEA and
differences of its mass matrix and of D(q, y). A joint the core
does not take (spherical ZYX, whose motion subspace moves with q) is refused by name.
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models import compiled
from geoddp.models.multibody import Multibody
from urdfs import urdf as urdf_file

core = compiled._core


def _inertia(rng):
    return pin.Inertia(float(rng.uniform(0.5, 2.0)), rng.normal(size=3) * 0.2,
                       np.diag(rng.uniform(0.05, 0.3, size=3)))


def _tree():
    """A branching tree: spherical root; a translation joint, a prismatic and an unaligned
    revolute below it; a second branch with a mid-tree spherical joint and an RZ joint."""
    rng = np.random.default_rng(3)
    model = pin.Model()

    def add(parent, joint, name):
        placement = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3) * 0.3)
        j = model.addJoint(parent, joint, placement, name)
        model.appendBodyToJoint(j, _inertia(rng), pin.SE3.Identity())
        return j

    root = add(0, pin.JointModelSpherical(), "root")
    a = add(root, pin.JointModelTranslation(), "a")
    b = add(a, pin.JointModelPrismaticUnaligned(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])), "b")
    add(b, pin.JointModelRevoluteUnaligned(np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])), "c")
    d = add(root, pin.JointModelRX(), "d")
    e = add(d, pin.JointModelSpherical(), "e")
    add(e, pin.JointModelRZ(), "f")
    add(d, pin.JointModelPY(), "g")
    return model


def _scene_model(urdf, root):
    return Multibody(urdf_file(urdf), root=root, dt=0.01, integrator="variational", gravity=True).pin_model


def _robot(name):
    example_robot_data = pytest.importorskip("example_robot_data")
    return example_robot_data.load(name).model


MODELS = {
    "free_flyer_arm": lambda: _scene_model("space_manipulator.urdf", "free_flyer"),
    "fixed_all_joints": lambda: _scene_model("test_all_joints.urdf", "fixed"),
    "spherical_chain": lambda: _scene_model("space_manipulator.urdf", "spherical"),
    "tree": _tree,
    "ur5": lambda: _robot("ur5"),
    "solo12": lambda: _robot("solo12"),
}


def _free(model):
    free = model.copy()
    free.gravity.setZero()
    return free


def _reference(free, q, y):
    Iqq = core.rnea_second_order(free, q, np.zeros(free.nv), y, False)[0]
    return 0.5 * np.einsum("p,pkl->kl", y, Iqq)


def _half_gradient(free, data, q, y):
    pin.computeRNEADerivatives(free, data, q, np.zeros(free.nv), y)
    return 0.5 * data.dtau_dq.T @ y


def _differenced(free, q, y, h=1e-5):
    data = free.createData()
    H = np.empty((free.nv, free.nv))
    for l in range(free.nv):
        e = np.zeros(free.nv)
        e[l] = h
        H[:, l] = (_half_gradient(free, data, pin.integrate(free, q, e), y)
                   - _half_gradient(free, data, pin.integrate(free, q, -e), y)) / (2 * h)
    return H


def _states(model, seed):
    rng = np.random.default_rng(seed)
    for spread in (1e-6, 0.7, 2.0):
        q = pin.integrate(model, pin.neutral(model), spread * rng.normal(size=model.nv))
        yield q, rng.normal(size=model.nv)


@pytest.mark.parametrize("name", list(MODELS))
def test_kinetic_hessian_equals_pinocchio(name):
    model = MODELS[name]()
    free = _free(model)
    for q, y in _states(model, seed=len(name)):
        H = core.testing.kinetic_hessian(model, q, y)
        ref = _reference(free, q, y)
        scale = max(1.0, np.abs(ref).max())
        assert np.abs(H - ref).max() <= 1e-12 * scale, name
        assert np.abs(H - _differenced(free, q, y)).max() <= 1e-7 * scale, name
        assert np.abs(ref).max() > 1e-3  # not a comparison of zeros
        # a joint on the universe moves its tree rigidly with its velocities: exactly zero columns
        roots = [model.idx_vs[j] + d for j in range(1, model.njoints) if model.parents[j] == 0 for d in range(model.nvs[j])]
        assert roots and np.all(H[:, roots] == 0.0)


@pytest.mark.parametrize("name", list(MODELS))
def test_kinetic_gradient_equals_pinocchio_and_differences(name):
    """g = 1/2 D(q, y)^T y (the variational residual's kinetic term, O(nv)) equals Pinocchio's RNEA
    derivative contracted with y, and central differences of the kinetic energy 1/2 y^T M(q) y."""
    model = MODELS[name]()
    free = _free(model)
    data = free.createData()

    def energy(q, y):
        M = pin.crba(free, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        return 0.5 * y @ M @ y

    for q, y in _states(model, seed=7 + len(name)):
        g = core.testing.kinetic_gradient(model, q, y)
        ref = _half_gradient(free, data, q, y)
        scale = max(1.0, np.abs(ref).max())
        assert np.abs(g - ref).max() <= 1e-12 * scale, name
        h = 1e-6
        fd = np.array([(energy(pin.integrate(free, q, h * e), y) - energy(pin.integrate(free, q, -h * e), y)) / (2 * h)
                       for e in np.eye(free.nv)])
        assert np.abs(g - fd).max() <= 1e-7 * scale, name
        assert np.abs(ref).max() > 1e-3


@pytest.mark.parametrize("name", list(MODELS))
def test_mass_tensors_equal_pinocchio_and_differences(name):
    """dM/dq and d/dq D(q, y) (the variational step's base-point tensors, by the same recursion)
    equal Pinocchio's second-order RNEA at (q, 0, y) without gravity (d2tau_dadq, d2tau_dqdq), and
    central differences of Pinocchio's mass matrix and of its analytic D(q, y) along q exp(+-h e_k);
    a joint on the universe turns the whole tree rigidly: its pages are exactly zero."""
    model = MODELS[name]()
    free = _free(model)
    data = free.createData()
    nv = free.nv

    def mass(q):
        M = pin.crba(free, data, q)
        return np.triu(M) + np.triu(M, 1).T

    def D(q, y):
        pin.computeRNEADerivatives(free, data, q, np.zeros(nv), y)
        return data.dtau_dq.copy()

    roots = [model.idx_vs[j] + d for j in range(1, model.njoints) if model.parents[j] == 0 for d in range(model.nvs[j])]
    for q, y in _states(model, seed=11 + len(name)):
        dM, T = core.testing.mass_tensors(model, q, y)
        Iqq, _, _, dM_ref = core.rnea_second_order(free, q, np.zeros(nv), y, False)
        for got, ref in ((dM, dM_ref), (T, Iqq)):
            scale = max(1.0, np.abs(ref).max())
            assert np.abs(ref).max() > 1e-3  # not a comparison of zeros
            assert np.abs(got - ref).max() <= 1e-12 * scale, name
        h = 1e-6
        for k in range(nv):
            e = np.zeros(nv)
            e[k] = h
            qp, qm = pin.integrate(free, q, e), pin.integrate(free, q, -e)
            fd_M = (mass(qp) - mass(qm)) / (2 * h)
            fd_D = (D(qp, y) - D(qm, y)) / (2 * h)
            assert np.abs(dM[:, :, k] - fd_M).max() <= 1e-7 * max(1.0, np.abs(fd_M).max()), (name, k)
            assert np.abs(T[:, :, k] - fd_D).max() <= 1e-7 * max(1.0, np.abs(fd_D).max()), (name, k)
        assert roots and np.all(dM[:, :, roots] == 0.0) and np.all(T[:, :, roots] == 0.0)


@pytest.mark.parametrize("name", list(MODELS))
def test_mass_velocity_derivative_equals_pinocchio_and_differences(name):
    """D(q, y) = d(M(q) y)/dq (what the variational step forms at every Newton iteration and base
    point, by the same recursion) equals Pinocchio's dtau_dq at (q, 0, y) without gravity, and
    central differences of M(q) y along q exp(+-h e_k); a joint on the universe turns the whole tree
    rigidly: its columns are exactly zero."""
    model = MODELS[name]()
    free = _free(model)
    data = free.createData()
    nv = free.nv

    def My(q, y):
        M = pin.crba(free, data, q)
        return (np.triu(M) + np.triu(M, 1).T) @ y

    roots = [model.idx_vs[j] + d for j in range(1, model.njoints) if model.parents[j] == 0 for d in range(model.nvs[j])]
    for q, y in _states(model, seed=13 + len(name)):
        D = core.testing.mass_velocity_derivative(model, q, y)
        pin.computeRNEADerivatives(free, data, q, np.zeros(nv), y)
        ref = data.dtau_dq.copy()
        scale = max(1.0, np.abs(ref).max())
        assert np.abs(ref).max() > 1e-3  # not a comparison of zeros
        assert np.abs(D - ref).max() <= 1e-12 * scale, name
        h = 1e-6
        fd = np.stack([(My(pin.integrate(free, q, h * e), y) - My(pin.integrate(free, q, -h * e), y)) / (2 * h)
                       for e in np.eye(nv)], axis=1)
        assert np.abs(D - fd).max() <= 1e-7 * scale, name
        assert roots and np.all(D[:, roots] == 0.0)


def test_gravity_plays_no_part():
    model = MODELS["free_flyer_arm"]()
    q, y = next(_states(model, seed=1))
    assert np.array_equal(core.testing.kinetic_hessian(model, q, y), core.testing.kinetic_hessian(_free(model), q, y))


def test_joint_with_moving_subspace_refused():
    """Spherical ZYX (motion subspace moving with q) is none of the core's joint groups: refused by name."""
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelSphericalZYX(), pin.SE3.Identity(), "zyx")
    model.appendBodyToJoint(j, _inertia(np.random.default_rng(0)), pin.SE3.Identity())
    with pytest.raises(ValueError, match="'zyx' of type JointModelSphericalZYX is not supported"):
        core.testing.kinetic_hessian(model, pin.neutral(model), np.ones(model.nv))
