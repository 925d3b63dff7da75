"""RosHarness.settle(): the barrier the sim-time node tests advance the clock behind; what
message_stamped says when the message it waits for never comes; the test process's DDS threads on
their rung.

settle() must not return while a callback it ran has set off another. rclpy starts a pass's quiet
timer when the pass starts; a pass that first resumes a slow coroutine (a goal's execute callback
on a busy machine) finds the timer run out when it waits, gets back what is ready at once, runs it,
and ends "timed out". Beside the load harness that ended a test's sim instant before the abort its
stale sample set off.
"""
from __future__ import annotations

import os
import subprocess
import time

from prisma_testing.node_process import process_deaths
from prisma_testing.priorities import TEST_COLLECTOR_NICE, TEST_DDS_NICE
from prisma_testing.ros_harness import RosHarness, require_ros

require_ros()

import pytest  # noqa: E402
from rclpy.node import Node  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402


class Relay(Node):
    """What a node does with a message: another message, here on `second`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("relay", **kwargs)
        self.out = self.create_publisher(String, "second", 10)
        self.create_subscription(String, "first", self.out.publish, 10)


class _Yield:
    def __await__(self):
        yield


async def slow_coroutine(done: list[bool]) -> None:
    """A coroutine task that takes longer than settle's quiet window each time it is resumed."""
    while not done:
        time.sleep(2 * RosHarness.SPIN_SEC)  # settle's default quiet window
        await _Yield()


def test_settle_runs_what_a_callback_set_off_when_the_quiet_timer_ran_out_before_the_wait(ros):
    relay = ros.node(Relay)
    second = ros.collect(String, "second")
    assert ros.spin_until(lambda: relay.out.get_subscription_count() >= 1, 10.0)
    done: list[bool] = []
    ros.executor.create_task(slow_coroutine(done))
    ros.publish("first", String(data="grasp"))  # in the relay's queue: settle's first pass runs it
    try:
        ros.settle()
        assert [m.data for m in second] == ["grasp"]
    finally:
        done.append(True)
        ros.spin_for(0.05)


def test_settle_returns_while_a_coroutine_still_awaits(ros):
    """A goal's execute callback awaits its end for the whole goal: polling it is not work."""
    done: list[bool] = []
    ros.executor.create_task(slow_coroutine(done))
    start = time.monotonic()
    try:
        ros.settle(timeout_sec=5.0)
    finally:
        done.append(True)
        ros.spin_for(0.05)
    assert time.monotonic() - start < 1.0


def test_settle_returns_with_nothing_to_run(ros):
    start = time.monotonic()
    ros.settle()
    assert time.monotonic() - start < 1.0


class StalePublisher(Node):
    """A stream that keeps coming, every message stamped at one instant in the past."""

    STAMP_NS = 1_600_000_000 * 10**9

    def __init__(self, **kwargs) -> None:
        super().__init__("stale_publisher", **kwargs)
        self.out = self.create_publisher(JointState, "stale", 10)
        message = JointState()
        message.header.stamp.sec = self.STAMP_NS // 10**9
        self.create_timer(0.02, lambda: self.out.publish(message))


def test_message_stamped_tells_a_stream_still_published_from_a_silent_one(ros):
    ros.node(StalePublisher)
    received = ros.collect(JointState, "stale")
    assert ros.spin_until(lambda: len(received) >= 3, 10.0)
    with pytest.raises(AssertionError) as behind:
        ros.message_stamped(received, time.time_ns(), timeout_sec=0.5)
    # the newest it has, how this process ran meanwhile, and a fresh subscription's view
    text = str(behind.value)
    assert text.startswith("newest: -"), text
    assert " spins, longest gap " in text, text
    assert "stale: 1 publisher(s), a fresh subscription received " in text, text
    silent = ros.collect(JointState, "silent")
    with pytest.raises(AssertionError) as nothing:
        ros.message_stamped(silent, time.time_ns(), timeout_sec=0.1)
    assert "silent: 0 publisher(s), a fresh subscription received nothing in 2.0 s" in str(nothing.value)


def _thread_niceness() -> dict[str, set[int]]:
    """Niceness of this process's threads, by thread name."""
    found: dict[str, set[int]] = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/comm") as comm, open(f"/proc/self/task/{tid}/stat") as stat:
                found.setdefault(comm.read().strip(), set()).add(int(stat.read().rsplit(")", 1)[1].split()[16]))
        except FileNotFoundError:  # a thread that ended meanwhile
            continue
    return found


