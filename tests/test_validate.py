"""Tests for geoddp.validate: each validator accepts good input exactly and rejects bad input
with an InputError that names the parameter."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from geoddp import validate as v
from geoddp.validate import InputError


def raises(name: str, *fragments: str):
    """Context manager: expect InputError for parameter `name` whose message has `fragments`."""

    class _Ctx:
        def __enter__(self):
            self._cm = pytest.raises(InputError)
            self.info = self._cm.__enter__()
            return self.info

        def __exit__(self, *exc):
            suppressed = self._cm.__exit__(*exc)
            err = self.info.value
            assert err.parameter == name, (err.parameter, name)
            msg = str(err)
            assert msg.startswith(f"{name}: "), msg
            for frag in fragments:
                assert frag in msg, (frag, msg)
            return suppressed

    return _Ctx()


# ------------------------------------------------------------------ InputError


def test_input_error_is_value_error_with_parameter():
    e = InputError("initial.quaternion", "expected x, got y")
    assert isinstance(e, ValueError)
    assert e.parameter == "initial.quaternion"
    assert str(e) == "initial.quaternion: expected x, got y"
    assert str(e.with_source("a.toml")) == "initial.quaternion: expected x, got y (in a.toml)"


# ------------------------------------------------------------------ finite_array


def test_finite_array_returns_float64_copy():
    src = np.array([[1, 2], [3, 4]])
    out = v.finite_array(src, "x", shape=(2, None))
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [[1.0, 2.0], [3.0, 4.0]])
    out[0, 0] = 99.0
    assert src[0, 0] == 1  # a copy, not a view
    fsrc = np.array([1.5, 2.5])
    fout = v.finite_array(fsrc, "x")
    assert fout is not fsrc and not np.shares_memory(fout, fsrc)


def test_finite_array_scalar_and_wildcards():
    assert v.finite_array(3, "x", shape=()).shape == ()
    assert v.finite_array(np.zeros((7, 2)), "x", shape=(None, 2)).shape == (7, 2)
    # Python ints beyond int64 arrive as object dtype and are still accepted as numbers.
    assert v.finite_array([2**70], "x")[0] == float(2**70)


@pytest.mark.parametrize(
    "bad, fragment",
    [
        ([1.0, np.nan, 3.0], "nan"),
        ([[1.0, 2.0], [np.inf, 0.0]], "inf"),
        ([1.0, -np.inf], "-inf"),
        (np.nan, "nan"),
    ],
)
def test_finite_array_rejects_nonfinite_anywhere(bad, fragment):
    with raises("w", "finite", fragment):
        v.finite_array(bad, "w")


@pytest.mark.parametrize(
    "bad",
    ["1.0", None, [1.0, "a"], [True, False], [1 + 2j], [[1.0, 2.0], [3.0]], {"a": 1}, [1.0, None]],
)
def test_finite_array_rejects_non_numeric(bad):
    with raises("w", "expected"):
        v.finite_array(bad, "w")


@pytest.mark.parametrize(
    "x, shape",
    [([1.0, 2.0], (3,)), (np.zeros((3, 3)), (3,)), (np.zeros((2, 3)), (3, None)), (1.0, (1,)), ([1.0], ())],
)
def test_finite_array_rejects_wrong_shape(x, shape):
    with raises("w", "shape", str(np.shape(x))):
        v.finite_array(x, "w", shape=shape)


# ------------------------------------------------------------------ rotations and quaternions


def test_rotation_matrix_accepts_rotation_exactly():
    R = Rotation.from_euler("XZ", [30, 70], degrees=True).as_matrix()
    out = v.rotation_matrix(R, "R")
    np.testing.assert_array_equal(out, R)
    np.testing.assert_array_equal(v.rotation_matrix(np.eye(3), "R"), np.eye(3))


def test_rotation_matrix_rejects_non_orthonormal():
    R = np.eye(3)
    R[0, 1] = 1e-6
    with raises("target.rotation", "orthonormal", "R^T R - I"):
        v.rotation_matrix(R, "target.rotation")
    with raises("R", "orthonormal"):
        v.rotation_matrix(2.0 * np.eye(3), "R")


def test_rotation_matrix_rejects_reflection():
    with raises("R", "det", "reflection"):
        v.rotation_matrix(np.diag([1.0, 1.0, -1.0]), "R")
    with raises("R", "det"):
        v.rotation_matrix(-np.eye(3), "R")


def test_rotation_matrix_tolerance_is_respected():
    R = np.eye(3)
    R[0, 1] = 1e-10
    v.rotation_matrix(R, "R")  # within default 1e-9
    with raises("R", "orthonormal"):
        v.rotation_matrix(R, "R", tol=1e-12)


@pytest.mark.parametrize(
    "bad", [np.eye(2), np.eye(4), np.zeros(9), [[1, 0, 0], [0, 1, 0], [0, 0, np.nan]]]
)
def test_rotation_matrix_rejects_bad_shape_or_nan(bad):
    with raises("R"):
        v.rotation_matrix(bad, "R")


def test_unit_quaternion_accepts_exactly():
    q = [0.0, 0.0, 0.0, 1.0]
    np.testing.assert_array_equal(v.unit_quaternion(q, "q"), q)


def test_unit_quaternion_rejects_norm_1_1():
    q = np.array([0.0, 0.0, 0.0, 1.1])
    with raises("initial.quaternion", "norm", "1.1"):
        v.unit_quaternion(q, "initial.quaternion")


@pytest.mark.parametrize("bad", [[0.0, 0.0, 1.0], [0, 0, 0, 0, 1], [[0, 0], [0, 1]], [0, 0, np.nan, 1], [0.0] * 4])
def test_unit_quaternion_rejects_bad(bad):
    with raises("q"):
        v.unit_quaternion(bad, "q")


def test_quaternion_to_rotation_matches_pinocchio_and_scipy_xyzw():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        R = v.quaternion_to_rotation(q)
        R_pin = pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix()
        R_sp = Rotation.from_quat(q).as_matrix()  # scipy is (x, y, z, w) too
        np.testing.assert_allclose(R, R_pin, atol=1e-14)
        np.testing.assert_allclose(R, R_sp, atol=1e-14)
    # 90 degrees about z: the w component is last.
    s = np.sqrt(0.5)
    np.testing.assert_allclose(
        v.quaternion_to_rotation([0, 0, s, s]), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15
    )


def test_quaternion_to_rotation_validates():
    with raises("quaternion", "norm"):
        v.quaternion_to_rotation([0, 0, 0, 2])


# ------------------------------------------------------------------ spd_matrix


def test_spd_matrix_forms():
    np.testing.assert_array_equal(v.spd_matrix(0.1, "S", 3), 0.1 * np.eye(3))
    np.testing.assert_array_equal(v.spd_matrix([1, 2, 3], "S", 3), np.diag([1.0, 2.0, 3.0]))
    M = np.array([[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_array_equal(v.spd_matrix(M, "S", 2), M)


def test_spd_matrix_form_restrictions():
    with raises("S", "3x3 matrix", "()"):
        v.spd_matrix(1.0, "S", 3, allow_scalar=False)
    with raises("S", "3x3 matrix", "(3,)"):
        v.spd_matrix([1, 2, 3], "S", 3, allow_vector=False)
    with raises("S", "length-3 vector", "(2,)"):
        v.spd_matrix([1, 2], "S", 3)
    with raises("S", "shape (2, 2)"):
        v.spd_matrix(np.eye(2), "S", 3)


def test_spd_matrix_rejects_non_symmetric():
    with raises("[cost].control", "symmetric"):
        v.spd_matrix([[1.0, 0.1], [0.0, 1.0]], "[cost].control", 2)


@pytest.mark.parametrize("bad", [[[1.0, 2.0], [2.0, 1.0]], 0.0, -1.0, [1.0, -1.0], [1.0, 0.0]])
def test_spd_matrix_rejects_indefinite_or_singular(bad):
    with raises("S", "positive definite", "eigenvalue"):
        v.spd_matrix(bad, "S", 2)


def test_spd_matrix_semidefinite():
    np.testing.assert_array_equal(v.spd_matrix(0.0, "S", 3, semidefinite=True), np.zeros((3, 3)))
    np.testing.assert_array_equal(
        v.spd_matrix([1.0, 0.0, 2.0], "S", 3, semidefinite=True), np.diag([1.0, 0.0, 2.0])
    )
    with raises("S", "positive semidefinite"):
        v.spd_matrix([1.0, -1e-3, 2.0], "S", 3, semidefinite=True)
    with raises("S", "positive semidefinite"):
        v.spd_matrix(-1.0, "S", 3, semidefinite=True)


def test_spd_matrix_rejects_nan():
    with raises("S", "finite"):
        v.spd_matrix([[1.0, np.nan], [np.nan, 1.0]], "S", 2)


# ------------------------------------------------------------------ inertia and actuation


def test_inertia_matrix_accepts_vector_and_matrix():
    np.testing.assert_array_equal(v.inertia_matrix([10.0, 11.1, 13.0]), np.diag([10.0, 11.1, 13.0]))
    J = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    I = J @ np.diag([1.0, 2.0, 2.5]) @ J.T
    I = 0.5 * (I + I.T)
    np.testing.assert_array_equal(v.inertia_matrix(I), I)
    # boundary cases: a flat lamina (equality) and the long slender rod 1:1000.
    v.inertia_matrix([1.0, 1.0, 2.0])
    v.inertia_matrix([1.0, 1000.0, 1000.0])


@pytest.mark.parametrize("bad", [[-1.0, 2.0, 2.0], [0.0, 1.0, 1.0], [[1, 0, 0], [0, 1, 0], [0, 0, -1]]])
def test_inertia_matrix_rejects_non_positive(bad):
    with raises("inertia", "positive definite"):
        v.inertia_matrix(bad)


@pytest.mark.parametrize("bad", [[1.0, 1.0, 3.0], [1.0, 1000.0, 1002.0], [1.0, 500.0, 500.0 + 1.0 + 1e-4]])
def test_inertia_matrix_rejects_triangle_inequality(bad):
    with raises("inertia", "triangle inequality"):
        v.inertia_matrix(bad)


def test_inertia_matrix_rejects_triangle_violation_in_rotated_frame():
    J = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    I = J @ np.diag([1.0, 1.0, 3.0]) @ J.T
    with raises("[model].inertia", "triangle"):
        v.inertia_matrix(0.5 * (I + I.T), "[model].inertia")


def test_inertia_matrix_rejects_scalar_and_bad_shape():
    with raises("inertia", "length-3 vector or a 3x3 matrix"):
        v.inertia_matrix(5.0)
    with raises("inertia"):
        v.inertia_matrix([1.0, 2.0])


def test_actuation_matrix_accepts():
    H = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]
    np.testing.assert_array_equal(v.actuation_matrix(H), H)
    np.testing.assert_array_equal(v.actuation_matrix([[1.0], [2.0], [3.0]]), [[1.0], [2.0], [3.0]])


def test_actuation_matrix_rejects_zero_column():
    with raises("actuation", "non-zero", "column 1"):
        v.actuation_matrix([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])


@pytest.mark.parametrize("bad", [[1.0, 0.0, 0.0], np.zeros((3, 0)), np.eye(2), np.zeros((4, 3)), [[1, 0], [0, np.inf], [0, 0]]])
def test_actuation_matrix_rejects_bad_shape(bad):
    with raises("actuation"):
        v.actuation_matrix(bad)


def test_actuation_matrix_flat_vector_hint():
    with raises("actuation", "[[a], [b], [c]]"):
        v.actuation_matrix([1.0, 0.0, 0.0])


# ------------------------------------------------------------------ scalars


def test_scalar_validators_accept():
    assert v.positive_float(0.5, "x") == 0.5 and isinstance(v.positive_float(2, "x"), float)
    assert v.nonnegative_float(0, "x") == 0.0
    assert v.positive_int(200, "x") == 200
    assert v.nonnegative_int(0, "x") == 0
    assert v.positive_int(np.int64(3), "x") == 3
    assert v.bounded_float(0.1, "s", 0.0, 1.0, False, False) == 0.1


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, np.inf, "1", True, None, [1.0]])
def test_positive_float_rejects(bad):
    with raises("horizon.dt"):
        v.positive_float(bad, "horizon.dt")


def test_negative_tol_rejected():
    with raises("[solver].tol", ">= 0", "-1e-08"):
        v.nonnegative_float(-1e-8, "[solver].tol")
    with raises("tol"):
        v.nonnegative_float(np.nan, "tol")


def test_max_iter_zero_rejected():
    with raises("[solver].max_iter", ">= 1", "got 0"):
        v.positive_int(0, "[solver].max_iter")


@pytest.mark.parametrize("bad", [2.0, 1.5, True, "3", None])
def test_ints_reject_non_integers(bad):
    with raises("n"):
        v.positive_int(bad, "n")
    with raises("n"):
        v.nonnegative_int(bad, "n")


def test_nonnegative_int_rejects_negative():
    with raises("n", ">= 0"):
        v.nonnegative_int(-1, "n")


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.5, 1.5])
def test_bounded_float_open_interval(bad):
    with raises("[solver].switch_ratio", "(0, 1)"):
        v.bounded_float(bad, "[solver].switch_ratio", 0.0, 1.0, False, False)


# ------------------------------------------------------------------ choice


def test_choice_accepts():
    assert v.choice("euler", "i", {"euler", "semi_implicit"}) == "euler"


def test_choice_rejects_with_suggestion_and_options():
    with raises("[horizon].integrator", "euler | semi_implicit", "did you mean 'semi_implicit'"):
        v.choice("semi-implicit", "[horizon].integrator", {"euler", "semi_implicit"})
    with raises("e", "did you mean 'switch'"):
        v.choice("swich", "e", ["first", "second", "switch"])
    with raises("e", "did you mean 'first'"):
        v.choice("First", "e", ["first", "second", "switch"])


def test_choice_no_suggestion_when_nothing_close():
    with pytest.raises(InputError) as info:
        v.choice("zzzzzz", "e", ["first", "second", "switch"])
    assert "did you mean" not in str(info.value)
    assert "first | second | switch" in str(info.value)


def test_choice_rejects_non_string():
    with raises("e", "first | second"):
        v.choice(1, "e", ["first", "second"])


# ------------------------------------------------------------------ time grid


def test_time_grid_accepts():
    assert v.time_grid(3.0, 0.01) == 300
    assert v.time_grid(30.0, 0.01) == 3000
    assert v.time_grid(0.5, 1e-4) == 5000
    assert v.time_grid(3, 0.1) == 30
    assert v.time_grid(0.3, 0.1) == 3  # 0.3/0.1 = 2.9999999999999996 in floating point


@pytest.mark.parametrize("dt", [0.0, -0.01, np.nan, np.inf])
def test_time_grid_rejects_bad_dt(dt):
    with raises("horizon.dt"):
        v.time_grid(3.0, dt)


@pytest.mark.parametrize("tf", [0.0, -3.0, np.nan])
def test_time_grid_rejects_bad_tf(tf):
    with raises("horizon.tf"):
        v.time_grid(tf, 0.01)


@pytest.mark.parametrize("tf, dt", [(1.0, 0.3), (3.005, 0.01), (3.0 + 1e-7, 0.01), (0.004, 0.01)])
def test_time_grid_rejects_non_multiple(tf, dt):
    with raises("horizon.tf", "horizon.dt"):
        v.time_grid(tf, dt)


def test_time_grid_custom_names():
    with raises("tf"):
        v.time_grid(1.0, 0.3, tf_name="tf", dt_name="dt")


# ------------------------------------------------------------------ properties (hypothesis)

from hypothesis import example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402

_reals = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, 4, elements=_reals).filter(lambda q: np.linalg.norm(q) > 1e-3))
def test_property_any_normalised_quaternion_gives_a_valid_rotation(q):
    q = q / np.linalg.norm(q)
    R = v.quaternion_to_rotation(q)
    np.testing.assert_array_equal(v.rotation_matrix(R, "R", tol=1e-13), R)
    # q and -q are the same rotation.
    np.testing.assert_allclose(v.quaternion_to_rotation(-q), R, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, (3, 3), elements=_reals))
def test_property_gram_plus_identity_is_spd_and_returned_exactly(A):
    S = A @ A.T + np.eye(3)
    S = 0.5 * (S + S.T)
    np.testing.assert_array_equal(v.spd_matrix(S, "S", 3), S)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(1e-3, 1e3)))
def test_property_inertia_accepts_iff_triangle_inequality(moments):
    a, b, c = np.sort(moments)
    if c <= a + b:
        np.testing.assert_array_equal(v.inertia_matrix(moments), np.diag(moments))
    elif c > (a + b) * (1 + 1e-6):
        with raises("inertia", "triangle"):
            v.inertia_matrix(moments)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 100000), st.sampled_from([1e-4, 1e-3, 0.01, 0.02, 0.05, 0.1, 0.25]))
def test_property_time_grid_recovers_step_count(H, dt):
    assert v.time_grid(H * dt, dt) == H


def test_threads_from_the_environment(monkeypatch):
    from geoddp.validate import threads_from_environment

    monkeypatch.delenv("GEODDP_THREADS", raising=False)
    assert threads_from_environment() == 0
    monkeypatch.setenv("GEODDP_THREADS", " 3 ")
    assert threads_from_environment() == 3
    for bad in ("0", "-1", "two", "1.5", "5000"):
        monkeypatch.setenv("GEODDP_THREADS", bad)
        with pytest.raises(InputError, match="GEODDP_THREADS") as exc:
            threads_from_environment()
        assert repr(bad) in str(exc.value)


def test_multibody_threads_follow_the_environment_and_one_thread_means_no_speculation(monkeypatch):
    import numpy as np

    from geoddp.data import urdf_path
    from geoddp.models.multibody import Multibody
    from geoddp.solver import backward

    monkeypatch.setenv("GEODDP_THREADS", "1")
    mb = Multibody(urdf_path("quadrotor.urdf"), root="free_flyer", dt=0.01)
    assert mb.threads == 1
    assert Multibody(urdf_path("quadrotor.urdf"), root="free_flyer", dt=0.01, threads=2).threads == 2  # explicit wins
    lin = type("Lin", (), {"second_order": object(), "Phi": np.zeros((1, 12, 12))})()
    assert backward._speculation_pool(lin) is None
    monkeypatch.delenv("GEODDP_THREADS")
    assert Multibody(urdf_path("quadrotor.urdf"), root="free_flyer", dt=0.01).threads == 0  # the core's default
    monkeypatch.setenv("GEODDP_THREADS", "lots")
    with pytest.raises(InputError, match="GEODDP_THREADS"):
        Multibody(urdf_path("quadrotor.urdf"), root="free_flyer", dt=0.01)


def _outcome(fn):
    """(returned array, None) or (None, the InputError's message)."""
    try:
        return fn(), None
    except InputError as e:
        return None, str(e)


_weights = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e100, 2e100, -1e-9]))


