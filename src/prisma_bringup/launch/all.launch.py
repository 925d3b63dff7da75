"""Hand and glove together.

    ros2 launch prisma_bringup all.launch.py                       # both simulated
    ros2 launch prisma_bringup all.launch.py sim:=false glove_backend:=serial glove_port:=/dev/ttyACM0
    ros2 launch prisma_bringup all.launch.py glove:=false
    ros2 launch prisma_bringup all.launch.py parts:=robot         # the drivers; parts:=workstation the rest
    ros2 launch prisma_bringup all.launch.py sim:=false hand_config:=~/hands/pad7   # the hand's directory
"""
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.substitutions import FindPackageShare

from prisma_bringup.launch_nodes import checked_launch_description


def generate_launch_description():
    launch_dir = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "launch"])

    declared_arguments = [
        DeclareLaunchArgument("sim", default_value="true", choices=["true", "false"],
                              description="Simulated hand instead of the hardware"),
        DeclareLaunchArgument("tactile_backend", default_value="serial", choices=["serial", "i2c", "sim"]),
        DeclareLaunchArgument("motor_backend", default_value="dynamixel", choices=["dynamixel", "sim"]),
        DeclareLaunchArgument("glove", default_value="true", choices=["true", "false"],
                              description="Also start the STAG glove nodes"),
        DeclareLaunchArgument("glove_backend", default_value="sim", choices=["sim", "serial", "replay"]),
        DeclareLaunchArgument("glove_port", default_value="/dev/ttyACM0"),
        DeclareLaunchArgument("parts", default_value="all", choices=["all", "robot", "workstation"],
                              description="Which computer's share of hand and glove to start (hand.launch.py)"),
        DeclareLaunchArgument("hand_config", default_value="auto",
                              description="The hand's directory (hand.launch.py): auto, none or a directory"),
    ]
    hand = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "hand.launch.py"])),
        launch_arguments={"sim": LaunchConfiguration("sim"),
                          "tactile_backend": LaunchConfiguration("tactile_backend"),
                          "motor_backend": LaunchConfiguration("motor_backend"),
                          "parts": LaunchConfiguration("parts"),
                          "hand_config": LaunchConfiguration("hand_config")}.items(),
    )
    glove = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "glove.launch.py"])),
        launch_arguments={"backend": LaunchConfiguration("glove_backend"),
                          "port": LaunchConfiguration("glove_port"),
                          "parts": LaunchConfiguration("parts")}.items(),
        condition=IfCondition(LaunchConfiguration("glove")),
    )
    return checked_launch_description(declared_arguments, [hand, glove])
