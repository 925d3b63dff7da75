"""A hand starts whole or not at all (issue 40), as an operator meets it in a terminal: `ros2 launch`
of hand.launch.py with a node that exits at start (`sim_object:=cube`: tactile_driver;
`model_bundle:=/nonexistent`: force_estimator), with an argument no launch file declares
(`simulation:=false`), and a second hand.launch.py beside a running one. Each exits non-zero
within 30 s, its last line names the cause, and no process it started is left; the running hand
keeps every node, and stops on ctrl-C with exit 0 as before. A value outside an argument's words is
refused with them (teleop.launch.py `hardware:=robot`); `hardware:=sim` (the words teleop.launch.py
uses) is the sim hand (the cube is refused by the sim world). The bad launches run side by side in
namespaces of their own, to keep the file short.

The running hand is the emulated one, whose normal start logged `cannot open serial port .../hub`
(the tactile driver started before the emulator made its devices) and `bus watchdog fired` for all
three servos (armed at the motor driver's construction, fed only from its first tick): neither may
appear before it is up. prisma-hand-emulator's first line is the one hand.launch.py starts the
drivers on (launch_nodes.EMULATOR_READY).
"""
from __future__ import annotations

import re
import time
from pathlib import Path

from prisma_testing.emulator_rig import run_cli
from prisma_testing.node_process import ros2_launch, stop_process
from prisma_testing.ros_harness import require_ros

require_ros()

from prisma_bringup.launch_nodes import EMULATOR_READY  # noqa: E402

ACCEPTANCE_S = 30.0  # each refused launch has exited this long after its start
HAND_NODES = ["/tactile_driver", "/motor_driver", "/force_estimator", "/manipulation", "/robot_state_publisher",
              "/tendon_stretch", "/tactile_markers"]
_STARTED = re.compile(r"process started with pid \[(\d+)\]")


def last_line(output: str) -> str:
    return next((line for line in reversed(output.splitlines()) if line.strip()), "")


def started_pids(output: str) -> list[int]:
    return [int(pid) for pid in _STARTED.findall(output)]


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


class Refused:
    """A launch expected to refuse or stop: its start instant, its exit, its output."""

    def __init__(self, *arguments: str, launch_file: str = "hand.launch.py") -> None:
        self.arguments = arguments
        self.started = time.monotonic()
        self.proc = ros2_launch("prisma_bringup", launch_file, *arguments)
        self.ended_after: float | None = None

    def wait(self) -> str:
        """Its output once it exited (at most ACCEPTANCE_S after its start, with a margin to report it)."""
        result = self.proc.wait(timeout_sec=max(1.0, self.started + ACCEPTANCE_S + 30.0 - time.monotonic()))
        self.ended_after = time.monotonic() - self.started
        self.returncode = result.returncode
        return result.output

    def check(self, cause: str) -> None:
        output = self.wait()
        context = f"{' '.join(self.arguments)}:\n{output[-6000:]}"
        assert self.returncode != 0, context
        assert self.ended_after is not None and self.ended_after <= ACCEPTANCE_S, \
            f"ended {self.ended_after:.1f} s after its start; {context}"
        assert cause in last_line(output), f"last line {last_line(output)!r}; {context}"
        left = [pid for pid in started_pids(output) if alive(pid)]
        assert left == [], f"left running: {left}; {context}"
        assert "Traceback" not in output, context
        print(f"{' '.join(self.arguments)}: exit {self.returncode} {self.ended_after:.1f} s after its start")


def graph_nodes(ros) -> list[str]:
    ros.spin_for(0.2)
    return [f"{ns.rstrip('/')}/{name}" for name, ns in ros.probe.get_node_names_and_namespaces()]


