"""PRISMA Hand II: fingertip sensors, force estimator, motors and the manipulation controller.

    ros2 launch prisma_bringup hand.launch.py                      # sim:=true
    ros2 launch prisma_bringup hand.launch.py sim:=false tactile_port:=/dev/ttyUSB1 motor_port:=/dev/ttyUSB0
    ros2 launch prisma_bringup hand.launch.py sim:=false tactile_backend:=i2c
    ros2 launch prisma_bringup hand.launch.py model_bundle:=/path/to/bundle namespace:=left
    ros2 launch prisma_bringup hand.launch.py hardware:=emulated   # + tactile_backend:=i2c
    ros2 launch prisma_bringup hand.launch.py hardware:=robot      # = sim:=false
    ros2 launch prisma_bringup hand.launch.py parts:=robot         # on the robot; parts:=workstation beside it
    ros2 launch prisma_bringup hand.launch.py sim:=false hand_config:=~/hands/pad7   # this hand's directory

sim:=true runs the drivers' sim backends: motor_driver simulates the motors and publishes
/joint_states, tactile_driver computes the fingertip contacts from them (contact_source hand_world)
with the object sim_object presented to the hand (pinch_ball; none = an empty hand).
sim:=false runs them on the hardware selected by tactile_backend / motor_backend. Every parameter
not given here comes from config/<node>.yaml.

hand_config:= is the directory of this physical hand (prisma_common/hand_config.py): the motor zeros
homing found, the fingertips' bias (~/bias) and per-finger model bundles, loaded at start by
motor_driver and force_estimator and written there by the services that find them; anything it does
not hold comes from config/. auto (the default): ~/.config/prisma_hand/<namespace or default>
($XDG_CONFIG_HOME) with sim:=false, none with sim:=true or hardware:=emulated; none: the shipped
config only.

hardware:= says which hand, in the words teleop.launch.py uses too: sim (the drivers' sim backends),
robot (the hardware) or emulated; auto (the default) follows sim:= (true: sim, false: robot).

hardware:=emulated (whatever sim is) starts prisma-hand-emulator: the Dynamixel servos on a
pseudo-terminal and the pads on the link tactile_backend names (serial: the fingertip hub on a
second pseudo-terminal; i2c: the pads' I2C bus on a socket), in emulator_dir, driven by one
hand/world model. The drivers run their hardware paths on them: motor_driver backend dynamixel
through dynamixel-sdk, tactile_driver backend serial (or i2c) through pyserial (or smbus2).
`prisma-hand-fault --dir <emulator_dir> ...` injects faults while it runs (those of the other
tactile link are refused). Its servos come up as real ones do, their turn count lost: home:=true
homes them at start (the motor driver refuses every goal `not_homed` until then). sim_object names
its world as it does the sim one's (pinch_ball, power_ball, lateral_card, none), and a prisma-sim
scenario's start besides (the emulator poses its servos; the simulated motors start open).

Beside them: robot_state_publisher (the hand's description from prisma_description, /tf and
/tf_static for every frame the hand's messages name; under a namespace its frames get the prefix
`<namespace>/`, and the drivers stamp their messages with it) drawing from prisma/model_joint_states,
which tendon_stretch makes of /joint_states (the motors) and the pads' estimated forces: the fingers
where the elastic tendons let them under load, at the object rather than through it; and
tactile_markers (the pads drawn in RViz, idle until a display subscribes). rviz:=true opens RViz
with the hand, its taxels and forces, and the simulated object.

parts:= splits the hand between two computers on one ROS domain (docs/architecture.md, "Across
machines"): parts:=robot starts what talks to the hardware (tactile_driver, motor_driver,
robot_state_publisher and tendon_stretch; the emulator with hardware:=emulated), parts:=workstation
the rest (force_estimator, manipulation, tactile_markers, RViz); parts:=all (the default) both. The nodes do
not know where the others run: same topics, same actions.

The control path (the four nodes, and the emulator with hardware:=emulated) runs with real-time
scheduling, SCHED_FIFO rt_priority:=20, ahead of every ordinary process: a plotting tool, a recorder,
a browser on the same cores cannot hold up the taxel, wrench and motor streams until a goal stops
sensor_stale (prisma_common/scheduling.py). Where real-time scheduling is not permitted (not root, no
`rtprio` limit in /etc/security/limits.conf; docs/real_hand.md, "Real-time limits") the nodes run at nice:=-5 if
that is permitted, else at the default priority, and say so in their first log line. rt_priority:=0
asks for niceness only.

The hand starts whole or not at all (prisma_bringup/launch_nodes.py): an argument this file does not
declare is refused, with the ones it does; a hand whose nodes already run in the namespace is refused
before anything starts; a node of the control path (or the emulator) that exits on its own stops
every node of the launch, and the launch's last line names it and its reason (exit 1).
"""
import tempfile
from pathlib import Path

