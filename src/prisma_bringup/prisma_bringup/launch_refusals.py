"""Why a launch of the hand refuses to start, or stops whole: the decisions and their words, without
launch or ROS (launch_nodes.py carries them out in every launch file).

A hand starts whole or not at all:
- an argument the launch file does not declare is refused before anything starts, with the ones it
  declares, closest match first (`simulation:=false` would otherwise be ignored and a sim hand start);
- a hand whose nodes already run in the namespace is refused before anything starts (a second
  tactile_driver would publish on the first hand's topics);
- a node of the control path that exits on its own (an exit code above 0: its FATAL, a traceback)
  stops every node the launch started, and the launch's last line names the node and its reason.
"""
from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence

# launch configurations no launch file declares: ros2 launch's --launch-prefix options, and those
# launch and launch_ros keep there themselves (SetParameter, SetParametersFromFile, SetRemap,
# PushRosNamespace, emulate_tty)
LAUNCH_OWN_ARGUMENTS = frozenset({"launch-prefix", "launch-prefix-filter", "global_params", "ros_remaps",
                                  "ros_namespace", "emulate_tty"})

# a node that exits within this long of its start "exited at start-up" (a bad parameter, a missing
# device or bundle): the nodes read their configuration and open their devices in their first seconds
STARTUP_S = 30.0

# an rclpy/rcutils console line: [FATAL] [1733600000.123456789] [motor_driver]: <message>
_FATAL_LINE = re.compile(r"\[FATAL\]\s*(?:\[[^\]]*\]\s*)*?\[[^\]]*\]:\s?(?P<message>.*)$")


class LaunchRefused(Exception):
    """The launch refuses to start, or stops: the message says why and what to do."""


def closeness(name: str, candidate: str) -> float:
    """How close `candidate` is to the misspelt `name`: difflib's ratio, raised by 0.5 where one is the
    other's beginning (`simulation` is closest to `sim`, not to `sim_object`)."""
    ratio = difflib.SequenceMatcher(None, name, candidate).ratio()
    return ratio + (0.5 if name.startswith(candidate) or candidate.startswith(name) else 0.0)


def by_closeness(name: str, candidates: Iterable[str]) -> list[str]:
    """`candidates` sorted with the closest to `name` first (ties alphabetical)."""
    return sorted(candidates, key=lambda c: (-closeness(name, c), c))


# below this closeness no declared argument is offered as the one meant
CLOSE_ENOUGH = 0.6


def unknown_arguments(launch_file: str, given: Iterable[str], declared: Sequence[str]) -> str | None:
    """Why `launch_file` refuses the arguments `given` (the names of its `name:=value`), or None when
    it declares each of them. The message names each unknown one with the declared one it is
    closest to, then lists the declared ones, closest to the first unknown one first."""
    unknown = sorted(set(given) - set(declared) - LAUNCH_OWN_ARGUMENTS)
    if not unknown:
        return None
    parts = []
    for name in unknown:
        closest = by_closeness(name, declared)[:1]
        if closest and closeness(name, closest[0]) >= CLOSE_ENOUGH:
            parts.append(f"unknown argument '{name}'; did you mean '{closest[0]}'?")
        else:
            parts.append(f"unknown argument '{name}'.")
    arguments = ", ".join(by_closeness(unknown[0], declared))
    return f"{launch_file}: {' '.join(parts)} Starting nothing. Its arguments: {arguments}"


def nodes_already_running(graph: Iterable[str], namespace: str, names: Iterable[str]) -> list[str]:
    """The nodes among `names` (node names, in `namespace`) that `graph` (fully qualified node
    names) already holds, fully qualified, in the order of `names`."""
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    present = set(graph)
    return [f"{prefix}/{name}" for name in names if f"{prefix}/{name}" in present]


def second_hand_refusal(launch_file: str, namespace: str, running: Sequence[str]) -> str:
    """The refusal of a hand whose nodes `running` already run in `namespace`."""
    where = f"namespace '{namespace.strip('/')}'" if namespace.strip("/") else "the root namespace"
    return (f"{launch_file}: a hand already runs in {where} ({', '.join(running)}): starting nothing. "
            "Stop that launch first (ctrl-C), or start this hand under its own namespace:=")


def reason_in_output(lines: Sequence[str]) -> str:
    """What a process said last about why it stops: its last FATAL message, else its last line (the
    last line of a traceback), else a pointer to its log."""
    for line in reversed(lines):
        match = _FATAL_LINE.search(line)
        if match:
            return match.group("message").strip()
    for line in reversed(lines):
        if line.strip():
            return line.strip()
    return "it said nothing (see its lines above)"


def stopped_because(launch_file: str, node: str, returncode: int, ran_s: float, reason: str) -> str:
    """The launch's last line when a required node of it exited on its own after `ran_s` seconds."""
    when = "at start-up" if ran_s < STARTUP_S else f"after {ran_s:.0f} s"
    return f"{launch_file}: {node} exited {returncode} {when}: {reason}; every node of this launch is stopped"


def recording_refusal(launch_file: str, out: str, exists: bool) -> str | None:
    """Why a recording launch refuses to start for its out:= (None: it may): none given, or one that
    exists (ros2 bag record would stop on it after the graph came up, and a second take must not
    replace the first)."""
    if not out.strip():
        return f"{launch_file}: no out:= given: name the bag directory to write, e.g. out:=demo_01. Starting nothing"
    if exists:
        return (f"{launch_file}: out:={out} already exists: give a new bag directory (a recording never replaces "
                f"another). Starting nothing")
    return None
