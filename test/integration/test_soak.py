"""Soak, two minutes: pinch Grasp, horizontal Manipulate, a cancelled vertical and a GripperCommand
open, back to back on `hand.launch.py sim:=true` beside the load harness (a CPU hog per core and a
memory-bandwidth hog at the default priority). Every goal reaches its paper outcome (none ends
sensor_stale, none is refused), every node is alive at the end and grew less than 5 MB after the
first cycle. The twenty-minute run is bench/soak.py (docs/performance.md).

Skips without ROS 2 (fails under PRISMA_REQUIRE_ROS=1).
"""
from __future__ import annotations

import json

from prisma_testing.goal_soak import node_pids, run_soak
from prisma_testing.load_harness import machine_load
from prisma_testing.node_process import ros2_launch, stop_process
from prisma_testing.ros_harness import require_ros

require_ros()

NODES = ("tactile_driver", "force_estimator", "motor_driver", "manipulation")
SOAK_S = 120.0
MAX_RSS_GROWTH_MB = 5.0


def test_two_minutes_of_goals_beside_the_load_harness(ros):
    ros.capture_logs()
    hand = ros2_launch("prisma_bringup", "hand.launch.py", "sim:=true")
    try:
        pids = node_pids(hand.proc.pid, NODES)
        assert set(pids) == set(NODES), (pids, hand.output[-3000:])
        with machine_load():
            report = run_soak(ros, pids, SOAK_S)
        print(json.dumps(report.summary(), indent=1))
    finally:
        stop_process(hand)
    assert report.goals and len(report.goals) % 4 == 0
    assert report.failures == [], report.why
    assert report.refused_replacements == []
    assert report.dead == []
    assert all(growth < MAX_RSS_GROWTH_MB for growth in report.rss_growth_mb.values()), report.rss_growth_mb
