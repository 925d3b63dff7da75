"""A hand-pose glove worn by the test: the operator's joint angles (prisma_teleop's synthetic glove
core, the nominal hand) on /glove/joint_states at 60 Hz, stamped when published.

    glove = OperatorGlove()
    glove.move(FIST, 1.5)       # close in 1.5 s (raised cosine), then hold
    glove.stamp(None)           # from the next sample on: stamped 0 (glove.stamp(5.0): 5 s old; 0.0: now)
    last_ns = glove.stop()      # falls silent; glove.move(...) publishes again
    glove.close()

It runs in a process of its own on the control path's rung (SCHED_FIFO 20 where permitted), as
teleop.launch.py's synthetic glove does, told what to do over its stdin: from the test's process,
at the default priority beside a control path at real-time priority and the test's own 100 Hz
collections, a glove thread went silent for 150 ms at times and the goal ended input_stale while the
"operator" was closing.
"""
from __future__ import annotations

import subprocess
import sys

from prisma_teleop.synthetic_glove_core import Synergies
from prisma_testing.launch_case import MotorPositions

OPEN = Synergies(0.0, 0.0, 0.0)
FIST = Synergies(1.0, 1.0, 0.0)

GLOVE = r"""
import math, sys, threading, time
from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY, try_rt_priority

try_rt_priority(CONTROL_PATH_RT_PRIORITY)  # before rclpy starts its threads: they inherit it
import rclpy
from sensor_msgs.msg import JointState
from prisma_teleop.retargeting import nominal_calibration
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose

PERIOD_S = 1.0 / 60.0
rclpy.init()
node = rclpy.create_node("test_operator_glove")
publisher = node.create_publisher(JointState, sys.argv[1], 10)
calibration = nominal_calibration()
lock = threading.Lock()
state = {"on": False, "from": Synergies(0.0, 0.0, 0.0), "to": Synergies(0.0, 0.0, 0.0), "start": 0.0,
         "seconds": 1e-9, "published": 0, "silent_at": None, "age_ns": 0}


def at(now):
    u = min(1.0, (now - state["start"]) / state["seconds"])
    e = 0.5 - 0.5 * math.cos(math.pi * u)
    a, b = state["from"], state["to"]
    return Synergies(*(x + e * (y - x) for x, y in zip((a.fingers, a.thumb, a.opposition),
                                                       (b.fingers, b.thumb, b.opposition))))


def fall_silent():
    state["on"] = False
    print(f"stopped {state['published']}", flush=True)


def commands():
    for line in sys.stdin:
        words = line.split()
        with lock:
            if words[0] == "move":
                now = time.monotonic()
                target = Synergies(*map(float, words[1:4]))
                state.update({"from": at(now) if state["on"] else target, "to": target, "start": now,
                              "seconds": max(float(words[4]), 1e-9), "on": True,
                              "silent_at": now + float(words[5]) if len(words) > 5 else None})
            elif words[0] == "stop":
                fall_silent()
            elif words[0] == "stamp":  # "stamp zero" or "stamp <age in s>"
                state["age_ns"] = None if words[1] == "zero" else int(float(words[1]) * 1e9)
    state["quit"] = True


threading.Thread(target=commands, daemon=True).start()
print("ready", flush=True)
next_s = time.monotonic()
while not state.get("quit"):
    with lock:
        if state["on"] and state["silent_at"] is not None and time.monotonic() >= state["silent_at"]:
            fall_silent()
        if state["on"]:
            angles = hand_pose(at(time.monotonic()), calibration)
            now_ns = time.time_ns()
            msg = JointState(name=list(angles), position=list(angles.values()))
            if state["age_ns"] is not None:  # else stamped 0, as `ros2 topic pub` without header: auto
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now_ns - state["age_ns"], 1_000_000_000)
            publisher.publish(msg)
            state["published"] = now_ns
    next_s += PERIOD_S
    time.sleep(max(0.0, next_s - time.monotonic()))
node.destroy_node()
rclpy.try_shutdown()
"""


class OperatorGlove:
    def __init__(self, topic: str = "/glove/joint_states") -> None:
        self.process = subprocess.Popen([sys.executable, "-c", GLOVE, topic], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, text=True)
        ready = self.process.stdout.readline().strip()
        if ready != "ready":
            raise RuntimeError(f"the test's glove did not start (said {ready!r}, exit {self.process.poll()})")

    def _say(self, line: str) -> None:
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()

    def move(self, to: Synergies, seconds: float = 0.0) -> None:
        """From where the operator's hand is now to `to` in `seconds`, then held; publishing (again)."""
        self._say(f"move {to.fingers} {to.thumb} {to.opposition} {seconds}")

    def stamp(self, age_s: float | None) -> None:
        """From the next sample on, stamp each `age_s` before it is published (None: stamped 0)."""
        self._say("stamp zero" if age_s is None else f"stamp {age_s}")

    def move_and_fall_silent(self, to: Synergies, seconds: float, silent_after_s: float) -> int:
        """`move(to, seconds)` that stops publishing `silent_after_s` into the move, timed by the
        glove's own process on its real-time rung (the test's process, at the default priority on a
        loaded machine, could say "stop" late); when the last sample went out (ns)."""
        self._say(f"move {to.fingers} {to.thumb} {to.opposition} {seconds} {silent_after_s}")
        return self._stopped()

    def stop(self) -> int:
        """Stop publishing; when the last sample went out (ns)."""
        self._say("stop")
        return self._stopped()

    def _stopped(self) -> int:
        words = self.process.stdout.readline().split()
        if words[:1] != ["stopped"]:
            raise RuntimeError(f"the test's glove answered {words!r} to stop")
        return int(words[1])

    def close(self) -> None:
        self.process.stdin.close()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


class WearingTheGlove(MotorPositions):
    """For a GraphTestCase whose subscribe() sets `cls.glove` (an OperatorGlove) and `cls.joints` (a
    /joint_states collection): the glove closed with the graph, and where the motors stand."""

    JOINT_STATES_WAIT_S = 30.0

    @classmethod
    def tearDownClass(cls) -> None:
        cls.glove.close()
        super().tearDownClass()  # type: ignore[misc]
