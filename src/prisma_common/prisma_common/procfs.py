"""Processes read from Linux's /proc: the nodes a launch started, their CPU time and memory.

For the soak, the benchmarks and the tests that watch a launched graph from outside it: a launch
file's nodes are its descendants (ros2 launch -> the node's interpreter), found by their command
line, as `ps` would.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

PROC = Path("/proc")

ArgvMatch = Callable[[list[bytes]], bool]


def stat_fields(path: str | Path) -> list[str]:
    """The fields of a /proc/<pid>/stat (or task stat) after the command name: [0] state, [1] ppid,
    [11] utime, [12] stime (proc(5) numbers them from 3)."""
    text = Path(path).read_text()
    return text[text.rfind(")") + 2:].split()  # comm may hold spaces and parentheses


def comm(path: str | Path) -> str:
    """The command (thread) name in a /proc/<pid>/stat."""
    text = Path(path).read_text()
    return text[text.find("(") + 1:text.rfind(")")]


def cmdline(pid: int) -> list[bytes]:
    """A process's argv (OSError once it is gone)."""
    return (PROC / str(pid) / "cmdline").read_bytes().split(b"\0")


def descendants(pid: int) -> list[int]:
    """Every process below `pid` (children, their children, ...) now."""
    parent = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit():
            try:
                parent[int(entry.name)] = int(stat_fields(entry / "stat")[1])
            except (OSError, IndexError, ValueError):
                continue  # gone meanwhile
    found, frontier = [], [pid]
    while frontier:
        p = frontier.pop()
        children = [c for c, pp in parent.items() if pp == p]
        found += children
        frontier += children
    return found


def executable_named(name: str) -> ArgvMatch:
    """A process running the executable `name` (itself or as the script of its interpreter)."""
    return lambda argv: any(Path(a.decode(errors="replace")).name == name for a in argv[:2])


def node_named(name: str, namespace: str | None = None) -> ArgvMatch:
    """A node launch_ros started as `name` (`-r __node:=<name>`), in `namespace` when given
    (`-r __ns:=<namespace>`; none: the root)."""
    def match(argv: list[bytes]) -> bool:
        if f"__node:={name}".encode() not in argv:
            return False
        if namespace is None:
            return True
        ns = next((a[len(b"__ns:="):].decode() for a in argv if a.startswith(b"__ns:=")), "")
        return ns.rstrip("/") == namespace
    return match


def launched_pids(root_pids: Iterable[int], matches: Mapping[str, ArgvMatch], timeout_s: float = 60.0,
                  poll_s: float = 0.5) -> dict[str, int]:
    """label -> pid of the descendant of `root_pids` that `matches[label]` accepts, polled until every
    label is found or `timeout_s` passed (then those found: the caller says what is missing)."""
    roots = list(root_pids)
    deadline = time.monotonic() + timeout_s
    found: dict[str, int] = {}
    while True:
        for pid in [d for root in roots for d in descendants(root)]:
            try:
                argv = cmdline(pid)
            except OSError:
                continue
            for label, match in matches.items():
                if match(argv):
                    found[label] = pid
        if len(found) == len(matches) or time.monotonic() > deadline:
            return found
        time.sleep(poll_s)


def rss_mb(pid: int) -> float | None:
    """Resident memory of a process in MiB (None once it is gone)."""
    try:
        for line in (PROC / str(pid) / "status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None
