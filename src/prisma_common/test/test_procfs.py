"""The /proc helper on processes this test starts: a shell's child found by its executable and by a
launch_ros-style node name, what is missing after the timeout, memory of a live and a gone process."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from prisma_common.procfs import cmdline, descendants, executable_named, launched_pids, node_named, rss_mb

# a shell whose child is a sleeping Python started the way launch_ros starts a node
CHILD = [sys.executable, "-c", "import time; time.sleep(30)", "--ros-args", "-r", "__node:=sleeper",
         "-r", "__ns:=/left"]


def test_a_launched_child_is_found_by_executable_and_by_node_name_and_namespace():
    # a session of its own: the shell and its child go together (killed alone, the shell would leave
    # the child running, reparented, out of reach of descendants())
    shell = subprocess.Popen(["bash", "-c", " ".join(f"'{a}'" for a in CHILD) + " & wait"], start_new_session=True)
    try:
        found = launched_pids([shell.pid], {"by node": node_named("sleeper", "/left"),
                                            "by root node": node_named("sleeper"),
                                            "by executable": executable_named(os.path.basename(sys.executable))},
                              timeout_s=10.0, poll_s=0.05)
        assert len(set(found.values())) == 1 and set(found) == {"by node", "by root node", "by executable"}
        pid = found["by node"]
        assert pid in descendants(shell.pid) and cmdline(pid)[0].decode() == sys.executable
        assert rss_mb(pid) is not None and rss_mb(pid) > 1.0
    finally:
        os.killpg(shell.pid, signal.SIGKILL)
        shell.wait()


def test_labels_not_found_are_left_out_after_the_timeout():
    shell = subprocess.Popen(["sleep", "30"])
    try:
        start = time.monotonic()
        found = launched_pids([shell.pid], {"right": node_named("sleeper", "/right")}, timeout_s=0.3, poll_s=0.05)
        assert found == {} and 0.3 <= time.monotonic() - start < 5.0
    finally:
        shell.kill()
        shell.wait()


def test_rss_of_a_gone_process_is_none():
    shell = subprocess.Popen(["true"])
    shell.wait()
    assert rss_mb(shell.pid) is None
