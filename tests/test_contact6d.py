"""6D (flat-foot) contacts and impulses of geoddp.models.contact.ContactDynamics on Talos' legs
(example-robot-data): the analytic first derivatives of the accelerations (v+ at an impulse), the
reported forces and the Euler step against central differences of the values; the exact second
derivatives (the KKT system differentiated twice) against central differences of those analytic
Jacobians, every entry; the one-step prediction test (errors falling 4x per halving at first
order, 8x at second); 6D and 3D feet mixed; and the inputs refused."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models.contact import ContactDynamics
from geoddp.validate import InputError

erd = pytest.importorskip("example_robot_data", reason="example-robot-data not installed: the 'robots' extra")


@pytest.fixture(scope="module")
def talos():
    model = erd.load("talos_legs").model
    feet = (model.getFrameId("right_sole_link"), model.getFrameId("left_sole_link"))
    return model, tuple(int(f) for f in feet)


def state(model, rng, impulse):
    q = pin.integrate(model, model.referenceConfigurations["half_sitting"], 0.1 * rng.standard_normal(model.nv))
    v = 0.5 * rng.standard_normal(model.nv)
    u = np.zeros(model.nv - 6) if impulse else 20.0 * rng.standard_normal(model.nv - 6)
    return q, v, u


def evaluate(dyn, impulse, feet, q, v, u, z, derivatives=False):
    nv = dyn.nv
    qz, vz, uz = pin.integrate(dyn.model, q, z[:nv]), v + z[nv:2 * nv], u + z[2 * nv:]
    return dyn.impulse(qz, vz, feet, derivatives) if impulse else dyn.contact(qz, vz, uz, feet, derivatives)


def chart_jacobians(dyn, impulse, feet, q, v, u, z):
    """(acceleration or v+ Jacobian, force Jacobian) at z in the chart of (q, v, u)."""
    ev = evaluate(dyn, impulse, feet, q, v, u, z, True)
    Rq = pin.dIntegrate(dyn.model, q, z[:dyn.nv], pin.ArgumentPosition.ARG1)
    A, L = ev.Az.copy(), ev.Lz.copy()
    A[:, :dyn.nv], L[:, :dyn.nv] = A[:, :dyn.nv] @ Rq, L[:, :dyn.nv] @ Rq
    return A, L


CASES = [("6d", (0.0, 30.0)), ("6d", (20.0, 30.0)), ("6d_local", (0.0, 30.0)), ("mixed", (0.0, 30.0))]


def dynamics(talos, kind, gains):
    model, (rf, lf) = talos
    kinds = {rf: "6d", lf: "3d"} if kind == "mixed" else {rf: kind, lf: kind}
    return ContactDynamics(model, 0.03, gains=gains, contact_kinds=kinds)


@pytest.mark.parametrize("kind,gains", CASES)
@pytest.mark.parametrize("impulse", [False, True])
@pytest.mark.parametrize("nfeet", [1, 2])
def test_first_derivatives_against_differences(talos, kind, gains, impulse, nfeet):
    dyn = dynamics(talos, kind, gains)
    feet = talos[1][:nfeet] if nfeet == 1 else talos[1]
    q, v, u = state(dyn.model, np.random.default_rng(nfeet + 10 * impulse), impulse)
    nv, nz = dyn.nv, 2 * dyn.nv + dyn.nu
    ev = evaluate(dyn, impulse, feet, q, v, u, np.zeros(nz), True)
    assert ev.forces.shape == (sum(dyn.force_dims(feet)),)
    h = 1e-6
    DA, DL, DF = np.zeros_like(ev.Az), np.zeros_like(ev.Lz), np.zeros_like(ev.Fz)
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = h
        p, m = evaluate(dyn, impulse, feet, q, v, u, e), evaluate(dyn, impulse, feet, q, v, u, -e)
        DA[:, j] = ((p.v_next - m.v_next) if impulse else (p.acc - m.acc)) / (2 * h)
        DL[:, j] = (p.forces - m.forces) / (2 * h)
        DF[:, j] = np.concatenate([pin.difference(dyn.model, m.q_next, p.q_next), p.v_next - m.v_next]) / (2 * h)
    for name, a, b in (("accelerations", ev.Az, DA), ("forces", ev.Lz, DL), ("step", ev.Fz, DF)):
        err = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1.0)
        assert err < 1e-7, (name, err)


@pytest.mark.parametrize("kind", ["6d", "mixed"])
@pytest.mark.parametrize("impulse", [False, True])
@pytest.mark.parametrize("nfeet", [1, 2])
def test_second_derivatives_against_differences(talos, kind, impulse, nfeet):
    """The exact second derivatives against central differences of the analytic Jacobians, every
    entry (1e-7 of the largest; the differences' own error is about 1e-10), symmetric."""
    dyn = dynamics(talos, kind, (0.0, 30.0))
    feet = talos[1][:nfeet] if nfeet == 1 else talos[1]
    q, v, u = state(dyn.model, np.random.default_rng(20 + nfeet + 10 * impulse), impulse)
    nz = 2 * dyn.nv + dyn.nu
    ev = evaluate(dyn, impulse, feet, q, v, u, np.zeros(nz), True)
    Y2, L2 = dyn.impulse_second(q, v, feet, ev) if impulse else dyn.contact_second(q, v, u, feet, ev)
    h = 1e-5
    DY, DL = np.zeros_like(Y2), np.zeros_like(L2)
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = h
        (Ap, Lp), (Am, Lm) = (chart_jacobians(dyn, impulse, feet, q, v, u, s * e) for s in (1.0, -1.0))
        DY[:, :, j], DL[:, :, j] = (Ap - Am) / (2 * h), (Lp - Lm) / (2 * h)
    for name, a, b in (("accelerations", Y2, DY), ("forces", L2, DL)):
        b = 0.5 * (b + b.transpose(0, 2, 1))
        err = np.max(np.abs(a - b)) / np.max(np.abs(b))
        assert err < 1e-7, (name, err)
        assert np.max(np.abs(a - a.transpose(0, 2, 1))) <= 1e-9 * np.max(np.abs(a))


@pytest.mark.parametrize("impulse", [False, True])
def test_one_step_prediction_halving(talos, impulse):
    """Along a random direction d: |y(s d) - y(0) - s Y' d| falls 4x per halving of s, and with
    s^2/2 d Y'' d subtracted too 8x (y: the accelerations or v+, and the forces)."""
    dyn = dynamics(talos, "6d", (0.0, 30.0))
    feet = talos[1]
    rng = np.random.default_rng(3)
    q, v, u = state(dyn.model, rng, impulse)
    nz = 2 * dyn.nv + dyn.nu
    ev = evaluate(dyn, impulse, feet, q, v, u, np.zeros(nz), True)
    Y2, L2 = dyn.impulse_second(q, v, feet, ev) if impulse else dyn.contact_second(q, v, u, feet, ev)
    d = rng.standard_normal(nz)
    if impulse:
        d[2 * dyn.nv:] = 0.0
    y0 = np.concatenate([ev.v_next if impulse else ev.acc, ev.forces])
    Y1, Y2 = np.vstack([ev.Az, ev.Lz]), np.concatenate([Y2, L2])
    e1, e2 = [], []
    for s in [4e-3 / 2**i for i in range(4)]:
        p = evaluate(dyn, impulse, feet, q, v, u, s * d)
        y = np.concatenate([p.v_next if impulse else p.acc, p.forces])
        lin = y0 + s * (Y1 @ d)
        e1.append(np.linalg.norm(y - lin))
        e2.append(np.linalg.norm(y - lin - 0.5 * s * s * np.einsum("ijk,j,k->i", Y2, d, d)))
    r1, r2 = np.array(e1[:-1]) / np.array(e1[1:]), np.array(e2[:-1]) / np.array(e2[1:])
    assert np.all(np.abs(r1 - 4) < 0.3), r1
    assert np.all(np.abs(r2 - 8) < 0.8), r2


def test_lwa_and_local_give_the_same_motion(talos):
    """LOCAL and LOCAL_WORLD_ALIGNED 6D contacts: the same accelerations (to round-off), forces
    related by the foot's rotation."""
    model, feet = talos
    q, v, u = state(model, np.random.default_rng(4), False)
    a = ContactDynamics(model, 0.03, gains=(0.0, 30.0), contact_kinds={f: "6d" for f in feet}).contact(q, v, u, feet)
    b = ContactDynamics(model, 0.03, gains=(0.0, 30.0), contact_kinds={f: "6d_local" for f in feet}).contact(q, v, u, feet)
    assert np.max(np.abs(a.acc - b.acc)) < 1e-9 * np.max(np.abs(a.acc))
    d = model.createData()
    pin.framesForwardKinematics(model, d, q)
    for i, f in enumerate(feet):
        R = d.oMf[f].rotation
        assert np.allclose(a.forces[6 * i:6 * i + 3], R @ b.forces[6 * i:6 * i + 3], rtol=0, atol=1e-8)
        assert np.allclose(a.forces[6 * i + 3:6 * i + 6], R @ b.forces[6 * i + 3:6 * i + 6], rtol=0, atol=1e-8)


def test_flat_feet_stay_flat(talos):
    """Quasi-static torques on both flat feet: the state stays at rest (the accelerations vanish),
    the vertical forces carry the weight and the feet's spatial accelerations are zero."""
    model, feet = talos
    dyn = ContactDynamics(model, 0.03, gains=(0.0, 30.0), contact_kinds={f: "6d" for f in feet})
    q = model.referenceConfigurations["half_sitting"].copy()
    u = dyn.quasi_static(q, feet)
    ev = dyn.contact(q, np.zeros(model.nv), u, feet)
    assert np.max(np.abs(ev.acc)) < 1e-9
    weight = pin.computeTotalMass(model) * 9.81
    assert abs(ev.forces[2] + ev.forces[8] - weight) < 1e-6 * weight


def test_inputs_refused(talos):
    model, feet = talos
    with pytest.raises(InputError) as e:
        ContactDynamics(model, 0.03, contact_kinds={feet[0]: "flat"})
    assert e.value.parameter == "contact_kinds"
    with pytest.raises(InputError) as e:
        ContactDynamics(model, 0.03, contact_kinds={"no_such_frame": "6d"})
    assert e.value.parameter == "contact_kinds"
    by_name = ContactDynamics(model, 0.03, contact_kinds={"right_sole_link": "6d"})
    assert by_name.kind(feet[0]) == "6d" and by_name.kind(feet[1]) == "3d"
    q, v, u = state(model, np.random.default_rng(0), False)
    dyn = ContactDynamics(model, 0.03, gains=(10.0, 30.0), contact_kinds={f: "6d" for f in feet})
    ev = dyn.contact(q, v, u, feet, True)
    with pytest.raises(InputError) as e:
        dyn.contact_second(q, v, u, feet, ev)
    assert e.value.parameter == "gains"
