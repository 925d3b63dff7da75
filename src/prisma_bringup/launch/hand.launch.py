"""PRISMA Hand II: fingertip sensors, force estimator, motors and the manipulation controller.

    ros2 launch prisma_bringup hand.launch.py                      # sim:=true
    ros2 launch prisma_bringup hand.launch.py sim:=false tactile_port:=/dev/ttyUSB1 motor_port:=/dev/ttyUSB0
    ros2 launch prisma_bringup hand.launch.py sim:=false tactile_backend:=i2c
    ros2 launch prisma_bringup hand.launch.py model_bundle:=/path/to/bundle namespace:=left
    ros2 launch prisma_bringup hand.launch.py hardware:=emulated   # + tactile_backend:=i2c

sim:=true runs the drivers' sim backends: motor_driver simulates the motors and publishes
/joint_states, tactile_driver computes the fingertip contacts from them (contact_source hand_world)
with the object sim_object presented to the hand (pinch_ball; none = an empty hand).
sim:=false runs them on the hardware selected by tactile_backend / motor_backend. Every parameter
not given here comes from config/<node>.yaml.

hardware:=emulated (whatever sim is) starts prisma-hand-emulator: the Dynamixel servos and the
fingertip hub on pseudo-terminals and the pads' I2C bus on a socket, in emulator_dir, all driven by
one hand/world model. The drivers run their hardware paths on them: motor_driver backend dynamixel
through dynamixel-sdk, tactile_driver backend serial (or i2c) through pyserial (or smbus2).
`prisma-hand-fault --dir <emulator_dir> ...` injects faults while it runs.

The four nodes run at nice -5 (`nice:=0` for the default priority): the hand's control path comes
before a plotting tool or a recorder on the same cores. Without the right to raise priority (not
root, no `nice` limit in /etc/security/limits.conf; README, "On the robot") `nice` says "cannot set
niceness" and the nodes run at the default priority.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackagePrefix, FindPackageShare


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    sim = LaunchConfiguration("sim")
    namespace = LaunchConfiguration("namespace")
    hardware = LaunchConfiguration("hardware")
    emulator_dir = LaunchConfiguration("emulator_dir")
    emulated = IfCondition(PythonExpression(["'", hardware, "' == 'emulated'"]))
    simulated = IfCondition(PythonExpression(["'", hardware, "' != 'emulated' and '", sim, "' == 'true'"]))
    on_robot = IfCondition(PythonExpression(["'", hardware, "' != 'emulated' and '", sim, "' == 'false'"]))

    declared_arguments = [
        DeclareLaunchArgument("sim", default_value="true", choices=["true", "false"],
                              description="Simulated motors and fingertip sensors instead of the hardware"),
        DeclareLaunchArgument("tactile_backend", default_value="serial", choices=["serial", "i2c", "sim"],
                              description="Fingertip hub link when sim:=false (serial: Arduino hub, i2c: host bus)"),
        DeclareLaunchArgument("tactile_port", default_value="/dev/ttyUSB1",
                              description="Serial port of the fingertip hub (tactile_backend:=serial)"),
        DeclareLaunchArgument("motor_backend", default_value="dynamixel", choices=["dynamixel", "sim"],
                              description="Motor bus when sim:=false"),
        DeclareLaunchArgument("motor_port", default_value="/dev/ttyUSB0",
                              description="Serial port of the Dynamixel adapter (motor_backend:=dynamixel)"),
        DeclareLaunchArgument("model_bundle",
                              default_value=PathJoinSubstitution([config, "models", "cnn2"]),
                              description="Force estimator model bundle directory (model.pt + metadata.json)"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="Namespace for every node of the hand (topics follow it)"),
        DeclareLaunchArgument("hardware", default_value="robot", choices=["robot", "emulated"],
                              description="emulated: the drivers' hardware paths on prisma-hand-emulator's "
                                          "devices (overrides sim)"),
        DeclareLaunchArgument("emulator_dir", default_value="/tmp/prisma_hand_emulator",
                              description="Where the emulator's devices appear, an absolute path (hardware:=emulated)"),
        DeclareLaunchArgument("emulator_world", default_value="hand",
                              description="The emulator's object and pose: hand (as sim:=true) or a "
                                          "prisma-sim scenario (grasp, lateral, horizontal, ...)"),
        DeclareLaunchArgument("sim_object", default_value="pinch_ball",
                              description="sim:=true: the object in the hand's world, pinch_ball, power_ball, "
                                          "lateral_card or none (an empty hand)"),
        DeclareLaunchArgument("nice", default_value="-5",
                              description="Scheduling niceness of the hand's nodes (-20..19; lower runs first)"),
    ]
    # every hand node starts under `nice -n <nice>`: the priority covers all its threads (DDS too)
    prefix = ["nice -n ", LaunchConfiguration("nice")]

    tactile_sim = Node(
        package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="tactile_driver",
        parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                    {"backend": "sim", "contact_source": "hand_world",
                     "sim_object": ParameterValue(LaunchConfiguration("sim_object"), value_type=str)}],
        condition=simulated,
    )
    tactile_hardware = Node(
        package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="tactile_driver",
        parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                    {"backend": LaunchConfiguration("tactile_backend"),
                     "port": ParameterValue(LaunchConfiguration("tactile_port"), value_type=str)}],
        condition=on_robot,
    )
    motors_sim = Node(
        package="prisma_motor_driver", executable="motor_driver", name="motor_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="motor_driver",
        parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]), {"backend": "sim"}],
        condition=simulated,
    )
    motors_hardware = Node(
        package="prisma_motor_driver", executable="motor_driver", name="motor_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="motor_driver",
        parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                    {"backend": LaunchConfiguration("motor_backend"),
                     "port": ParameterValue(LaunchConfiguration("motor_port"), value_type=str)}],
        condition=on_robot,
    )
    emulator = ExecuteProcess(
        cmd=[PathJoinSubstitution([FindPackagePrefix("prisma_bringup"), "lib", "prisma_bringup",
                                   "prisma-hand-emulator"]),
             "--dir", emulator_dir, "--world", LaunchConfiguration("emulator_world")],
        name="hand_emulator", output="screen", prefix=prefix, condition=emulated,
    )
    tactile_emulated = Node(
        package="prisma_tactile_driver", executable="tactile_driver", name="tactile_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="tactile_driver",
        parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                    {"backend": LaunchConfiguration("tactile_backend"),
                     "port": ParameterValue(PathJoinSubstitution([emulator_dir, "hub"]), value_type=str),
                     "i2c_socket": ParameterValue(PathJoinSubstitution([emulator_dir, "i2c.sock"]), value_type=str)}],
        condition=emulated,
    )
    motors_emulated = Node(
        package="prisma_motor_driver", executable="motor_driver", name="motor_driver",
        namespace=namespace, output="screen", prefix=prefix, exec_name="motor_driver",
        parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                    {"backend": "dynamixel",
                     "port": ParameterValue(PathJoinSubstitution([emulator_dir, "servos"]), value_type=str)}],
        condition=emulated,
    )
    force_estimator = Node(
        package="prisma_force_estimator", executable="force_estimator", name="force_estimator",
        namespace=namespace, output="screen", prefix=prefix, exec_name="force_estimator",
        parameters=[PathJoinSubstitution([config, "force_estimator.yaml"]),
                    {"model_bundle": ParameterValue(LaunchConfiguration("model_bundle"), value_type=str)}],
    )
    manipulation = Node(
        package="prisma_manipulation", executable="manipulation", name="manipulation",
        namespace=namespace, output="screen", prefix=prefix, exec_name="manipulation",
        parameters=[PathJoinSubstitution([config, "manipulation.yaml"])],
    )

    nodes = [tactile_sim, tactile_hardware, motors_sim, motors_hardware,
             emulator, tactile_emulated, motors_emulated, force_estimator, manipulation]
    return LaunchDescription(declared_arguments + nodes)
