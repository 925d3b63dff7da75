"""Hand and glove together: `ros2 launch prisma_bringup all.launch.py sim:=true`."""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.substitutions import FindPackageShare


def generate_launch_description():
    launch_dir = PathJoinSubstitution([FindPackageShare("prisma_bringup"), "launch"])
    sim = LaunchConfiguration("sim")
    return LaunchDescription([
        DeclareLaunchArgument("sim", default_value="true", choices=["true", "false"]),
        DeclareLaunchArgument("glove", default_value="true", choices=["true", "false"],
                              description="Also start the STAG glove nodes"),
        DeclareLaunchArgument("glove_backend", default_value="sim",
                              choices=["sim", "serial", "replay"]),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "hand.launch.py"])),
            launch_arguments={"sim": sim}.items(),
        ),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(PathJoinSubstitution([launch_dir, "glove.launch.py"])),
            launch_arguments={"backend": LaunchConfiguration("glove_backend")}.items(),
            condition=IfCondition(LaunchConfiguration("glove")),
        ),
    ])