from launch import LaunchContext, Substitution
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction, RegisterEventHandler
from launch.conditions import IfCondition
from launch.event_handlers import OnShutdown
from launch.substitutions import Command, LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackagePrefix, FindPackageShare

from prisma_bringup.launch_nodes import (
    EMULATOR_READY,
    checked_launch_description,
    control_path_env,
    control_path_node,
    once_said,
    refuse_a_second_hand,
    required,
)
from prisma_common.control_socket import CONTROL_SOCKET_NAME
from prisma_common.hand_config import launch_hand_config
from prisma_common.scheduling import CONTROL_PATH_NICE, CONTROL_PATH_RT_PRIORITY


def rviz_for_this_hand(context, config_dir: Substitution, namespace: Substitution, frame_prefix: Substitution) -> list:
    """rviz2 with config/hand.rviz; under a namespace the fixed frame and the model's TF prefix
    follow the hand's frame prefix (the config's topics are relative, so they follow the namespace)."""
    prefix = frame_prefix.perform(context)
    config = Path(config_dir.perform(context)) / "hand.rviz"
    actions: list = []
    if prefix:
        text = config.read_text().replace("Fixed Frame: prisma_hand_base", f"Fixed Frame: {prefix}prisma_hand_base")
        text = text.replace('TF Prefix: ""', f"TF Prefix: {prefix.rstrip('/')}")
        with tempfile.NamedTemporaryFile("w", prefix="prisma_hand_", suffix=".rviz", delete=False) as out:
            out.write(text)
        config = Path(out.name)
        actions.append(RegisterEventHandler(OnShutdown(on_shutdown=lambda event, context: config.unlink())))
    return actions + [Node(package="rviz2", executable="rviz2", name="rviz2", namespace=namespace.perform(context),
                           output="screen", arguments=["-d", str(config)])]


class HandConfigDir(Substitution):
    """The nodes' hand_config parameter from hand_config:= (prisma_common.hand_config.launch_hand_config)."""

    def __init__(self, given: Substitution, namespace: Substitution, simulated: Substitution) -> None:
        super().__init__()
        self.given, self.namespace, self.simulated = given, namespace, simulated

    def perform(self, context: LaunchContext) -> str:
        return launch_hand_config(self.given.perform(context), self.namespace.perform(context),
                                  self.simulated.perform(context) == "True")


def declared_arguments(config) -> list[DeclareLaunchArgument]:
    return [
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
        DeclareLaunchArgument("hardware", default_value="auto", choices=["auto", "sim", "robot", "emulated"],
                              description="Which hand (overrides sim): sim (the drivers' sim backends), robot "
                                          "(the hardware), emulated (the drivers' hardware paths on "
                                          "prisma-hand-emulator's devices); auto: as sim:= says"),
        DeclareLaunchArgument("emulator_dir", default_value="/tmp/prisma_hand_emulator",
                              description="Where the emulator's devices appear, an absolute path (hardware:=emulated)"),
        DeclareLaunchArgument("sim_object", default_value="pinch_ball",
                              description="The simulated world (sim:=true or hardware:=emulated): the object "
                                          "presented to the open hand, pinch_ball, power_ball, lateral_card or "
                                          "none (an empty hand); with hardware:=emulated also the start of a "
                                          "prisma-sim scenario (pinch_grasp, lateral_grasp, horizontal, "
                                          "vertical, disturbance, combined), the hand posed and the object held"),
        DeclareLaunchArgument("frame_prefix", default_value="auto",
                              description="Put in front of every frame of the hand: its TF frames and the "
                                          "frame_id of its messages; auto: '<namespace>/' under a namespace, "
                                          "none at the root"),
        DeclareLaunchArgument("hand_config", default_value="auto",
                              description="This hand's directory (motor zeros, fingertip bias, bundles): auto = "
                                          "~/.config/prisma_hand/<namespace or default> with sim:=false, none "
                                          "in sim; none; or a directory"),
        DeclareLaunchArgument("home", default_value="false", choices=["true", "false"],
                              description="Home the motors at start (each turns slowly to its open end stop): "
                                          "needed after the servos powered up, before any goal moves them"),
        DeclareLaunchArgument("rviz", default_value="false", choices=["true", "false"],
                              description="Open RViz with the hand model, its taxels, contacts and forces"),
        DeclareLaunchArgument("parts", default_value="all", choices=["all", "robot", "workstation"],
                              description="Which computer's share to start: robot (the drivers and "
                                          "robot_state_publisher), workstation (force_estimator, manipulation, "
                                          "the display tools) or all"),
        DeclareLaunchArgument("rt_priority", default_value=str(CONTROL_PATH_RT_PRIORITY),
                              description="SCHED_FIFO priority of the control path (1-99; 0: no real-time scheduling)"),
        DeclareLaunchArgument("nice", default_value=str(CONTROL_PATH_NICE),
                              description="Niceness of the control path where real-time scheduling is not asked for "
                                          "or not permitted (-20..19; lower runs first)"),
    ]


