"""PRISMA Hand II: fingertip sensors, force estimator, motors and the manipulation controller.

    ros2 launch prisma_bringup hand.launch.py sim:=true
    ros2 launch prisma_bringup hand.launch.py sim:=false tactile_backend:=serial motor_backend:=dynamixel
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    sim = LaunchConfiguration("sim")
    tactile_backend = LaunchConfiguration("tactile_backend")
    motor_backend = LaunchConfiguration("motor_backend")
    model_bundle = LaunchConfiguration("model_bundle")
    namespace = LaunchConfiguration("namespace")
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])

    # In simulation both drivers use their sim backends whatever the hardware arguments say.
    effective_tactile = PythonExpression(
        ["'sim' if '", sim, "'.lower() == 'true' else '", tactile_backend, "'"])
    effective_motor = PythonExpression(
        ["'sim' if '", sim, "'.lower() == 'true' else '", motor_backend, "'"])

    return LaunchDescription([
        DeclareLaunchArgument("sim", default_value="true", choices=["true", "false"],
                              description="Simulated hand and sensors instead of hardware"),
        DeclareLaunchArgument("tactile_backend", default_value="serial",
                              choices=["serial", "i2c", "sim"],
                              description="Fingertip hub link when sim:=false"),
        DeclareLaunchArgument("motor_backend", default_value="dynamixel",
                              choices=["dynamixel", "sim"],
                              description="Motor bus when sim:=false"),
        DeclareLaunchArgument("model_bundle",
                              default_value=PathJoinSubstitution([config, "models", "cnn2"]),
                              description="Force estimator model bundle directory"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="Namespace for every node of the hand"),
        Node(
            package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                        {"backend": effective_tactile,
                         "contact_source": "hand_world"}],
        ),
        Node(
            package="prisma_force_estimator", executable="force_estimator", name="force_estimator",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "force_estimator.yaml"]),
                        {"model_bundle": model_bundle}],
        ),
        Node(
            package="prisma_manipulation", executable="motor_driver", name="motor_driver",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                        {"backend": effective_motor}],
        ),
        Node(
            package="prisma_manipulation", executable="manipulation", name="manipulation",
            namespace=namespace, output="screen",
            parameters=[PathJoinSubstitution([config, "manipulation.yaml"])],
        ),
    ])
