"""Calibration recording for retraining the force estimator.

Runs the tactile driver on the hardware next to a reference F/T sensor driver (any node publishing
geometry_msgs/WrenchStamped) and records both into one bag:

    ros2 launch prisma_bringup calibration.launch.py finger:=thumb reference_topic:=/ati/wrench
    prisma-train-force --model cnn2 --data <bag> --finger thumb --reference-topic /ati/wrench
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    finger = LaunchConfiguration("finger")
    return LaunchDescription([
        DeclareLaunchArgument("finger", default_value="thumb",
                              choices=["thumb", "index", "middle", "ring", "little"]),
        DeclareLaunchArgument("tactile_backend", default_value="serial", choices=["serial", "i2c"]),
        DeclareLaunchArgument("reference_topic", default_value="/ft_sensor/wrench",
                              description="geometry_msgs/WrenchStamped from the F/T sensor"),
        DeclareLaunchArgument("bag", default_value="calibration",
                              description="Output bag directory"),
        Node(
            package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
            output="screen",
            parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                        {"backend": LaunchConfiguration("tactile_backend")}],
        ),
        ExecuteProcess(
            cmd=["ros2", "bag", "record", "-s", "mcap", "-o", LaunchConfiguration("bag"),
                 ["/prisma/", finger, "/taxels"], LaunchConfiguration("reference_topic")],
            output="screen",
        ),
    ])
