"""Goals back to back on the launched sim graph, for a soak: each cycle a pinch Grasp (SUCCEEDED
force_reached), a horizontal Manipulate (SUCCEEDED edge_lost), a vertical Manipulate cancelled
0.3 s after it starts (CANCELED) and a GripperCommand to position 0 that opens the hand (SUCCEEDED
reached_goal); then the tactile driver's ~/replace_object puts the ball back between the open
fingers, as an operator would (the horizontal manipulation rolled it to the thumb pad's edge). The
soak starts once the graph takes goals (a pinch sent until it is not refused, then the hand opened);
after that every goal is sent once: a refusal (`not_ready`, `busy`) or any other end is a failure.
The nodes' resident memory is read from /proc after the first cycle (what a node allocates once,
its first goals' code paths and buffers, is not growth) and at the end.

Used by test/integration/test_soak.py (two minutes, in CI) and bench/soak.py (twenty, beside the
load harness: docs/performance.md).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from prisma_common.procfs import executable_named, launched_pids, rss_mb

CANCEL_AFTER_S = 0.3
# each goal's paper outcome: (status, reason)
EXPECTED = {"grasp pinch": ("SUCCEEDED", "force_reached"), "manipulate horizontal": ("SUCCEEDED", "edge_lost"),
            "manipulate vertical, cancelled": ("CANCELED", "canceled"), "gripper open": ("SUCCEEDED", "reached_goal")}


@dataclass
class GoalRecord:
    name: str
    outcome: tuple[str, str]
    seconds: float
    started_s: float  # from the soak's start

    @property
    def as_expected(self) -> bool:
        return self.outcome == EXPECTED[self.name]


@dataclass
class SoakReport:
    seconds: float
    goals: list[GoalRecord] = field(default_factory=list)
    rss_start_mb: dict[str, float] = field(default_factory=dict)
    rss_end_mb: dict[str, float] = field(default_factory=dict)
    dead: list[str] = field(default_factory=list)
    why: list[str] = field(default_factory=list)  # the manipulation node's log of each unexpected end
    rss_timeline: list[tuple[float, dict[str, float]]] = field(default_factory=list)  # after each cycle

    @property
    def failures(self) -> list[GoalRecord]:
        return [g for g in self.goals if not g.as_expected]

    @property
    def refused_replacements(self) -> list[str]:
        return [w for w in self.why if w.startswith("replace_object")]

    @property
    def rss_growth_mb(self) -> dict[str, float]:
        return {name: round(self.rss_end_mb[name] - self.rss_start_mb[name], 2)
                for name in self.rss_start_mb if name in self.rss_end_mb}

    def summary(self) -> dict[str, Any]:
        counts: dict[str, dict[str, int]] = {}
        for g in self.goals:
            key = f"{g.outcome[0]} {g.outcome[1]}"
            counts.setdefault(g.name, {}).setdefault(key, 0)
            counts[g.name][key] += 1
        return {"seconds": round(self.seconds, 1), "goals": len(self.goals), "cycles": len(self.goals) // 4,
                "failures": len(self.failures), "outcomes": counts, "rss_start_mb": self.rss_start_mb,
                "rss_growth_mb": self.rss_growth_mb, "dead": self.dead, "why": self.why}


def node_pids(launch_pid: int, names: tuple[str, ...], timeout_sec: float = 60.0) -> dict[str, int]:
    """The pids of the nodes a launch started (its descendants whose executable is named so)."""
    return launched_pids([launch_pid], {name: executable_named(name) for name in names}, timeout_sec)


def run_soak(ros: Any, pids: dict[str, int], seconds: float, namespace: str = "",
             progress: Callable[[str], None] = print) -> SoakReport:
    """Cycles of the four goals until `seconds` have passed (the cycle under way is finished), on the
    hand whose nodes run as `pids` (name -> pid). Needs `ros.capture_logs()` before the graph logs."""
    from control_msgs.action import GripperCommand
    from control_msgs.msg import GripperCommand as GripperCommandMsg
    from prisma_msgs.action import Grasp, Manipulate
    from std_srvs.srv import Trigger

    from prisma_testing.goals import goal_outcome

    clients = {"grasp": ros.action_client(Grasp, f"{namespace}/prisma/grasp", wait_sec=90.0),
               "manipulate": ros.action_client(Manipulate, f"{namespace}/prisma/manipulate", wait_sec=90.0),
               "gripper": ros.action_client(GripperCommand, f"{namespace}/prisma/gripper_cmd", wait_sec=90.0)}
    open_hand = GripperCommand.Goal(command=GripperCommandMsg(position=0.0, max_effort=0.0))
    # the graph takes goals: a pinch (sent again while refused for now), then the hand opened (a
    # GripperCommand result has no reason to tell a refusal by: sent until it opens)
    first = ros.send_until_started(clients["grasp"], Grasp.Goal(grasp="pinch"), timeout_sec=90.0)
    ros.result(first, timeout_sec=60.0)
    deadline = time.monotonic() + 60.0
    opened = EXPECTED["gripper open"]
    while goal_outcome(ros.result(ros.send_goal(clients["gripper"], open_hand), timeout_sec=60.0)) != opened:
        assert time.monotonic() < deadline, "the hand did not open in 60 s"
        ros.spin_for(0.5)
    report = SoakReport(seconds=0.0)

    def replace_object() -> None:
        answer = ros.call(Trigger, f"{namespace}/tactile_driver/replace_object", Trigger.Request())
        if not answer.success:
            report.why.append(f"replace_object at {time.monotonic() - start:.1f} s: {answer.message}")

    start = time.monotonic()
    replace_object()

    def goal(name: str, client: str, message: Any, cancel_after_s: float | None = None) -> None:
        # before the clock starts: a scan of every log line so far, longer with each goal
        ended = len(ros.logs(name="manipulation", contains="goal ended"))
        t0 = time.monotonic()
        feedback: list = []
        handle = ros.send_goal(clients[client], message, feedback)
        assert handle.accepted, f"{name}: not accepted (the hand's servers accept every goal)"
        if cancel_after_s is not None:
            result = handle.get_result_async()
            ros.spin_until(lambda: bool(feedback) or result.done(), 10.0)
            if not result.done():
                ros.spin_for(cancel_after_s)
                handle.cancel_goal_async()
        outcome = goal_outcome(ros.result(handle, timeout_sec=60.0))
        record = GoalRecord(name, outcome, time.monotonic() - t0, t0 - start)
        report.goals.append(record)
        if not record.as_expected:
            ros.spin_for(0.2)
            log = ros.logs(name="manipulation", contains="goal")[-3:]
            report.why.append(f"{name} at {record.started_s:.1f} s: {outcome}; "
                              f"{ros.logs(name='manipulation', contains='goal ended')[ended:] or log}")

    while time.monotonic() - start < seconds:
        goal("grasp pinch", "grasp", Grasp.Goal(grasp="pinch"))
        goal("manipulate horizontal", "manipulate", Manipulate.Goal(motion="horizontal"))
        goal("manipulate vertical, cancelled", "manipulate", Manipulate.Goal(motion="vertical"),
             cancel_after_s=CANCEL_AFTER_S)
        goal("gripper open", "gripper", open_hand)
        replace_object()
        cycles = len(report.goals) // 4
        report.rss_timeline.append((time.monotonic() - start, {name: round(rss_mb(pid) or 0.0, 2)
                                                               for name, pid in pids.items()}))
        if cycles == 1:
            report.rss_start_mb = {name: round(rss_mb(pid) or 0.0, 2) for name, pid in pids.items()}
        if cycles % 10 == 0:
            progress(f"soak: {cycles} cycles, {time.monotonic() - start:.0f} s, {len(report.failures)} failures")
    report.seconds = time.monotonic() - start
    report.rss_end_mb = {name: round(mb, 2) for name, pid in pids.items() if (mb := rss_mb(pid)) is not None}
    report.dead = sorted(set(pids) - set(report.rss_end_mb))
    return report
