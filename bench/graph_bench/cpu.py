"""CPU time and scheduling of processes, read from Linux's /proc: per process and thread name, the
whole machine's, and the rung (real-time priority or niceness) each process runs at."""
from __future__ import annotations

import os
import time
from pathlib import Path

from prisma_common.procfs import comm, stat_fields

CLK_TCK = os.sysconf("SC_CLK_TCK")
POLICIES = {0: "default", 1: "SCHED_FIFO", 2: "SCHED_RR", 3: "SCHED_BATCH", 5: "SCHED_IDLE"}


def cpu_ticks(pid: int) -> tuple[int, dict[str, int]]:
    """utime + stime of a process (all its threads) and per thread name, in clock ticks."""
    f = stat_fields(f"/proc/{pid}/stat")
    total = int(f[11]) + int(f[12])
    threads: dict[str, int] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            tf = stat_fields(f"{task}/stat")
            name = comm(f"{task}/stat")
        except OSError:
            continue  # thread ended
        threads[name] = threads.get(name, 0) + int(tf[11]) + int(tf[12])
    return total, threads


def rung(pid: int) -> str:
    """The scheduling a process runs at ("SCHED_FIFO 20", "nice -5", "default"): proc(5) fields 19
    (nice), 40 (rt_priority) and 41 (policy) of its main thread. The runs of a comparison must share it."""
    try:
        f = stat_fields(f"/proc/{pid}/stat")
    except OSError:
        return "gone"
    nice, rt_priority, policy = int(f[16]), int(f[37]), int(f[38])
    if policy in (1, 2):
        return f"{POLICIES[policy]} {rt_priority}"
    return f"nice {nice}" if nice else POLICIES.get(policy, f"policy {policy}")


def system_ticks() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine, all cores."""
    values = [int(v) for v in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    idle = values[3] + values[4]
    total = sum(values[:8])
    return total - idle, total


def wait_quiet(max_busy_pct: float | None, max_wait_s: float) -> dict:
    """Wait until the machine's CPU use (all processes, % of one core over 3 s) is at most
    max_busy_pct, for up to max_wait_s; returns what was seen. Other jobs share this machine."""
    t0 = time.monotonic()
    while True:
        busy0, total0 = system_ticks()
        time.sleep(3.0)
        busy1, total1 = system_ticks()
        busy = (busy1 - busy0) / max(1, total1 - total0) * (os.cpu_count() or 1) * 100
        waited = time.monotonic() - t0
        if max_busy_pct is None or busy <= max_busy_pct or waited >= max_wait_s:
            return {"busy_before_pct": round(busy, 1), "waited_s": round(waited, 1),
                    "quiet": None if max_busy_pct is None else busy <= max_busy_pct}
        time.sleep(7.0)


def measure_cpu(pids: dict[str, int], seconds: float) -> dict:
    """CPU of each process over `seconds`, in % of one core, with the machine's load beside it."""
    start = {name: cpu_ticks(pid) for name, pid in pids.items()}
    busy0, total0 = system_ticks()
    load0 = os.getloadavg()
    t0 = time.monotonic()
    time.sleep(seconds)
    elapsed = time.monotonic() - t0
    end = {name: cpu_ticks(pid) for name, pid in pids.items()}
    busy1, total1 = system_ticks()
    cores = os.cpu_count() or 1
    out: dict = {"window_s": round(elapsed, 2), "processes": {}}
    ours = 0.0
    for name, pid in pids.items():
        pct = (end[name][0] - start[name][0]) / CLK_TCK / elapsed * 100
        ours += pct
        threads = {t: round((v - start[name][1].get(t, 0)) / CLK_TCK / elapsed * 100, 1)
                   for t, v in end[name][1].items()}
        busy_threads = {t: v for t, v in sorted(threads.items(), key=lambda kv: -kv[1]) if v > 0}
        out["processes"][name] = {"cpu_pct": round(pct, 1), "threads": busy_threads, "rung": rung(pid)}
    machine = (busy1 - busy0) / max(1, total1 - total0) * cores * 100
    out["machine_busy_pct"] = round(machine, 1)  # all cores, % of one core
    out["others_pct"] = round(machine - ours, 1)  # everything not listed above
    out["loadavg_1min"] = [round(load0[0], 2), round(os.getloadavg()[0], 2)]
    return out


class CpuSampler:
    """CPU of processes between construction and done() (a window that something else fills)."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.start = {name: cpu_ticks(pid)[0] for name, pid in pids.items()}
        self.t0 = time.monotonic()
        self.t0_ns = time.time_ns()

    def done(self) -> dict:
        """window_s, the window's wall-clock ends (ns) and each process's % of one core."""
        elapsed = time.monotonic() - self.t0
        return {"window_s": round(elapsed, 2), "window_ns": [self.t0_ns, time.time_ns()],
                **{name: round((cpu_ticks(pid)[0] - self.start[name]) / CLK_TCK / elapsed * 100, 1)
                   for name, pid in self.pids.items()}}
