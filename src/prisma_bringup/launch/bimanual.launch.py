"""Two hands and the glove on one ROS domain: hand.launch.py under namespace:=left and
namespace:=right, glove.launch.py at the root (/stag/...).

    ros2 launch prisma_bringup bimanual.launch.py                      # both hands and the glove simulated
    ros2 launch prisma_bringup bimanual.launch.py parts:=robot         # on the robot; parts:=workstation beside it
    ros2 launch prisma_bringup bimanual.launch.py sim:=false left_motor_port:=/dev/ttyUSB0 \
        left_tactile_port:=/dev/ttyUSB1 right_motor_port:=/dev/ttyUSB2 right_tactile_port:=/dev/ttyUSB3
    ros2 launch prisma_bringup bimanual.launch.py sim:=false left_hand_config:=~/hands/pad7   # a hand's directory

Each hand is its own graph (/left/prisma/grasp, /right/prisma/grasp, /left/joint_states, ...; frames
prefixed left/ and right/): a goal on one hand never touches the other's motors. parts:= splits all
three between two computers as hand.launch.py and glove.launch.py do (docs/architecture.md,
"Across machines"). Each hand has its own directory (hand_config, hand.launch.py): by default
~/.config/prisma_hand/left and .../right on the hardware, none in sim.
"""
from launch.actions import DeclareLaunchArgument, GroupAction, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.substitutions import FindPackageShare

from prisma_bringup.launch_nodes import checked_launch_description


def generate_launch_description():
    launch_dir = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "launch"])
    parts = LaunchConfiguration("parts")

    declared_arguments = [
        DeclareLaunchArgument("sim", default_value="true", choices=["true", "false"],
                              description="Simulated hands instead of the hardware"),
        DeclareLaunchArgument("parts", default_value="all", choices=["all", "robot", "workstation"],
                              description="Which computer's share of both hands and the glove to start"),
        DeclareLaunchArgument("glove", default_value="true", choices=["true", "false"],
                              description="Also start the STAG glove nodes"),
        DeclareLaunchArgument("left_motor_port", default_value="/dev/ttyUSB0",
                              description="Serial port of the left hand's Dynamixel adapter (sim:=false)"),
        DeclareLaunchArgument("left_tactile_port", default_value="/dev/ttyUSB1",
                              description="Serial port of the left hand's fingertip hub (sim:=false)"),
        DeclareLaunchArgument("right_motor_port", default_value="/dev/ttyUSB2",
                              description="Serial port of the right hand's Dynamixel adapter (sim:=false)"),
        DeclareLaunchArgument("right_tactile_port", default_value="/dev/ttyUSB3",
                              description="Serial port of the right hand's fingertip hub (sim:=false)"),
        DeclareLaunchArgument("left_hand_config", default_value="auto",
                              description="The left hand's directory (hand.launch.py hand_config): auto = "
                                          "~/.config/prisma_hand/left with sim:=false, none in sim; none; or a "
                                          "directory"),
        DeclareLaunchArgument("right_hand_config", default_value="auto",
                              description="The right hand's directory (hand.launch.py hand_config): auto = "
                                          "~/.config/prisma_hand/right with sim:=false, none in sim; none; or a "
                                          "directory"),
    ]
    ports = {"left": (LaunchConfiguration("left_motor_port"), LaunchConfiguration("left_tactile_port")),
             "right": (LaunchConfiguration("right_motor_port"), LaunchConfiguration("right_tactile_port"))}
    hand_configs = {"left": LaunchConfiguration("left_hand_config"), "right": LaunchConfiguration("right_hand_config")}
    # each include in a scope of its own: an include's arguments otherwise stay set for the next
    # (the glove would run under the right hand's namespace)
    hands = [GroupAction([IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "hand.launch.py"])),
        launch_arguments={"sim": LaunchConfiguration("sim"), "namespace": side, "parts": parts,
                          "motor_port": ports[side][0], "tactile_port": ports[side][1],
                          "hand_config": hand_configs[side]}.items(),
    )], scoped=True) for side in ("left", "right")]
    glove = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "glove.launch.py"])),
        launch_arguments={"parts": parts}.items(),
        condition=IfCondition(LaunchConfiguration("glove")),
    )
    return checked_launch_description(declared_arguments, hands + [glove])