def test_a_hand_starts_whole_or_not_at_all(ros, tmp_path):
    # side by side, in namespaces of their own; the running hand after them (three hands starting at
    # once on a 2-core machine took 24 s of the 30 to refuse)
    cube = Refused("hardware:=sim", "sim_object:=cube", "namespace:=cube")
    bundle = Refused("model_bundle:=/nonexistent", "namespace:=bundle")
    misspelt = Refused("simulation:=false")
    outside = Refused("hardware:=robot", launch_file="teleop.launch.py")
    try:
        misspelt.check("hand.launch.py: unknown argument 'simulation'; did you mean 'sim'? Starting nothing. "
                       "Its arguments: sim, ")
        assert started_pids(misspelt.proc.output) == []
        outside.check("Argument \"hardware\" provided value \"robot\" is not valid. Valid options are: "
                      "['sim', 'emulated']")
        cube.check("hand.launch.py: /cube/tactile_driver exited 1 at start-up: invalid parameter 'sim_object' = "
                   "'cube': expected one of pinch_ball|power_ball|lateral_card|none; every node of this launch is "
                   "stopped")
        bundle.check("hand.launch.py: /bundle/force_estimator exited 1 at start-up: model bundle /nonexistent: "
                      "directory does not exist; every node of this launch is stopped")
    finally:
        for refused in (cube, bundle, misspelt, outside):
            refused.proc.kill()  # only one that failed its check still runs

    first = ros2_launch("prisma_bringup", "hand.launch.py", "hardware:=emulated",
                        f"emulator_dir:={tmp_path / 'emulator'}")
    try:
        assert ros.spin_until(lambda: set(HAND_NODES) <= set(graph_nodes(ros)), 90.0), \
            f"the first hand never came up: {graph_nodes(ros)}\n{first.output[-4000:]}"
        assert first.wait_for_output("] [motor_driver]: dynamixel motors", 30.0), first.output
        start = first.output
        assert "cannot open" not in start and "bus watchdog fired" not in start, start
        ready = start.index(EMULATOR_READY)
        assert ready < start.index("[tactile_driver-") and ready < start.index("[motor_driver-"), start
        first_pids = started_pids(first.output)
        assert len(first_pids) == len(HAND_NODES) + 1, first.output  # and the emulator

        second = Refused()
        second.check("): starting nothing. Stop that launch first (ctrl-C), or start this hand under its own "
                     "namespace:=")
        # it names the first hand's nodes it found: discovery may not have shown it every one of them yet
        # (a CI run's refusal named three), but each named is one of the first hand's
        found = re.search(r"hand\.launch\.py: a hand already runs in the root namespace \(([^)]*)\)",
                          last_line(second.proc.output))
        assert found is not None, last_line(second.proc.output)
        named = found.group(1).split(", ")
        assert named and set(named) <= set(HAND_NODES), named
        assert started_pids(second.proc.output) == []  # nothing of it started, not even for a moment

        # the first hand untouched: every process alive, every node once in the graph, none of the others'
        assert [pid for pid in first_pids if not alive(pid)] == [], first.output
        nodes = graph_nodes(ros)
        assert sorted(n for n in nodes if n in HAND_NODES) == sorted(HAND_NODES), nodes
        assert not [n for n in nodes if n.startswith(("/cube/", "/bundle/"))], nodes
        assert first.proc.poll() is None
    finally:
        stopped = stop_process(first)
    # a normal stop exits as before
    assert stopped.returncode == 0, stopped.output[-4000:]
    assert "Caught exception" not in stopped.output, stopped.output[-4000:]


def test_the_emulators_first_line_is_the_one_the_launch_starts_the_drivers_on(tmp_path):
    result = run_cli("prisma-hand-emulator", "--dir", str(tmp_path / "emu"), "--seconds", "1", "--linger", "0")
    assert result.returncode == 0, result.stderr
    first = result.stdout.splitlines()[0]
    assert first.startswith(EMULATOR_READY), result.stdout
    assert f"servos {tmp_path / 'emu' / 'servos'}" in first, result.stdout
