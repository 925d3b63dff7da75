"""The words and decisions of a launch that refuses to start or stops whole (launch_refusals.py):
the closest declared argument first, the nodes of a hand already running, the reason a node gave
last, the launch's last line."""
from __future__ import annotations

from prisma_bringup.launch_refusals import (
    LAUNCH_OWN_ARGUMENTS,
    STARTUP_S,
    by_closeness,
    nodes_already_running,
    reason_in_output,
    second_hand_refusal,
    stopped_because,
    unknown_arguments,
)

HAND_ARGUMENTS = ["sim", "tactile_backend", "tactile_port", "motor_backend", "motor_port", "model_bundle",
                  "namespace", "hardware", "emulator_dir", "sim_object", "frame_prefix", "hand_config", "home",
                  "rviz", "parts", "rt_priority", "nice"]


def test_a_misspelt_argument_is_refused_naming_the_one_meant_and_listing_all_closest_first():
    message = unknown_arguments("hand.launch.py", ["simulation", "sim_object"], HAND_ARGUMENTS)
    assert message is not None
    assert message.startswith("hand.launch.py: unknown argument 'simulation'; did you mean 'sim'? Starting nothing. "
                              "Its arguments: sim, ")
    listed = message.split("Its arguments: ")[1].split(", ")
    assert sorted(listed) == sorted(HAND_ARGUMENTS)  # every declared one, each once
    assert listed[:3] == ["sim", "emulator_dir", "sim_object"]
    message = unknown_arguments("hand.launch.py", ["tactile_prot"], HAND_ARGUMENTS)
    assert message is not None and "unknown argument 'tactile_prot'; did you mean 'tactile_port'?" in message
    assert message.split("Its arguments: ")[1].startswith("tactile_port, tactile_backend, ")


def test_an_argument_like_none_is_refused_without_a_guess_and_several_are_named_each():
    message = unknown_arguments("glove.launch.py", ["xyzzy"], ["backend", "port"])
    assert message == "glove.launch.py: unknown argument 'xyzzy'. Starting nothing. Its arguments: backend, port"
    message = unknown_arguments("hand.launch.py", ["simulation", "prot"], HAND_ARGUMENTS)
    assert message is not None and message.startswith(
        "hand.launch.py: unknown argument 'prot'; did you mean 'parts'? unknown argument 'simulation'; did you "
        "mean 'sim'? Starting nothing. Its arguments: parts, ")


def test_declared_arguments_and_ros2_launchs_own_pass():
    assert unknown_arguments("hand.launch.py", ["sim", "namespace"], HAND_ARGUMENTS) is None
    assert unknown_arguments("hand.launch.py", [], HAND_ARGUMENTS) is None
    assert unknown_arguments("hand.launch.py", sorted(LAUNCH_OWN_ARGUMENTS), HAND_ARGUMENTS) is None


def test_by_closeness_puts_a_prefix_first():
    assert by_closeness("simulation", ["sim_object", "sim", "nice"])[0] == "sim"
    assert by_closeness("rviz", ["rviz", "rt_priority"]) == ["rviz", "rt_priority"]


def test_nodes_already_running_in_the_namespace_only():
    graph = ["/tactile_driver", "/left/motor_driver", "/left/tactile_driver", "/rviz2"]
    assert nodes_already_running(graph, "", ["tactile_driver", "motor_driver"]) == ["/tactile_driver"]
    assert nodes_already_running(graph, "left", ["tactile_driver", "motor_driver"]) == [
        "/left/tactile_driver", "/left/motor_driver"]
    assert nodes_already_running(graph, "/left/", ["motor_driver"]) == ["/left/motor_driver"]
    assert nodes_already_running(graph, "right", ["tactile_driver", "motor_driver"]) == []


def test_second_hand_refusal_names_the_nodes_and_the_fix():
    assert second_hand_refusal("hand.launch.py", "", ["/tactile_driver", "/motor_driver"]) == (
        "hand.launch.py: a hand already runs in the root namespace (/tactile_driver, /motor_driver): starting "
        "nothing. Stop that launch first (ctrl-C), or start this hand under its own namespace:=")
    assert "runs in namespace 'left' (/left/motor_driver)" in second_hand_refusal("teleop.launch.py", "/left",
                                                                                 ["/left/motor_driver"])


def test_the_reason_is_the_last_fatal_line_else_the_last_line():
    lines = ["[INFO] [1733600000.100000000] [force_estimator]: loading",
             "[FATAL] [1733600000.123456789] [force_estimator]: model bundle /nonexistent: directory does not exist",
             "", "[INFO] [1733600000.2] [rclpy]: shutting down"]
    assert reason_in_output(lines) == "model bundle /nonexistent: directory does not exist"
    # a FATAL logged with the node's namespace in its logger name
    assert reason_in_output(["[FATAL] [1.5] [left.motor_driver]: bad port: give motor_port:="]) == (
        "bad port: give motor_port:=")
    traceback = ["Traceback (most recent call last):", '  File "x.py", line 1, in <module>',
                 "ValueError: something the node did not expect", ""]
    assert reason_in_output(traceback) == "ValueError: something the node did not expect"
    assert reason_in_output([]) == "it said nothing (see its lines above)"


def test_the_launchs_last_line_names_the_node_its_exit_and_its_reason():
    assert stopped_because("hand.launch.py", "motor_driver", 1, 2.5, "invalid parameter 'baud' = 7") == (
        "hand.launch.py: motor_driver exited 1 at start-up: invalid parameter 'baud' = 7; every node of this "
        "launch is stopped")
    assert stopped_because("teleop.launch.py", "/left/teleop", 1, STARTUP_S + 90.4, "glove lost") == (
        "teleop.launch.py: /left/teleop exited 1 after 120 s: glove lost; every node of this launch is stopped")
