"""Calibration recording for retraining the force estimator.

Runs the tactile driver on the hardware while a reference F/T sensor driver (any node publishing
geometry_msgs/WrenchStamped on `reference_topic`, started separately) measures the same contacts,
and records both into one MCAP bag:

    ros2 launch prisma_bringup calibration.launch.py finger:=thumb reference_topic:=/ft_sensor/wrench bag:=cal_thumb
    prisma-train-force --model cnn2 --data cal_thumb --finger thumb --reference-topic /ft_sensor/wrench \\
        --out config/models/cnn2_thumb

The trainer pairs each taxel sample with the reference wrench nearest in header stamp (5 ms).
"""
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

from prisma_bringup.launch_nodes import checked_launch_description, required
from prisma_common.hand import FINGERS


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    finger = LaunchConfiguration("finger")

    declared_arguments = [
        DeclareLaunchArgument("finger", default_value="thumb",
                              choices=list(FINGERS),
                              description="Fingertip pressed against the reference sensor"),
        DeclareLaunchArgument("tactile_backend", default_value="serial", choices=["serial", "i2c"],
                              description="Fingertip hub link"),
        DeclareLaunchArgument("tactile_port", default_value="/dev/ttyUSB1",
                              description="Serial port of the fingertip hub (tactile_backend:=serial)"),
        DeclareLaunchArgument("reference_topic", default_value="/ft_sensor/wrench",
                              description="geometry_msgs/WrenchStamped from the reference F/T sensor"),
        DeclareLaunchArgument("bag", default_value="calibration", description="Output bag directory"),
    ]

    # required, both: a recording without either is no calibration
    tactile_driver = required(Node(
        package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
        output="screen",
        parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                    {"backend": LaunchConfiguration("tactile_backend"),
                     "port": ParameterValue(LaunchConfiguration("tactile_port"), value_type=str)}],
    ))
    record = required(ExecuteProcess(
        cmd=["ros2", "bag", "record", "-s", "mcap", "-o", LaunchConfiguration("bag"),
             ["/prisma/", finger, "/taxels"], LaunchConfiguration("reference_topic"), "/diagnostics"],
        name="bag_record", output="screen",  # named in the launch's last line should it fail
    ))
    return checked_launch_description(declared_arguments, [tactile_driver, record])
