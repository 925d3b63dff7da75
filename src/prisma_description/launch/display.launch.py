"""The PRISMA Hand II model alone: robot_state_publisher, a joint state source for the three motors
and RViz.

    ros2 launch prisma_description display.launch.py                 # sliders, if the GUI is installed
    ros2 launch prisma_description display.launch.py gui:=false rviz:=false

With gui:=true the motors are set with joint_state_publisher_gui's three sliders (fingers,
thumb_flexion, thumb_rotation; every finger joint follows through the tendon coupling). Where that
package is missing (`sudo apt install ros-jazzy-joint-state-publisher-gui`), joint_state_publisher
publishes the motors at their `zeros` (arguments fingers:=, thumb_flexion:=, thumb_rotation:=, rad).
"""
from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import Command, LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

MOTORS = ("fingers", "thumb_flexion", "thumb_rotation")


def joint_state_source(context) -> list:
    zeros = {name: float(LaunchConfiguration(name).perform(context)) for name in MOTORS}
    if LaunchConfiguration("gui").perform(context) == "true":
        try:
            get_package_share_directory("joint_state_publisher_gui")
            return [Node(package="joint_state_publisher_gui", executable="joint_state_publisher_gui",
                         name="joint_state_publisher_gui", parameters=[{"zeros": zeros}])]
        except PackageNotFoundError:
            note = LogInfo(msg="joint_state_publisher_gui is not installed: no sliders; the motors stay at "
                               "fingers:=, thumb_flexion:=, thumb_rotation:= (sudo apt install "
                               "ros-jazzy-joint-state-publisher-gui for sliders)")
            return [note, Node(package="joint_state_publisher", executable="joint_state_publisher",
                               name="joint_state_publisher", parameters=[{"zeros": zeros}])]
    return [Node(package="joint_state_publisher", executable="joint_state_publisher",
                 name="joint_state_publisher", parameters=[{"zeros": zeros}])]


def generate_launch_description():
    share = FindPackageShare("prisma_description")
    description = ParameterValue(Command(["xacro ", PathJoinSubstitution([share, "urdf", "prisma_hand.urdf.xacro"])]),
                                 value_type=str)
    return LaunchDescription([
        DeclareLaunchArgument("gui", default_value="true", choices=["true", "false"],
                              description="Sliders for the three motors (joint_state_publisher_gui)"),
        DeclareLaunchArgument("rviz", default_value="true", choices=["true", "false"], description="Open RViz"),
        *[DeclareLaunchArgument(name, default_value="0.0", description=f"{name} motor position, rad "
                                "(where there are no sliders)") for name in MOTORS],
        Node(package="robot_state_publisher", executable="robot_state_publisher", name="robot_state_publisher",
             parameters=[{"robot_description": description}]),
        OpaqueFunction(function=joint_state_source),
        Node(package="rviz2", executable="rviz2", name="rviz2", output="screen",
             arguments=["-d", PathJoinSubstitution([share, "rviz", "display.rviz"])],
             condition=IfCondition(LaunchConfiguration("rviz"))),
    ])
