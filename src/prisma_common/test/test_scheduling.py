"""Process priority from the environment: real-time where permitted, niceness otherwise, said in words."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from prisma_common.scheduling import (
    CONTROL_PATH_NICE,
    CONTROL_PATH_RT_PRIORITY,
    apply_priority,
    apply_priority_from_env,
    control_path_env,
)
from prisma_testing.priorities import FAULT_CLI_RT_PRIORITY, PROBE_RT_PRIORITY, TEST_COLLECTOR_NICE, TEST_DDS_NICE

IS_ROOT = os.geteuid() == 0

PROBE = """
import os, sys, threading
from prisma_common.scheduling import apply_priority_from_env
started = threading.Event()
threading.Thread(target=lambda: (started.set(), threading.Event().wait(5)), daemon=True).start()  # a pool at import
started.wait()
print(apply_priority_from_env())
for tid in sorted(int(t) for t in os.listdir("/proc/self/task")):
    print(tid, os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority, os.getpriority(os.PRIO_PROCESS, tid))
"""


def run_probe(env: dict[str, str]) -> list[str]:
    out = subprocess.run([sys.executable, "-c", PROBE], env={**os.environ, **env}, capture_output=True, text=True,
                         check=True)
    return out.stdout.splitlines()


def test_nothing_asked_nothing_changed():
    assert apply_priority_from_env({}) is None


@pytest.mark.parametrize("env, message", [
    ({"PRISMA_RT_PRIORITY": "high"}, "PRISMA_RT_PRIORITY='high': an integer from 0 to 99"),
    ({"PRISMA_RT_PRIORITY": "120"}, "PRISMA_RT_PRIORITY=120: must be from 0 to 99"),
    ({"PRISMA_NICE": "-30"}, "PRISMA_NICE=-30: must be from -20 to 19"),
])
def test_a_malformed_request_is_named(env, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        apply_priority_from_env(env)


@pytest.mark.skipif(not IS_ROOT, reason="real-time scheduling needs root (or an rtprio limit) to be granted")
def test_real_time_for_every_thread_when_permitted():
    said, *threads = run_probe({"PRISMA_RT_PRIORITY": "20", "PRISMA_NICE": "-5"})
    assert said == "real-time scheduling (SCHED_FIFO 20)"
    assert len(threads) == 2  # the main thread and the one started before the call
    assert all(line.split()[1:3] == [str(os.SCHED_FIFO), "20"] for line in threads)


def test_refused_real_time_falls_back_to_niceness_and_says_why(monkeypatch):
    """As for a user without an rtprio limit: the kernel refuses SCHED_FIFO with EPERM."""
    def refuse(*_args):
        raise PermissionError(1, "Operation not permitted")

    applied = []
    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(os, "setpriority", lambda which, who, value: applied.append((who, value)))
    assert apply_priority(20, 5) == "real-time priority 20 refused (no rtprio limit or CAP_SYS_NICE); nice 5"
    assert applied and {value for _, value in applied} == {5}  # every thread
    monkeypatch.setattr(os, "setpriority", refuse)
    assert apply_priority(20, -5) == ("real-time priority 20 refused (no rtprio limit or CAP_SYS_NICE); "
                                      "default priority (nice -5 refused: no nice limit or CAP_SYS_NICE)")


def test_niceness_only_when_real_time_is_not_asked_for():
    assert apply_priority(0, None) == "default priority"
    current = os.getpriority(os.PRIO_PROCESS, 0)
    assert apply_priority(None, current) == f"nice {current}"  # the same value: changes nothing


def test_the_ladder_runs_probes_above_the_control_path_above_the_fault_cli():
    assert PROBE_RT_PRIORITY > CONTROL_PATH_RT_PRIORITY > FAULT_CLI_RT_PRIORITY > 0 and CONTROL_PATH_NICE < 0
    # a test's DDS threads ahead of ordinary processes, never ahead of the control path's fallback
    assert CONTROL_PATH_NICE <= TEST_DDS_NICE < 0 and CONTROL_PATH_NICE <= TEST_COLLECTOR_NICE < 0
    lines = run_probe(control_path_env())
    if IS_ROOT:
        assert lines[0] == f"real-time scheduling (SCHED_FIFO {CONTROL_PATH_RT_PRIORITY})"
        assert all(line.split()[1:3] == [str(os.SCHED_FIFO), str(CONTROL_PATH_RT_PRIORITY)] for line in lines[1:])
    else:
        assert lines[0].endswith(f"nice {CONTROL_PATH_NICE}") or "refused" in lines[0]


@pytest.mark.skipif(not IS_ROOT, reason="SCHED_FIFO needs root or an rtprio limit")
def test_try_rt_priority_sets_the_calling_process():
    code = ("import os; from prisma_common.scheduling import try_rt_priority; "
            f"print(try_rt_priority({FAULT_CLI_RT_PRIORITY}), os.sched_getscheduler(0), "
            "os.sched_getparam(0).sched_priority)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", str(os.SCHED_FIFO), str(FAULT_CLI_RT_PRIORITY)]
