"""Processes a test file started and left running: nodes of a launch that was not stopped, an
emulator, a probe. One left at real-time priority takes the CPU every later test's graph needs, so
that a run's later launch tests fail far from the file that leaked it.

Every process this pytest run starts inherits RUN_MARKER in its environment (set by conftest.py
before any test starts one; launch, `ip netns exec` and subprocess pass the environment on), so
they are told apart from anything else on the machine by reading /proc/<pid>/environ: a test never
stops a process it did not start.
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

RUN_MARKER = "PRISMA_TEST_RUN"
# the ROS 2 CLI's daemon outlives the command that started it by design (CI stops it at the end)
_EXPECTED_TO_OUTLIVE = ("_ros2_daemon",)


def mark_this_run() -> None:
    """Give the processes this run starts the marker (once, before any test starts one)."""
    os.environ.setdefault(RUN_MARKER, f"{os.getpid()}-{time.time_ns()}")


def started_by_this_run() -> dict[int, str]:
    """pid -> command line of every live process (not this one) that carries this run's marker."""
    marker = f"{RUN_MARKER}={os.environ[RUN_MARKER]}".encode()
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:  # gone meanwhile, or not ours to read
            continue
        if state != "Z" and command and not any(name in command for name in _EXPECTED_TO_OUTLIVE):
            found[int(entry.name)] = command
    return found


def stop_left_behind(known: set[int], grace_s: float = 10.0) -> dict[int, str]:
    """The processes of this run not in `known` that are still alive `grace_s` after the call (a
    launch's nodes take a few seconds to exit after SIGINT), each then killed; {} when none is."""
    deadline = time.monotonic() + grace_s
    while True:
        left = {pid: command for pid, command in started_by_this_run().items() if pid not in known}
        if not left or time.monotonic() >= deadline:
            break
        time.sleep(0.2)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return left
