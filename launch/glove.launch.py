"""STAG glove: readout driver and perception.

    ros2 launch prisma_bringup glove.launch.py backend:=sim
    ros2 launch prisma_bringup glove.launch.py backend:=serial port:=/dev/ttyACM0
    ros2 launch prisma_bringup glove.launch.py backend:=replay dataset:=/data/stag/metadata.mat
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    namespace = LaunchConfiguration("namespace")
    return LaunchDescription([
        DeclareLaunchArgument("backend", default_value="sim", choices=["sim", "serial", "replay"],
                              description="Glove readout source"),
        DeclareLaunchArgument("port", default_value="/dev/ttyACM0",
                              description="Serial port of the readout board (backend:=serial)"),
        DeclareLaunchArgument("dataset", default_value="",
                              description="metadata.mat or .h5 file to replay (backend:=replay)"),
        DeclareLaunchArgument("namespace", default_value=""),
        Node(
            package="stag_glove", executable="glove_driver", name="glove_driver",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "glove_driver.yaml"]),
                        {"backend": LaunchConfiguration("backend"),
                         "port": LaunchConfiguration("port"),
                         "dataset": LaunchConfiguration("dataset")}],
        ),
        Node(
            package="stag_glove", executable="glove_perception", name="glove_perception",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "glove_perception.yaml"])],
        ),
    ])
