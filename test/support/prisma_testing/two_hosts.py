"""Two hosts on one machine: a robot and a workstation as two network namespaces joined by a veth
pair, for the graph split with hand.launch.py parts:=robot|workstation (docs/architecture.md,
"Across machines").

    hosts = TwoHosts.create()            # root and `ip netns`; HostsUnavailable (the reason) elsewhere
    try:
        robot = subprocess.Popen(hosts.robot.run(["ros2", "launch", ...]), env=hosts.dds_env(...))
        hosts.link_down(); hosts.link_up()
    finally:
        hosts.delete()                   # exactly what create() made, also after a failure half-way

Each namespace has its loopback and one end of the veth, with an address on a /30 of its own; no
route leads anywhere else, so DDS in them can only meet over the link. Names and addresses derive
from the creating process's id: parallel runs do not clash. Both namespaces share the machine's one
kernel clock (real hosts need NTP or chrony: manipulation on the workstation stamps the MoveMotors
goals whose lease the motor driver on the robot counts from that stamp).

The link faults are the interface going down and up (`ip link set ... down`): the kernels here have
no netem for loss or delay.
"""
from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from prisma_testing.repo_paths import CONFIG

# subnet: ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET, Cyclone DDS discovering by multicast on the veth (no
# route needed: Cyclone names the interface) with config/cyclonedds_hosts.xml (data unicast, so each
# host's own nodes still hear each other while the link is down). static: unicast discovery to the
# other host's address only, as on a network that drops multicast (ROS_STATIC_PEERS; the LOCALHOST
# range keeps multicast off).
DISCOVERY = ("subnet", "static")
CYCLONE_CONFIG = CONFIG / "cyclonedds_hosts.xml"


class HostsUnavailable(RuntimeError):
    """Network namespaces cannot be made here (not root, no `ip`, a kernel without them)."""


@dataclass(frozen=True)
class Host:
    name: str  # robot / workstation
    netns: str
    interface: str  # this host's end of the veth pair
    address: str

    def run(self, command: Sequence[str]) -> list[str]:
        """`command` as this host runs it (inside its network namespace; environment passes through)."""
        return ["ip", "netns", "exec", self.netns, *command]


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    try:
        done = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)
    except OSError as exc:  # no iproute2
        raise HostsUnavailable(f"ip {' '.join(args)}: {exc}") from exc
    if check and done.returncode != 0:
        raise HostsUnavailable(f"ip {' '.join(args)}: {done.stderr.strip() or done.returncode}")
    return done


@dataclass
class TwoHosts:
    robot: Host
    workstation: Host
    _made: list[tuple[str, ...]] = field(default_factory=list)  # how to undo each step, newest last

    @classmethod
    def create(cls, tag: int | None = None) -> TwoHosts:
        """Make both namespaces and the link between them, up. tag: what makes the names unique
        (default: this process's id)."""
        if os.geteuid() != 0:
            raise HostsUnavailable("network namespaces need root (ip netns add)")
        tag = os.getpid() if tag is None else tag
        subnet = tag % (1 << 14)  # a /30 of 10.200.0.0/16, from the tag
        base = (10 << 24) | (200 << 16) | (subnet << 2)
        address = [".".join(str((base + i) >> s & 255) for s in (24, 16, 8, 0)) for i in (1, 2)]
        hosts = cls(Host("robot", f"prisma_robot_{tag}", f"prr{tag}", address[0]),
                    Host("workstation", f"prisma_ws_{tag}", f"prw{tag}", address[1]))
        try:
            hosts._make()
        except BaseException:
            hosts.delete()
            raise
        return hosts

    def _make(self) -> None:
        r, w = self.robot, self.workstation
        for host in (r, w):
            _ip("netns", "add", host.netns)
            self._made.append(("netns", "del", host.netns))
        _ip("link", "add", r.interface, "type", "veth", "peer", "name", w.interface)
        self._made.append(("link", "del", r.interface))  # both ends go with it, while still out here
        for host in (r, w):
            _ip("link", "set", host.interface, "netns", host.netns)
        self._made.remove(("link", "del", r.interface))  # now inside the namespaces: they go with them
        for host in (r, w):
            _ip("-n", host.netns, "addr", "add", f"{host.address}/30", "dev", host.interface)
            _ip("-n", host.netns, "link", "set", "lo", "up")
            _ip("-n", host.netns, "link", "set", host.interface, "up")

    def delete(self) -> None:
        """Remove what create() made, newest first (a namespace still holding a process lingers
        until that process ends: stop them first)."""
        while self._made:
            _ip(*self._made.pop(), check=False)

    # ---- the link ----------------------------------------------------------------------------------
    def link_down(self) -> int:
        """Take the robot's end of the link down (the pair loses its carrier both ways); the wall
        clock (ns) once it is down."""
        _ip("-n", self.robot.netns, "link", "set", self.robot.interface, "down")
        return time.time_ns()

    def link_up(self) -> int:
        """Bring the link back; the wall clock (ns) just before."""
        now = time.time_ns()
        _ip("-n", self.robot.netns, "link", "set", self.robot.interface, "up")
        return now

    def link_is_up(self) -> bool:
        return "LOWER_UP" in _ip("-n", self.robot.netns, "link", "show", self.robot.interface).stdout

    # ---- DDS ---------------------------------------------------------------------------------------
    def dds_env(self, host: Host, discovery: str = "subnet") -> dict[str, str]:
        """The environment for a ROS process on `host`: discovery over the link as chosen (see
        DISCOVERY). ROS_DOMAIN_ID is the caller's, the same on both hosts."""
        if discovery == "subnet":
            return {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": "",
                    "CYCLONEDDS_URI": f"file://{CYCLONE_CONFIG}"}
        if discovery == "static":
            other = self.workstation if host is self.robot else self.robot
            return {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": other.address,
                    "CYCLONEDDS_URI": ""}
        raise ValueError(f"discovery {discovery!r} is not one of {DISCOVERY}")

