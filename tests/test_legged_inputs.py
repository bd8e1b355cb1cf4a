"""Bad input to the legged-robot layer is an InputError naming the parameter."""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models.contact import ContactDynamics, friction_cone
from geoddp.problem.legged import ContactProblem, Node, QuadrupedGait
from geoddp.scene.legged import anymal_gait, load_anymal
from geoddp.validate import InputError


@pytest.fixture(scope="module")
def robot():
    return load_anymal()


def parameter(call):
    with pytest.raises(InputError) as err:
        call()
    return err.value.parameter


def test_bad_inputs_name_their_parameter(robot):
    model = robot.model
    fixed = pin.buildSampleModelManipulator()
    assert parameter(lambda: friction_cone(0.7, 3)) == "facets"
    assert parameter(lambda: ContactDynamics(fixed, 0.01)) == "model"
    assert parameter(lambda: ContactDynamics(model, 0.0)) == "dt"
    assert parameter(lambda: Node("flight", (1,))) == "kind"
    assert parameter(lambda: QuadrupedGait(model, ("LF_FOOT", "RF_FOOT", "LH_FOOT", "NO_FOOT"))) == "feet"
    assert parameter(lambda: anymal_gait("gallop", robot)) == "gait"
    dyn = ContactDynamics(model, 0.01)
    q0 = model.referenceConfigurations["standing"].copy()
    v0 = np.zeros(model.nv)
    node = Node("contact", tuple(model.getFrameId(f) for f in ("LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT")))
    assert parameter(lambda: ContactProblem(dyn, [], node, q0, v0, (q0, v0))) == "nodes"
    bad_q = q0.copy()
    bad_q[3:7] *= 2.0
    assert parameter(lambda: ContactProblem(dyn, [node], node, bad_q, v0, (q0, v0))) == "q0"
    assert parameter(lambda: ContactProblem(dyn, [node], node, q0, v0[:5], (q0, v0))) == "v0"
    problem = ContactProblem(dyn, [node, Node("impulse", node.feet)], node, q0, v0, (q0, v0))
    assert parameter(lambda: problem.check_controls(np.zeros((3, 12)))) == "initial_controls"
    U = problem.check_controls(np.ones((2, 12)))
    assert np.all(U[0] == 1.0) and np.all(U[1] == 0.0)  # the impulse node's row is zeroed
