"""Record demonstrations for prisma-dataset export (README, "Record demonstrations").

    ros2 launch prisma_bringup teleop.launch.py                      # the hand, the glove, the teleop node
    ros2 launch prisma_bringup record.launch.py out:=demo_01         # beside it: records until ctrl-C
    prisma-dataset export demo_01 --out pinch_dataset                # one episode per marked span

Runs `ros2 bag record -s mcap -o <out>` with exactly the topics an export reads
(prisma_dataset.bag_export.record_topics, also printed by `prisma-dataset topics`): /joint_states,
the per-hand taxels, wrench and contact, the teleop node's motor targets and episode markers, the
hand-pose glove's joint states and the STAG glove's frames, in the hand's namespace:=. The teleop
node marks the episodes (engaging starts one, letting go ends it; its ~/mark_episode service starts
one with a task or ends one with the operator's outcome); its markers are latched, so a recording
started inside an episode still gets its start. An out:= that exists is refused before anything
starts, as is an argument this file does not declare; the recorder exiting on its own stops the
launch with its reason.
"""
from pathlib import Path

from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration

from prisma_bringup.launch_nodes import checked_launch_description, required
from prisma_bringup.launch_refusals import LaunchRefused, recording_refusal
from prisma_dataset.recorded_topics import record_topics


def declared_arguments() -> list[DeclareLaunchArgument]:
    return [
        DeclareLaunchArgument("out", default_value="",
                              description="the bag directory to write (MCAP); it must not exist"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="the hand's namespace (as teleop.launch.py's namespace:=)"),
    ]


def recorder(context) -> list:
    out = LaunchConfiguration("out").perform(context)
    namespace = LaunchConfiguration("namespace").perform(context)
    refusal = recording_refusal(Path(context.locals.current_launch_file_path).name, out,
                                bool(out.strip()) and Path(out).expanduser().exists())
    if refusal is not None:
        raise LaunchRefused(refusal)
    return [required(ExecuteProcess(
        cmd=["ros2", "bag", "record", "-s", "mcap", "-o", str(Path(out).expanduser()), *record_topics(namespace)],
        name="bag_record", output="screen"))]  # named in the launch's last line should it fail


def generate_launch_description():
    return checked_launch_description(declared_arguments(), [OpaqueFunction(function=recorder)])