def simulated_hardware(config, namespace, frame_prefix, hand_dir, condition: IfCondition) -> list:
    """sim:=true: the drivers' sim backends, the pads' contacts from the hand's world."""
    return [
        control_path_node(
            package="prisma_tactile_driver", executable="tactile_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                        {"backend": "sim", "contact_source": "hand_world",
                         "frame_id_format": ParameterValue([frame_prefix, "prisma_{finger}_pad"], value_type=str),
                         "sim_object": ParameterValue(LaunchConfiguration("sim_object"), value_type=str),
                         "object_frame_id": ParameterValue([frame_prefix, "prisma_hand_base"], value_type=str)}]),
        control_path_node(
            package="prisma_motor_driver", executable="motor_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                        {"backend": "sim", "hand_config": hand_dir}]),
    ]


def robot_hardware(config, namespace, frame_prefix, hand_dir, condition: IfCondition) -> list:
    """sim:=false: the drivers on the hand's links, tactile_backend / motor_backend on their ports."""
    return [
        control_path_node(
            package="prisma_tactile_driver", executable="tactile_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                        {"backend": LaunchConfiguration("tactile_backend"),
                         "port": ParameterValue(LaunchConfiguration("tactile_port"), value_type=str),
                         "frame_id_format": ParameterValue([frame_prefix, "prisma_{finger}_pad"], value_type=str)}]),
        control_path_node(
            package="prisma_motor_driver", executable="motor_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                        {"backend": LaunchConfiguration("motor_backend"), "hand_config": hand_dir,
                         "home_at_start": ParameterValue(LaunchConfiguration("home"), value_type=bool),
                         "port": ParameterValue(LaunchConfiguration("motor_port"), value_type=str)}]),
    ]


def emulated_hardware(config, namespace, frame_prefix, hand_dir, condition: IfCondition) -> list:
    """hardware:=emulated: prisma-hand-emulator, then, once it says its devices exist, the drivers'
    hardware paths on them (started beside it, they found no device yet: `cannot open serial port`,
    the bus opened late)."""
    emulator_dir = LaunchConfiguration("emulator_dir")
    emulator = required(ExecuteProcess(
        cmd=[PathJoinSubstitution([FindPackagePrefix("prisma_hand_emulator"), "lib", "prisma_hand_emulator",
                                   "prisma-hand-emulator"]),
             "--dir", emulator_dir, "--world", LaunchConfiguration("sim_object"),
             "--tactile-link", LaunchConfiguration("tactile_backend")],
        name="hand_emulator", output="screen", additional_env=control_path_env(), condition=condition,
    ))
    return [emulator, once_said(emulator, EMULATOR_READY, condition=condition, actions=[
        control_path_node(
            package="prisma_tactile_driver", executable="tactile_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "tactile_driver.yaml"]),
                        {"backend": LaunchConfiguration("tactile_backend"),
                         "port": ParameterValue(PathJoinSubstitution([emulator_dir, "hub"]), value_type=str),
                         "i2c_socket": ParameterValue(PathJoinSubstitution([emulator_dir, "i2c.sock"]),
                                                      value_type=str),
                         # ~/replace_object puts the emulator's object back, as the sim hand's does its own
                         "emulator_control": ParameterValue(PathJoinSubstitution([emulator_dir, CONTROL_SOCKET_NAME]),
                                                            value_type=str),
                         "frame_id_format": ParameterValue([frame_prefix, "prisma_{finger}_pad"], value_type=str)}]),
        control_path_node(
            package="prisma_motor_driver", executable="motor_driver", namespace=namespace, condition=condition,
            parameters=[PathJoinSubstitution([config, "motor_driver.yaml"]),
                        {"backend": "dynamixel", "hand_config": hand_dir,
                         "home_at_start": ParameterValue(LaunchConfiguration("home"), value_type=bool),
                         "port": ParameterValue(PathJoinSubstitution([emulator_dir, "servos"]), value_type=str)}]),
    ])]


