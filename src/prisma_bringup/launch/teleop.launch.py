"""Teleoperation: a glove drives the hand (docs/teleoperation.md).

    ros2 launch prisma_bringup teleop.launch.py                                # hand-pose glove (synthetic), sim hand
    ros2 launch prisma_bringup teleop.launch.py glove:=none                    # your glove on /glove/joint_states
    ros2 launch prisma_bringup teleop.launch.py input:=stag                    # STAG glove (sim stream) -> grasps
    ros2 launch prisma_bringup teleop.launch.py input:=stag glove_backend:=replay replay_file:=/tmp/stag_poses.h5
    ros2 launch prisma_bringup teleop.launch.py hardware:=emulated             # the hand's hardware paths, emulated

Starts hand.launch.py (hardware:=sim: the simulated hand holding sim_object; hardware:=emulated:
prisma-hand-emulator's servos and pads, homed at start; hand.launch.py's hardware:= in the same words),
the teleop node (prisma_teleop, parameters from config/teleop.yaml) and the glove: with
input:=joint_states the synthetic_glove node (a scripted operator closing around the ball, holding,
opening, sweeping the thumb) unless glove:=none; with input:=stag glove.launch.py (glove_driver with
glove_backend, glove_perception) unless glove:=none. engage:=true (the default here) has the teleop
node take the hand as soon as the glove's input flows; engage:=false waits for
`ros2 service call /teleop/engage std_srvs/srv/SetBool "{data: true}"`.

It starts whole or not at all, as hand.launch.py does (prisma_bringup/launch_nodes.py): an argument it
does not declare is refused, the teleop node and the glove are required with the hand's nodes.
"""
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

from prisma_bringup.launch_nodes import checked_launch_description, control_path_node
from prisma_common.scheduling import CONTROL_PATH_NICE, CONTROL_PATH_RT_PRIORITY


def declared_arguments() -> list[DeclareLaunchArgument]:
    return [
        DeclareLaunchArgument("input", default_value="joint_states", choices=["joint_states", "stag"],
                              description="joint_states: a hand-pose glove's joint angles; stag: the STAG glove's "
                                          "hand poses and pressure"),
        DeclareLaunchArgument("hardware", default_value="sim", choices=["sim", "emulated"],
                              description="sim: the simulated hand; emulated: the drivers' hardware paths on "
                                          "prisma-hand-emulator (homed at start)"),
        DeclareLaunchArgument("glove", default_value="synthetic", choices=["synthetic", "none"],
                              description="synthetic: the synthetic_glove node (joint_states) or glove.launch.py "
                                          "(stag); none: the glove is started elsewhere"),
        DeclareLaunchArgument("glove_backend", default_value="sim", choices=["sim", "serial", "replay"],
                              description="input:=stag: glove_driver's source"),
        DeclareLaunchArgument("glove_port", default_value="/dev/ttyACM0",
                              description="input:=stag glove_backend:=serial: the readout board's port"),
        DeclareLaunchArgument("replay_file", default_value="",
                              description="input:=stag glove_backend:=replay: the dataset file "
                                          "(prisma-teleop-stag-session writes a session of held poses)"),
        DeclareLaunchArgument("engage", default_value="true", choices=["true", "false"],
                              description="the teleop node takes the hand as soon as the glove's input flows"),
        DeclareLaunchArgument("calibration_file", default_value="",
                              description="the operator's calibration YAML (input:=joint_states): loaded if it "
                                          "exists, written by the ~/capture_* services"),
        DeclareLaunchArgument("sim_object", default_value="pinch_ball",
                              description="hardware:=sim: the object in the hand (pinch_ball, power_ball, "
                                          "lateral_card, none)"),
        DeclareLaunchArgument("emulator_dir", default_value="/tmp/prisma_hand_emulator",
                              description="hardware:=emulated: where the emulator's devices appear"),
        DeclareLaunchArgument("namespace", default_value="", description="the hand's namespace (teleop and glove too)"),
        DeclareLaunchArgument("rviz", default_value="false", choices=["true", "false"],
                              description="open RViz with the hand"),
        DeclareLaunchArgument("rt_priority", default_value=str(CONTROL_PATH_RT_PRIORITY),
                              description="SCHED_FIFO priority of the control path, the glove and the teleop node "
                                          "with it (1-99; 0: no real-time scheduling)"),
        DeclareLaunchArgument("nice", default_value=str(CONTROL_PATH_NICE),
                              description="Niceness of the control path where real-time scheduling is not asked for "
                                          "or not permitted"),
    ]


def generate_launch_description():
    launch_dir = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "launch"])
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    teleop_input = LaunchConfiguration("input")
    glove = LaunchConfiguration("glove")
    namespace = LaunchConfiguration("namespace")
    emulated = PythonExpression(["'", LaunchConfiguration("hardware"), "' == 'emulated'"])
    hand = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "hand.launch.py"])),
        launch_arguments={"hardware": LaunchConfiguration("hardware"),
                          "home": PythonExpression(["'true' if ", emulated, " else 'false'"]),
                          "emulator_dir": LaunchConfiguration("emulator_dir"),
                          "sim_object": LaunchConfiguration("sim_object"),
                          "namespace": namespace,
                          "rviz": LaunchConfiguration("rviz"),
                          "rt_priority": LaunchConfiguration("rt_priority"),
                          "nice": LaunchConfiguration("nice")}.items(),
    )
    stag_glove = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "glove.launch.py"])),
        launch_arguments={"backend": LaunchConfiguration("glove_backend"),
                          "port": LaunchConfiguration("glove_port"),
                          "replay_file": LaunchConfiguration("replay_file"),
                          "namespace": namespace}.items(),
        condition=IfCondition(PythonExpression(["'", teleop_input, "' == 'stag' and '", glove, "' != 'none'"])),
    )
    # the glove's targets drive the hand now: held up behind a busy process they would end the goal
    # input_stale, so the glove and the teleop node run on the control path's rung
    synthetic_glove = control_path_node(
        package="prisma_teleop", executable="synthetic_glove", namespace=namespace,
        parameters=[PathJoinSubstitution([config, "synthetic_glove.yaml"])],
        condition=IfCondition(PythonExpression(["'", teleop_input, "' == 'joint_states' and '", glove,
                                                "' != 'none'"])))
    teleop = control_path_node(
        package="prisma_teleop", executable="teleop", namespace=namespace,
        parameters=[PathJoinSubstitution([config, "teleop.yaml"]),
                    {"input": teleop_input,
                     "engage_at_start": ParameterValue(LaunchConfiguration("engage"), value_type=bool),
                     "calibration_file": ParameterValue(LaunchConfiguration("calibration_file"), value_type=str)}])
    return checked_launch_description(declared_arguments(), [hand, stag_glove, synthetic_glove, teleop])
