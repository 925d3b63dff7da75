"""Diagnostics of a hand in a namespace say which hand; at the root they stay as the node made them."""
from prisma_common.diagnostics import OK, WARN, DiagnosticStatusData, in_namespace, namespace_prefix, of_namespace

FINGERS_MOTOR = DiagnosticStatusData("motor_driver: fingers", OK, "ok", "sim#1", {"id": "1"})
MODEL = DiagnosticStatusData("force_estimator: thumb", WARN, "1 rejected", "")


def test_the_prefix_of_a_namespace():
    assert [namespace_prefix(ns) for ns in ("", "/", "/left", "left", "/robot/left/")] == \
        ["", "", "left/", "left/", "robot/left/"]


def test_a_namespaced_node_names_its_hand_in_the_name_and_hardware_id():
    left, right = in_namespace([FINGERS_MOTOR], "/left"), in_namespace([FINGERS_MOTOR], "/right")
    assert [(s.name, s.hardware_id) for s in left] == [("left/motor_driver: fingers", "left/sim#1")]
    assert [(s.name, s.hardware_id) for s in right] == [("right/motor_driver: fingers", "right/sim#1")]
    assert (left[0].level, left[0].message, left[0].values) == (OK, "ok", {"id": "1"})
    # no hardware ID stays none; the node's own status is left as it was
    assert in_namespace([MODEL], "/left")[0].hardware_id == ""
    assert FINGERS_MOTOR.name == "motor_driver: fingers"


def test_at_the_root_the_statuses_are_unchanged():
    assert in_namespace([FINGERS_MOTOR, MODEL], "/") == [FINGERS_MOTOR, MODEL]
    assert in_namespace([FINGERS_MOTOR], "") == [FINGERS_MOTOR]


def test_a_reader_of_one_hand_takes_its_statuses_back_and_no_others():
    published = (in_namespace([FINGERS_MOTOR, MODEL], "/left") + in_namespace([FINGERS_MOTOR], "/right")
                 + [FINGERS_MOTOR] + in_namespace([FINGERS_MOTOR], "/left/inner"))
    left = [of_namespace(s, "left") for s in published]
    assert left == [FINGERS_MOTOR, MODEL, None, None, None]
    assert [of_namespace(s, "") for s in published] == [None, None, None, FINGERS_MOTOR, None]
    assert [of_namespace(s, "/right") for s in published] == [None, None, FINGERS_MOTOR, None, None]
    # a hardware ID that is a path keeps its own slashes
    port = DiagnosticStatusData("motor_driver: bus", OK, "ok", "/dev/ttyUSB0")
    assert of_namespace(in_namespace([port], "/left")[0], "/left") == port
    assert of_namespace(port, "") == port