@settings(max_examples=200, deadline=None)
@given(st.one_of(_weights, arrays(np.float64, 4, elements=_weights)), st.booleans())
@example(np.array([1.0, -1e-9, 0.0, 2.0]), True)    # refused: below -1e-12 max|S|
@example(np.array([1.0, -1e-13, 0.0, 2.0]), True)   # accepted as semidefinite: round-off
@example(np.array([1.0, 0.0, 3.0, 2.0]), False)     # singular: refused as definite
@example(np.array([1.0, 1e100, 3.0, 2e100]), True)  # above MAX_WEIGHT
@example(-0.0, True)
def test_property_scalar_and_diagonal_weights_decide_as_the_full_matrix_does(w, semidefinite):
    """spd_matrix takes s I and diag(S) by their entries' signs; the same weight given as the full
    (4, 4) matrix goes through the symmetry and eigenvalue checks: the same matrix, bit for bit,
    or the same refusal."""
    D = np.diag(np.full(4, float(w)) if np.ndim(w) == 0 else w)
    fast, fast_err = _outcome(lambda: v.spd_matrix(w, "W", 4, semidefinite=semidefinite))
    full, full_err = _outcome(lambda: v.spd_matrix(D, "W", 4, semidefinite=semidefinite))
    assert fast_err == full_err
    if fast is not None:
        assert np.array_equal(fast, full) and np.array_equal(np.signbit(fast), np.signbit(full))


@settings(max_examples=200, deadline=None)
@given(st.floats(allow_nan=True, allow_infinity=True))
def test_property_finite_float_shortcut_returns_what_the_array_checks_return(x):
    """finite_float's shortcut for a finite Python float returns what the array checks return
    for it (sign of zero included); NaN and inf still meet those checks and their message."""
    fast, fast_err = _outcome(lambda: v.finite_float(x, "x"))
    full, full_err = _outcome(lambda: float(v.finite_array(x, "x", shape=())))
    assert fast_err == full_err
    if fast is not None:
        assert type(fast) is float and fast == full and np.signbit(fast) == np.signbit(full)
