"""The hand's control path runs ahead of everything else on the computer: real-time scheduling for
the processes a grasp depends on (the drivers, the force estimator, the manipulation node, the
emulated hardware).

Why not niceness alone: the Linux fair scheduler gives a process at nice -5 about three times the
CPU of one at nice 0, but still lets every runnable process run its slice before a woken node is
served. With a CPU hog per core and a memory hog beside the graph (test/support/prisma_testing/load_harness.py),
ten pinch grasps at nice -5 ended `sensor_stale` two to ten times (a stream 101-198 ms old): the
nodes were ready and waiting for a core. SCHED_FIFO runs a woken node at once, ahead of every
ordinary process. That holds while the control path leaves the computer room: it blocks between
samples, and it took about a third of one core when this was written. On a slow 2-core VM it has
since taken 1.4-1.7 cores (docs/performance.md, "The emulated servo bus on a full machine"); then it
starves the rest (the kernel's workers that move serial bytes too, it seems: not shown) until the kernel's real-time
budget (95% of each second) throttles it.

Real-time scheduling needs root, CAP_SYS_NICE or an `rtprio` limit (docs/real_hand.md, "Real-time limits"). Where
it is refused the process falls back to a raised niceness, which needs the `nice` limit, and
otherwise runs at the default priority; `apply_priority` says which happened, for the node's log.

The launch files ask for it through the environment (PRISMA_RT_PRIORITY, PRISMA_NICE), read once at
the start of the process. A node takes its real-time rung only once it is built (node_process.py):
its start (loading a model, torch's first inference) is seconds of CPU that, at SCHED_FIFO 20, would
hold a core away from the nodes already running on the rung, a motor driver homing included (its
servos' 100 ms Bus Watchdog fired so in a full test run). Until then it runs at the niceness.
`apply_priority` sets every thread the process has (DDS's, the executor's); threads started later
inherit the policy of the thread that starts them.
"""
from __future__ import annotations

import os
from collections.abc import Mapping

RT_PRIORITY_ENV = "PRISMA_RT_PRIORITY"  # 1-99: SCHED_FIFO priority; 0 or unset: no real-time scheduling
NICE_ENV = "PRISMA_NICE"  # niceness when real-time scheduling is not asked for or refused
RT_PRIORITY_RANGE = (0, 99)
NICE_RANGE = (-20, 19)

# The control path's rung (drivers, force estimator, manipulation, emulated hardware): hand.launch.py's
# rt_priority:= and nice:= defaults, the niceness where real-time scheduling is refused. SCHED_FIFO: a
# higher priority runs first; niceness: a lower one. The test processes' rungs, above and below it, are
# test support's (test/support/prisma_testing/priorities.py).
CONTROL_PATH_RT_PRIORITY = 20
CONTROL_PATH_NICE = -5


def control_path_env() -> dict[str, str]:
    """The environment that puts a process on the control path's rung, as hand.launch.py does."""
    return {RT_PRIORITY_ENV: str(CONTROL_PATH_RT_PRIORITY), NICE_ENV: str(CONTROL_PATH_NICE)}


def try_rt_priority(priority: int) -> bool:
    """This thread at SCHED_FIFO `priority` where permitted (False where not: the caller runs on at
    its priority). For a process's main thread before rclpy starts its threads, or a child's preexec_fn."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError:  # EPERM: no rtprio limit or CAP_SYS_NICE
        return False
    return True


def _env_int(env: Mapping[str, str], name: str, low: int, high: int) -> int | None:
    text = env.get(name, "").strip()
    if not text:
        return None
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"{name}={text!r}: an integer from {low} to {high}") from None
    if not low <= value <= high:
        raise ValueError(f"{name}={value}: must be from {low} to {high}")
    return value


def _threads() -> list[int]:
    """This process's threads (a library may have started a pool at import: numpy's BLAS)."""
    try:
        return sorted(int(tid) for tid in os.listdir("/proc/self/task"))
    except OSError:
        return [0]  # no /proc: the calling thread only


def apply_priority(rt_priority: int | None, nice: int | None) -> str:
    """Run this process's threads (and those they start from now on) at SCHED_FIFO `rt_priority`
    or, when that is None/0 or not permitted, at niceness `nice` (None: leave it). Returns what
    was applied, in words; never raises for a refused request."""
    if rt_priority:
        try:
            for tid in _threads():
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(rt_priority))
            return f"real-time scheduling (SCHED_FIFO {rt_priority})"
        except PermissionError:
            refused = f"real-time priority {rt_priority} refused (no rtprio limit or CAP_SYS_NICE)"
        except OSError as exc:
            refused = f"real-time priority {rt_priority} refused ({exc.strerror})"
    else:
        refused = ""
    if nice is None:
        return refused + ("; " if refused else "") + "default priority"
    try:
        for tid in _threads():
            os.setpriority(os.PRIO_PROCESS, tid, nice)
        applied = f"nice {nice}"
    except PermissionError:
        applied = f"default priority (nice {nice} refused: no nice limit or CAP_SYS_NICE)"
    return (refused + "; " if refused else "") + applied


def priority_from_env(env: Mapping[str, str] | None = None) -> tuple[int | None, int | None] | None:
    """(rt_priority, nice) from PRISMA_RT_PRIORITY and PRISMA_NICE, None when neither is set (a process
    started by hand keeps the priority it was given). ValueError names a malformed one."""
    env = os.environ if env is None else env
    rt_priority = _env_int(env, RT_PRIORITY_ENV, *RT_PRIORITY_RANGE)
    nice = _env_int(env, NICE_ENV, *NICE_RANGE)
    if rt_priority is None and nice is None:
        return None
    return rt_priority, nice


def apply_priority_from_env(env: Mapping[str, str] | None = None) -> str | None:
    """`apply_priority` with `priority_from_env` (None when nothing is asked)."""
    priority = priority_from_env(env)
    return None if priority is None else apply_priority(*priority)
