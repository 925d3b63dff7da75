"""Processes the benchmarks start: each in its own process group, stopped as a whole (SIGINT, then
SIGTERM, then SIGKILL), none outliving the run; and the launched nodes found among them."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from prisma_common.procfs import launched_pids, node_named

BENCH = Path(__file__).resolve().parent.parent


@dataclass
class Proc:
    name: str
    popen: subprocess.Popen
    log: Path


def _child_env() -> dict:
    env = dict(os.environ)
    # the tests turn rclpy's field checks on; a deployed graph runs without them
    env.pop("ROS_PYTHON_CHECK_FIELDS", None)
    return env


def start(name: str, cmd: list[str], logdir: Path, env: dict[str, str] | None = None) -> Proc:
    """`cmd` in a process group of its own, its output in logdir/<name>.log."""
    log = logdir / f"{name}.log"
    handle = open(log, "wb")
    # own process group (stopped as a whole); SIGINT back to default in case this script runs as a
    # background job, whose children would otherwise inherit SIGINT ignored
    popen = subprocess.Popen(cmd, stdout=handle, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                             env={**_child_env(), **(env or {})}, start_new_session=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    handle.close()
    return Proc(name, popen, log)


def relay_command(script: str, role: str, *args: str) -> list[str]:
    """The command of a relay role of bench/<script> (ros_relay.py, teleop_relay.py)."""
    return [sys.executable, str(BENCH / script), role, *args]


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
        return True
    except ProcessLookupError:
        return False


def stop(procs: list[Proc], timeout_s: float = 15.0) -> None:
    """SIGINT each process group, then SIGTERM, then SIGKILL; waits until every group is gone."""
    for sig, wait_s in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        alive = [p for p in procs if _group_alive(p.popen.pid)]
        if not alive:
            break
        for p in alive:
            try:
                os.killpg(p.popen.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and any(_group_alive(p.popen.pid) for p in alive):
            for p in alive:
                p.popen.poll()
            time.sleep(0.1)
    for p in procs:
        try:
            p.popen.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            pass


def check_alive(procs: list[Proc]) -> None:
    """RuntimeError with the end of its log when one of `procs` has exited."""
    dead = [p for p in procs if p.popen.poll() is not None]
    if dead:
        tail = dead[0].log.read_text(errors="replace")[-1500:]
        raise RuntimeError(f"{dead[0].name} exited with {dead[0].popen.returncode}; log {dead[0].log}:\n{tail}")


def node_pids(launch_pid: int, names: tuple[str, ...], timeout_s: float = 60.0) -> dict[str, int]:
    """The pid of each node launched under `launch_pid` (launch_ros passes `-r __node:=<name>`)."""
    found = launched_pids([launch_pid], {name: node_named(name) for name in names}, timeout_s, poll_s=0.2)
    if len(found) < len(names):
        raise RuntimeError(f"launched nodes not found after {timeout_s:.0f} s: missing "
                           f"{sorted(set(names) - set(found))}")
    return found


def launch_nodes(name: str, cmd: list[str], logdir: Path, names: tuple[str, ...]) -> tuple[Proc, dict[str, int]]:
    """`ros2 launch ...` started as `name` and the pid of each of its nodes `names`; the launch is
    stopped again when they are not all found (a launch that outlived its run would load the next)."""
    proc = start(name, cmd, logdir)
    try:
        return proc, node_pids(proc.popen.pid, names)
    except BaseException:
        stop([proc])
        raise


def namespaced_node_pids(root_pids: list[int], nodes: list[tuple[str, str, str, str]],
                         timeout_s: float = 90.0) -> dict[str, int]:
    """The pid of each of `nodes` ((label, node, namespace, computer) rows) launched under `root_pids`
    (launch_ros passes `-r __node:=<name>` and, under a namespace, `-r __ns:=<namespace>`)."""
    found = launched_pids(root_pids, {label: node_named(node, namespace) for label, node, namespace, _ in nodes},
                          timeout_s)
    if len(found) == len(nodes):
        return found
    raise RuntimeError(f"launched nodes not found after {timeout_s:.0f} s: missing "
                       f"{sorted({n[0] for n in nodes} - set(found))}")
