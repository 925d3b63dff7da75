"""What prisma-doctor knows about a running hand (`HandFacts`), as plain data: gathered from the
running drivers by doctor_graph.py (rclpy) and from this computer here (the ports, the udev rules,
the real-time limits), and looked up by the checks (`node_path`, `status_named`, `param`)."""
from __future__ import annotations

import grp
import os
import pwd
import resource
import stat
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prisma_common.diagnostics import DiagnosticStatusData

# the hand's nodes (hand.launch.py), each exactly once per namespace
HAND_NODES = ("tactile_driver", "motor_driver", "force_estimator", "manipulation")
SAMPLE_SECONDS = 1.0  # how long prisma-doctor samples the taxel topics
# config/udev/: the project's rules, looked for where udev reads rules from
UDEV_RULES = ("99-prisma-hub.rules",)
UDEV_DIRS = ("/etc/udev/rules.d", "/lib/udev/rules.d", "/usr/lib/udev/rules.d")
CAP_SYS_NICE = 23


@dataclass(frozen=True)
class PortFacts:
    """A device path as this user sees it."""

    path: str
    exists: bool
    writable: bool = False
    group: str = ""  # the group owning the device
    in_group: bool = False  # this process has that group
    group_listed: bool = False  # /etc/group lists the user in it (a new login gives it to the process)
    is_device: bool = False  # a character device (a real adapter or a pty), not a file


@dataclass(frozen=True)
class TaxelSample:
    """What one finger's /prisma/<finger>/taxels delivered during the sampling window."""

    messages: int
    seconds: float
    min_v: float = 0.0
    max_v: float = 0.0
    # the driver's own rate, from the sample counter of two of its /diagnostics reports (None: fewer
    # than two came): on a busy computer this process takes in fewer messages than the driver publishes
    published_hz: float | None = None

    @property
    def rate_hz(self) -> float:
        """The rate this process received the topic at."""
        return self.messages / self.seconds if self.seconds > 0 else 0.0

    @property
    def driver_hz(self) -> float:
        """The rate the driver published at: its own count when known, else what arrived here."""
        return self.rate_hz if self.published_hz is None else self.published_hz


@dataclass
class HandFacts:
    namespace: str = ""  # "" or "left"
    env: Mapping[str, str] = field(default_factory=dict)
    rtprio: tuple[int, int] = (0, 0)  # RLIMIT_RTPRIO soft, hard
    rt_capable: bool = False  # root or CAP_SYS_NICE: no limit needed
    nodes: Sequence[str] = ()  # fully qualified names of every node seen, duplicates kept
    motor_params: Mapping[str, Any] | None = None  # None: no answer from <ns>/motor_driver
    tactile_params: Mapping[str, Any] | None = None
    force_params: Mapping[str, Any] | None = None
    diagnostics: Sequence[DiagnosticStatusData] = ()  # the latest status of each name (this hand's)
    taxels: Mapping[str, TaxelSample] = field(default_factory=dict)
    # finger -> the nodes publishing its taxel topic, fully qualified (absent: not looked up)
    taxel_publishers: Mapping[str, Sequence[str]] = field(default_factory=dict)
    sample_seconds: float = 1.0
    ports: Mapping[str, PortFacts] = field(default_factory=dict)  # "servos", "hub"
    udev_installed: Mapping[str, str] = field(default_factory=dict)  # rule file -> where it is installed


# ---- facts of this computer (no ROS) ----------------------------------------------------------
def port_facts(path: str) -> PortFacts:
    try:
        info = os.stat(path)
    except OSError:
        return PortFacts(path, False)
    try:
        group = grp.getgrgid(info.st_gid).gr_name
        members = grp.getgrgid(info.st_gid).gr_mem
    except KeyError:
        group, members = str(info.st_gid), []
    user = user_name()
    return PortFacts(path, True, os.access(path, os.R_OK | os.W_OK), group, info.st_gid in os.getgroups()
                     or info.st_gid == os.getegid(), user in members, stat.S_ISCHR(info.st_mode))



def user_name() -> str:
    try:
        return pwd.getpwuid(os.geteuid()).pw_name
    except KeyError:
        return str(os.geteuid())


def rt_capable() -> bool:
    """Root or CAP_SYS_NICE: SCHED_FIFO is permitted whatever RLIMIT_RTPRIO says."""
    if os.geteuid() == 0:
        return True
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("CapEff:"):
                return bool(int(line.split()[1], 16) >> CAP_SYS_NICE & 1)
    except (OSError, ValueError):
        pass
    return False


def rtprio_limits() -> tuple[int, int]:
    soft, hard = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return int(soft), int(hard)  # RLIM_INFINITY is -1 on Linux, but rtprio's ceiling is 99 anyway


def udev_installed(rules: Iterable[str] = UDEV_RULES, dirs: Iterable[str] = UDEV_DIRS) -> dict[str, str]:
    found = {}
    for rule in rules:
        for folder in dirs:
            if (Path(folder) / rule).is_file():
                found[rule] = str(Path(folder) / rule)
                break
    return found



MIN_COUNTED_NS = 900_000_000  # two reports of the 1 Hz /diagnostics, about a second apart


def counted_rate_hz(reports: Sequence[tuple[int, int]]) -> float | None:
    """A driver's publish rate from the first and the latest of its reports (stamp ns, its sample
    counter); None with fewer than two a second apart, or a counter that went backward: two
    drivers report under one status name (a second hand's), and their counters mixed gave
    -10026 Hz (the fingertip line names the two publishers instead)."""
    if len(reports) < 2 or reports[-1][0] - reports[0][0] < MIN_COUNTED_NS:
        return None
    (t0, n0), (t1, n1) = reports[0], reports[-1]
    if n1 < n0:
        return None
    return (n1 - n0) / ((t1 - t0) * 1e-9)


# ---- lookups ---------------------------------------------------------------------------------
def node_path(namespace: str, node: str) -> str:
    ns = namespace.strip("/")
    return f"/{ns}/{node}" if ns else f"/{node}"


def status_named(facts: HandFacts, name: str) -> DiagnosticStatusData | None:
    for status in facts.diagnostics:
        if status.name == name:
            return status
    return None


def param(params: Mapping[str, Any] | None, name: str, default: Any = None) -> Any:
    return default if params is None else params.get(name, default)

