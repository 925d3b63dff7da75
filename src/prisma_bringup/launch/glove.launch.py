"""STAG glove: readout driver and perception.

    ros2 launch prisma_bringup glove.launch.py                                   # backend:=sim
    ros2 launch prisma_bringup glove.launch.py backend:=serial port:=/dev/ttyACM0
    ros2 launch prisma_bringup glove.launch.py backend:=replay replay_file:=/data/stag/metadata.mat
    ros2 launch prisma_bringup glove.launch.py perception:=false
    ros2 launch prisma_bringup glove.launch.py parts:=robot        # the driver; parts:=workstation perception

parts:= splits the glove between two computers on one ROS domain as hand.launch.py does: robot runs
glove_driver (beside the readout board), workstation glove_perception (the networks), all both.

Every parameter not given here comes from config/glove_driver.yaml and config/glove_perception.yaml.
"""
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

from prisma_bringup.launch_nodes import checked_launch_description, required


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    namespace = LaunchConfiguration("namespace")

    declared_arguments = [
        DeclareLaunchArgument("backend", default_value="sim", choices=["sim", "serial", "replay"],
                              description="Glove readout: synthetic glove, readout board, or a dataset file"),
        DeclareLaunchArgument("port", default_value="/dev/ttyACM0",
                              description="Serial port of the readout board (backend:=serial)"),
        DeclareLaunchArgument("replay_file", default_value="",
                              description="metadata.mat (MATLAB v5/v7.3) or .h5 file to replay (backend:=replay)"),
        DeclareLaunchArgument("perception", default_value="true", choices=["true", "false"],
                              description="Also run glove_perception (object, hand pose, weight)"),
        DeclareLaunchArgument("namespace", default_value="", description="Namespace for the glove nodes"),
        DeclareLaunchArgument("parts", default_value="all", choices=["all", "robot", "workstation"],
                              description="Which computer's share to start: robot (glove_driver), workstation "
                                          "(glove_perception) or all"),
    ]
    parts = LaunchConfiguration("parts")

    # required: a glove that cannot read its board or load its networks stops the launch with its reason
    driver = required(Node(
        package="stag_glove", executable="glove_driver", name="glove_driver",
        namespace=namespace, output="screen",
        parameters=[PathJoinSubstitution([config, "glove_driver.yaml"]),
                    {"backend": LaunchConfiguration("backend"),
                     "port": ParameterValue(LaunchConfiguration("port"), value_type=str),
                     "replay_file": ParameterValue(LaunchConfiguration("replay_file"), value_type=str)}],
        condition=IfCondition(PythonExpression(["'", parts, "' != 'workstation'"])),
    ))
    perception = required(Node(
        package="stag_glove", executable="glove_perception", name="glove_perception",
        namespace=namespace, output="screen",
        parameters=[PathJoinSubstitution([config, "glove_perception.yaml"])],
        condition=IfCondition(PythonExpression(["'", LaunchConfiguration("perception"), "' == 'true' and '",
                                                parts, "' != 'robot'"])),
    ))
    return checked_launch_description(declared_arguments, [driver, perception])