def test_dds_threads_run_on_their_rung_and_this_thread_and_its_children_do_not(ros):
    if os.geteuid() != 0:
        pytest.skip("a niceness below 0 needs root or CAP_SYS_NICE: the harness leaves it where it is")
    ours = os.getpriority(os.PRIO_PROCESS, 0)
    threads = _thread_niceness()
    # Cyclone's receive and delivery threads: what takes the samples off the socket into the readers
    assert threads["recvUC"] == threads["dq.user"] == {TEST_DDS_NICE}, threads
    assert os.getpriority(os.PRIO_PROCESS, 0) == ours != TEST_DDS_NICE
    child = subprocess.run(["sh", "-c", "cut -d' ' -f19 /proc/self/stat"], capture_output=True, text=True, check=True)
    assert int(child.stdout) == ours


def test_publishing_keeps_its_rate_while_this_process_does_not_spin(ros):
    received = ros.collect(JointState, "other_driver")
    names = [["a"], ["b", "c"], []]
    with ros.publishing(JointState, "other_driver", lambda i: JointState(name=names[i % 3]), 100.0,
                        wait_for_subscribers=1) as sent:
        time.sleep(0.5)  # the executor is not spun: a probe timer would have sent nothing
        during_sleep = len(sent)
    assert 25 <= during_sleep <= 52, during_sleep  # 50 on time; half of it would still be no timer
    # every message sent came, stamped at its send instant, the kinds in turn
    assert ros.spin_until(lambda: len(received) >= len(sent), 10.0), (len(received), len(sent))
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in received] == sent
    assert [list(m.name) for m in received] == [names[i % 3] for i in range(len(sent))]


@pytest.fixture
def apart():
    """A RosHarness whose collections a collector process takes (as the launch tests' do)."""
    harness = RosHarness(collect_apart=True)
    try:
        yield harness
    finally:
        harness.shutdown()


def _scheduling(pid: int) -> tuple[int, int]:
    """(policy, niceness) of a process, from /proc."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return int(fields[38]), int(fields[16])


def test_a_collection_apart_holds_every_message_while_this_process_does_not_spin(apart):
    received = apart.collect(JointState, "apart")
    names = [["thumb"], ["index", "middle"], []]
    with apart.publishing(JointState, "apart", lambda i: JointState(name=names[i % 3], position=[i * 0.5]),
                          100.0, wait_for_subscribers=1) as sent:
        time.sleep(0.5)  # nothing spins the executor: the collector's process takes them
    assert len(sent) >= 25, len(sent)
    deadline = time.monotonic() + 10.0
    while len(received) < len(sent) and time.monotonic() < deadline:
        time.sleep(0.05)
    # each message whole, stamped at its send instant, in order; read back as messages
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in received] == sent
    assert [list(m.name) for m in received] == [names[i % 3] for i in range(len(sent))]
    assert [m.position[0] for m in received[-2:]] == [(len(sent) - 2) * 0.5, (len(sent) - 1) * 0.5]
    assert received[-1] is received[len(sent) - 1] is list(reversed(received))[0]
    # what message_stamped finds in it: the first message stamped at or after the instant
    assert apart.message_stamped(received, sent[3] - 1, timeout_sec=1.0) is received[3]
    collector = apart._collector.proc.pid
    if os.geteuid() == 0:  # a niceness below 0 needs root or a nice limit
        assert _scheduling(collector) == (os.SCHED_OTHER, TEST_COLLECTOR_NICE)
    apart.stop_collecting(received)
    with apart.publishing(JointState, "apart", lambda i: JointState(), 100.0):
        time.sleep(0.3)
    assert len(received) == len(sent)  # stopped: nothing more, what it held still there


def test_a_silent_collection_apart_says_so_and_shutdown_removes_its_files():
    apart = RosHarness(collect_apart=True)
    try:
        silent = apart.collect(JointState, "silent_apart")
        with pytest.raises(AssertionError) as nothing:
            apart.message_stamped(silent, time.time_ns(), timeout_sec=0.1)
        folder = apart._collector.folder
    finally:
        apart.shutdown()
    assert "silent_apart: 0 publisher(s), a fresh subscription received nothing in 2.0 s" in str(nothing.value)
    assert not os.path.exists(folder)


def test_process_deaths_leaves_out_only_the_exit_code_asyncio_made_up_for_a_reaped_pid():
    lost = "Unknown child process pid 23652, will report returncode 255"
    died = "[ERROR] [manipulation-2]: process has died [pid 23652, exit code 255, cmd '/x/manipulation --ros-args']."
    other = "[ERROR] [rviz2-7]: process has died [pid 23660, exit code -6, cmd 'rviz2 -d hand.rviz']."
    same_code_other_pid = "[ERROR] [tactile_driver-1]: process has died [pid 23650, exit code 255, cmd 'td']."
    clean = "[INFO] [motor_driver-3]: process has finished cleanly [pid 23654]"
    assert process_deaths("\n".join([clean, lost, died])) == []
    assert process_deaths("\n".join([died, clean])) == [died]  # no warning: a real 255
    assert process_deaths("\n".join([lost, died, other, same_code_other_pid])) == [other, same_code_other_pid]