def beside_the_hand(config, namespace, frame_prefix, robot_side: list, workstation_side: list) -> list:
    """robot_state_publisher and tendon_stretch (robot side: with the workstation away the fingers
    follow the motors), tactile_markers and RViz with rviz:=true (workstation side)."""
    description = ParameterValue(
        Command(["xacro ", PathJoinSubstitution([FindPackageShare("prisma_description"), "urdf",
                                                  "prisma_hand.urdf.xacro"])]), value_type=str)
    robot_state_publisher = Node(
        package="robot_state_publisher", executable="robot_state_publisher", name="robot_state_publisher",
        namespace=namespace, output="screen",
        parameters=[{"robot_description": description, "frame_prefix": frame_prefix}],
        # the full joint state, fingers under load (tendon_stretch): one publisher for every joint it draws
        remappings=[("joint_states", "prisma/model_joint_states")],
        condition=IfCondition(PythonExpression(robot_side)),
    )
    tendon_stretch = Node(
        package="prisma_visualization", executable="tendon_stretch", name="tendon_stretch",
        namespace=namespace, output="screen",
        parameters=[PathJoinSubstitution([config, "tendon_stretch.yaml"])],
        condition=IfCondition(PythonExpression(robot_side)),
    )
    tactile_markers = Node(
        package="prisma_visualization", executable="tactile_markers", name="tactile_markers",
        namespace=namespace, output="screen",
        parameters=[PathJoinSubstitution([config, "tactile_markers.yaml"])],
        condition=IfCondition(PythonExpression(workstation_side)),
    )
    rviz = OpaqueFunction(function=rviz_for_this_hand, args=[config, namespace, frame_prefix],
                          condition=IfCondition(PythonExpression(["'", LaunchConfiguration("rviz"), "' == 'true' and ",
                                                                  *workstation_side])))
    return [robot_state_publisher, tendon_stretch, tactile_markers, rviz]


def generate_launch_description():
    config = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "config"])
    sim = LaunchConfiguration("sim")
    namespace = LaunchConfiguration("namespace")
    hardware = LaunchConfiguration("hardware")
    parts = LaunchConfiguration("parts")
    robot_side = ["'", parts, "' != 'workstation'"]
    workstation_side = ["'", parts, "' != 'robot'"]
    is_sim = ["('", hardware, "' == 'sim' or ('", hardware, "' == 'auto' and '", sim, "' == 'true'))"]
    is_robot = ["('", hardware, "' == 'robot' or ('", hardware, "' == 'auto' and '", sim, "' == 'false'))"]
    emulated = IfCondition(PythonExpression(["'", hardware, "' == 'emulated' and ", *robot_side]))
    simulated = IfCondition(PythonExpression([*is_sim, " and ", *robot_side]))
    on_robot = IfCondition(PythonExpression([*is_robot, " and ", *robot_side]))
    # "auto" is resolved here, not in the argument's default: a default computed from another argument
    # would leak from the first of two hands included in one launch file into the second
    given_prefix = LaunchConfiguration("frame_prefix")
    frame_prefix = PythonExpression(["(('", namespace, "'.strip('/') + '/') if '", namespace, "'.strip('/') else '') "
                                     "if '", given_prefix, "' == 'auto' else '", given_prefix, "'"])
    on_workstation = IfCondition(PythonExpression(workstation_side))
    hand_dir = ParameterValue(HandConfigDir(LaunchConfiguration("hand_config"), namespace, PythonExpression(
        ["'", hardware, "' == 'emulated' or ", *is_sim])), value_type=str)

    force_estimator = control_path_node(
        package="prisma_force_estimator", executable="force_estimator", namespace=namespace, condition=on_workstation,
        parameters=[PathJoinSubstitution([config, "force_estimator.yaml"]),
                    {"model_bundle": ParameterValue(LaunchConfiguration("model_bundle"), value_type=str),
                     "hand_config": hand_dir}])
    manipulation = control_path_node(
        package="prisma_manipulation", executable="manipulation", namespace=namespace, condition=on_workstation,
        parameters=[PathJoinSubstitution([config, "manipulation.yaml"]),
                    {"frame_id_format": ParameterValue([frame_prefix, "prisma_{finger}_pad"], value_type=str)}])
    return checked_launch_description(
        declared_arguments(config),
        [refuse_a_second_hand(namespace, hand_nodes)]
        + simulated_hardware(config, namespace, frame_prefix, hand_dir, simulated)
        + robot_hardware(config, namespace, frame_prefix, hand_dir, on_robot)
        + emulated_hardware(config, namespace, frame_prefix, hand_dir, emulated)
        + [force_estimator, manipulation]
        + beside_the_hand(config, namespace, frame_prefix, robot_side, workstation_side))


# the nodes of each computer's share (parts:=), those a second hand in the namespace would duplicate
ROBOT_SIDE_NODES = ["tactile_driver", "motor_driver", "robot_state_publisher", "tendon_stretch"]
WORKSTATION_SIDE_NODES = ["force_estimator", "manipulation", "tactile_markers"]


def hand_nodes(context: LaunchContext) -> list[str]:
    """The nodes this launch starts, by parts:= (refuse_a_second_hand looks for them)."""
    parts = LaunchConfiguration("parts").perform(context)
    return (ROBOT_SIDE_NODES if parts != "workstation" else []) + (WORKSTATION_SIDE_NODES if parts != "robot" else [])
