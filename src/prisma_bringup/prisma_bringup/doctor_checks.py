"""prisma-doctor's checks, without ROS: each one a function from the facts gathered about a running
hand (`HandFacts`) to one `CheckResult` line, `OK <check>: <found>` or `FAIL <check>: <what is wrong>
-> <how to fix it>`.

One fault, one failing line: a check whose subject cannot be examined because another line already
failed (the fingertips while the hub is unplugged, the servos behind a port that does not open) says
SKIP and names that line, so the line that fails is the one whose fix helps. WARN is advisory (a value
this motor driver does not report yet, a default that works but is fragile) and keeps the exit status 0.

The facts come from the running drivers (their parameters, /diagnostics, the taxel topics, the ROS
graph) and from this computer (the ports, the udev rules, the limits, the environment); the doctor never
opens a driver's port. `doctor.py` gathers them with rclpy; everything here is plain data.
"""
from __future__ import annotations

import grp
import os
import re
import resource
import stat
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prisma_common.diagnostics import ERROR, OK, DiagnosticStatusData
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_motor_driver import control_table as ct

# the hand's nodes (hand.launch.py), each exactly once per namespace
HAND_NODES = ("tactile_driver", "motor_driver", "force_estimator", "manipulation")
SAMPLE_SECONDS = 1.0  # how long prisma-doctor samples the taxel topics
# hand.launch.py's rt_priority default: the rtprio limit must allow it
DEFAULT_RT_PRIORITY = 20
# config/udev/: the project's rules, looked for where udev reads rules from
UDEV_RULES = ("99-prisma-hub.rules",)
UDEV_DIRS = ("/etc/udev/rules.d", "/lib/udev/rules.d", "/usr/lib/udev/rules.d")
# the highest ROS_DOMAIN_ID whose DDS ports exist (0-101 is the range clear of Linux's ephemeral
# ports; above it works where few ports are in use, as the tests' domains do)
MAX_DOMAIN_ID = 232
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
# the fingertip hub scans at 100 Hz (firmware HUB_RATE_HZ); a stream under half its rate is failing
MIN_RATE_SHARE = 0.5
# a pad reading all of its taxels at ~0 V has a dark LED or an unpowered ADC; at ~vref it is saturated
DARK_V = 0.01
SATURATED_SHARE = 0.99
# operating modes the motor driver uses (velocity goals, position goals, homing)
DRIVER_MODES = ("velocity", "extended_position", "current_based_position", "position")
# a lost status packet now and then is normal on a loaded host; more than this share of the reads is a bus problem
MAX_RETRY_SHARE = 0.01
HOME_ACTION = "prisma/motors/home"
CAP_SYS_NICE = 23

OK_, WARN_, FAIL_, SKIP_ = "OK", "WARN", "FAIL", "SKIP"


@dataclass(frozen=True)
class CheckResult:
    name: str
    ok: bool
    found: str  # what was found; for a failure, what is wrong
    fix: str = ""  # how to fix it (failures and warnings)
    level: str = ""  # OK, WARN, FAIL or SKIP; "" = OK or FAIL from `ok`

    @property
    def status(self) -> str:
        return self.level or (OK_ if self.ok else FAIL_)

    def line(self) -> str:
        text = f"{self.status} {self.name}: {self.found}"
        return f"{text} -> {self.fix}" if self.fix else text


def passed(name: str, found: str) -> CheckResult:
    return CheckResult(name, True, found)


def failed(name: str, found: str, fix: str) -> CheckResult:
    return CheckResult(name, False, found, fix)


def warned(name: str, found: str, fix: str) -> CheckResult:
    return CheckResult(name, True, found, fix, WARN_)


def skipped(name: str, why: str) -> CheckResult:
    return CheckResult(name, True, f"not checked: {why}", "", SKIP_)


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

    @property
    def rate_hz(self) -> float:
        return self.messages / self.seconds if self.seconds > 0 else 0.0


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
    user = _user_name()
    return PortFacts(path, True, os.access(path, os.R_OK | os.W_OK), group, info.st_gid in os.getgroups()
                     or info.st_gid == os.getegid(), user in members, stat.S_ISCHR(info.st_mode))


def _user_name() -> str:
    import pwd

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


# ---- helpers ---------------------------------------------------------------------------------
def node_path(namespace: str, node: str) -> str:
    ns = namespace.strip("/")
    return f"/{ns}/{node}" if ns else f"/{node}"


def _status(facts: HandFacts, name: str) -> DiagnosticStatusData | None:
    for status in facts.diagnostics:
        if status.name == name:
            return status
    return None


def _param(params: Mapping[str, Any] | None, name: str, default: Any = None) -> Any:
    return default if params is None else params.get(name, default)


def _launch_hint(facts: HandFacts) -> str:
    ns = facts.namespace.strip("/")
    domain = facts.env.get("ROS_DOMAIN_ID", "") or "unset (0)"
    return (f"start the hand (ros2 launch prisma_bringup hand.launch.py{' namespace:=' + ns if ns else ''}), "
            f"or run the doctor with the ROS_DOMAIN_ID of the shell that launched it (this one: {domain})")


# ---- the checks ------------------------------------------------------------------------------
def check_domain(facts: HandFacts) -> CheckResult:
    name = "ros domain"
    text = facts.env.get("ROS_DOMAIN_ID", "").strip()
    if text:
        try:
            domain = int(text)
        except ValueError:
            return failed(name, f"ROS_DOMAIN_ID={text!r} is not a number",
                          "export ROS_DOMAIN_ID=<0-101>, the same in every shell of the hand")
        if not 0 <= domain <= MAX_DOMAIN_ID:
            return failed(name, f"ROS_DOMAIN_ID={domain} is outside 0-{MAX_DOMAIN_ID} (no DDS ports for it)",
                          "export ROS_DOMAIN_ID=<0-101>, the same in every shell of the hand")
    discovery = facts.env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() or "SUBNET"
    if discovery not in DISCOVERY_RANGES:
        return failed(name, f"ROS_AUTOMATIC_DISCOVERY_RANGE={discovery!r} is not one of {', '.join(DISCOVERY_RANGES)}",
                      "unset it or export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET")
    if discovery == "OFF":
        return failed(name, "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: no node finds another",
                      "unset it or export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (LOCALHOST: this computer only)")
    domain_text = text or "unset (0)"
    found = f"ROS_DOMAIN_ID {domain_text}, discovery {discovery}, {len(facts.nodes)} node(s) seen"
    if not facts.nodes:
        return failed(name, found, _launch_hint(facts))
    return passed(name, found)


def check_node(facts: HandFacts, node: str) -> CheckResult:
    path = node_path(facts.namespace, node)
    name = f"node {node}"
    count = sum(1 for n in facts.nodes if n == path)
    if count == 1:
        return passed(name, f"{path} running once")
    if count == 0:
        others = sorted({n for n in facts.nodes if n.rsplit("/", 1)[-1] == node})
        where = f" (running as {', '.join(others)}: --namespace)" if others else ""
        return failed(name, f"{path} not running{where}", _launch_hint(facts))
    return failed(name, f"{count} nodes named {path}: their goals, topics and parameters mix",
                  "stop the extra one (a second launch of the hand or a node started by hand: `ros2 node list`, "
                  "then stop that launch); a second hand needs its own namespace:=")


def check_realtime(facts: HandFacts, rt_priority: int = DEFAULT_RT_PRIORITY) -> CheckResult:
    name = "realtime"
    soft, hard = facts.rtprio
    if facts.rt_capable:
        return passed(name, f"SCHED_FIFO {rt_priority} permitted (root or CAP_SYS_NICE)")
    if soft < 0 or soft >= rt_priority:
        return passed(name, f"RLIMIT_RTPRIO {soft if soft >= 0 else 'unlimited'} allows SCHED_FIFO {rt_priority}")
    raise_soft = f" (the hard limit {hard} allows it: `ulimit -r {rt_priority}` in the launching shell)" \
        if hard < 0 or hard >= rt_priority else ""
    return failed(name, f"RLIMIT_RTPRIO {soft}: the nodes cannot run at SCHED_FIFO {rt_priority} and fall back to "
                  f"nice{raise_soft}",
                  f"add the line `{_user_name()} - rtprio {rt_priority}` to /etc/security/limits.conf, then log "
                  "in again (README, 'On the robot')")


def _ports_used(facts: HandFacts) -> dict[str, str]:
    """role -> port of the drivers on serial links (none for sim or i2c backends)."""
    ports = {}
    if _param(facts.motor_params, "backend") == "dynamixel":
        ports["servos"] = str(_param(facts.motor_params, "port", ""))
    if _param(facts.tactile_params, "backend") == "serial":
        ports["hub"] = str(_param(facts.tactile_params, "port", ""))
    return ports


def check_port(facts: HandFacts, role: str) -> CheckResult:
    name = f"port {role}"
    driver = "motor_driver" if role == "servos" else "tactile_driver"
    params = facts.motor_params if role == "servos" else facts.tactile_params
    if params is None:
        return skipped(name, f"no parameters from {node_path(facts.namespace, driver)} (see node {driver})")
    port = _ports_used(facts).get(role)
    if port is None:
        return passed(name, f"{driver} backend {_param(params, 'backend')}: no serial port")
    info = facts.ports.get(role) or PortFacts(port, False)
    if not info.exists:
        if role == "hub":
            # a hub that is down is the hub line's failure: its fix is the cable, not the port
            return skipped(name, f"{port} absent (see hub)")
        return failed(name, f"{port} does not exist", "plug the U2D2 in (`ls -l /dev/serial/by-id/`) and set "
                      "motor_driver's port (motor_port:= of hand.launch.py) to it")
    if not info.writable:
        if info.group and not info.in_group:
            again = " (already listed: log out and in again)" if info.group_listed else ""
            return failed(name, f"{port} is not writable: owned by group {info.group}, which this user lacks{again}",
                          f"sudo usermod -aG {info.group} $USER, then log out and in")
        return failed(name, f"{port} is not readable and writable by this user",
                      f"check its permissions (`ls -l {port}`): the udev rule or `sudo chmod g+rw {port}`")
    return passed(name, f"{port} present and writable")


def check_udev(facts: HandFacts) -> CheckResult:
    name = "udev rule"
    missing = [rule for rule in UDEV_RULES if rule not in facts.udev_installed]
    usb_ports = [p for p in _ports_used(facts).values() if p.startswith("/dev/")]
    if not missing:
        return passed(name, ", ".join(facts.udev_installed.values()))
    if not usb_ports:
        return passed(name, f"{', '.join(missing)} not installed; not needed: no port under /dev")
    return failed(name, f"{', '.join(missing)} not installed (FTDI latency 16 ms: the hub's frames arrive in bursts)",
                  "sudo cp $(ros2 pkg prefix prisma_bringup)/share/prisma_bringup/config/udev/99-prisma-hub.rules "
                  "/etc/udev/rules.d/ && sudo udevadm control --reload-rules && "
                  "sudo udevadm trigger --action=add --subsystem-match=tty")


def check_hub(facts: HandFacts) -> CheckResult:
    name = "hub"
    if facts.tactile_params is None:
        return skipped(name, "tactile_driver not answering (see node tactile_driver)")
    backend = _param(facts.tactile_params, "backend", "?")
    status = _status(facts, "tactile_driver: hub")
    if status is None:
        return failed(name, f"no /diagnostics from tactile_driver ({backend}) in {facts.sample_seconds:g} s",
                      "a longer --timeout on a loaded computer; else the node is stuck: see its log")
    link_error = status.values.get("last_error", "") if status.level == ERROR else ""
    if status.level == ERROR:
        port = _param(facts.tactile_params, "port", "")
        fix = (f"plug the hub's USB cable in and check that it enumerates as {port} (`ls -l /dev/serial/by-id/`); "
               "the driver reconnects by itself" if backend == "serial"
               else "check the pads' wiring and power (the driver reconnects by itself)")
        return failed(name, f"{backend} link down: {status.message}" + (f" ({link_error})" if link_error and
                                                                          link_error not in status.message else ""),
                      fix)
    frames = status.values.get("frames", "?")
    if backend == "serial":
        # the hub's frames carry the protocol version (1) and no firmware version: a frame that parses
        # is from firmware speaking protocol 1
        version = "firmware version not reported by the hub (its frames carry protocol version 1, and they parse)"
        return passed(name, f"serial {_param(facts.tactile_params, 'port', '')}, {frames} frames; {version}")
    return passed(name, f"{backend} link up ({status.message})")


def check_fingertip(facts: HandFacts, finger: str) -> CheckResult:
    name = f"fingertip {finger}"
    if facts.tactile_params is None:
        return skipped(name, "tactile_driver not answering (see node tactile_driver)")
    fingers = _param(facts.tactile_params, "fingers", list(FINGERS))
    if finger not in fingers:
        return warned(name, "not on this hub (tactile_driver's fingers)", "add it to fingers if the hand has it")
    hub = _status(facts, "tactile_driver: hub")
    if hub is not None and hub.level == ERROR:
        return skipped(name, "the hub link is down (see hub)")
    sample = facts.taxels.get(finger, TaxelSample(0, facts.sample_seconds))
    backend = _param(facts.tactile_params, "backend", "sim")
    expected = 100.0 if backend == "serial" else float(_param(facts.tactile_params, "rate_hz", 100.0))
    vref = float(_param(facts.tactile_params, "vref", 3.3))
    topic = node_path(facts.namespace, f"prisma/{finger}/taxels")
    if sample.messages == 0:
        return failed(name, f"nothing on {topic} in {sample.seconds:.1f} s",
                      f"check the {finger} pad's cable to the hub and its mux channel; the hub leaves an absent "
                      "pad out of its finger mask")
    if sample.rate_hz < MIN_RATE_SHARE * expected:
        return failed(name, f"{sample.rate_hz:.0f} Hz on {topic}, expected ~{expected:.0f} Hz",
                      "the hub or the driver falls behind: check the udev rule (latency timer), the CPU load, "
                      "the realtime line")
    found = f"{sample.rate_hz:.0f} Hz, {sample.min_v:.2f}-{sample.max_v:.2f} V"
    if sample.max_v < DARK_V:
        return failed(name, f"{found}: every taxel at 0 V (dark LEDs or an unpowered ADC)",
                      f"check the {finger} pad's supply and its cable")
    if sample.min_v >= SATURATED_SHARE * vref:
        return failed(name, f"{found}: every taxel at vref {vref:g} V (saturated)",
                      f"check the {finger} pad for light leaking in, a short, or vref ({vref:g} V)")
    if sample.min_v < 0 or sample.max_v > vref:
        return failed(name, f"{found}: outside 0-{vref:g} V", "check tactile_driver's vref parameter")
    return passed(name, found)


# a bus error naming the motor it happened at (the ping at open, a sync read after)
_MOTOR_IN_ERROR = re.compile(r"\b(" + "|".join(map(re.escape, MOTOR_NAMES)) + r") \(id (\d+)\)")


def _bus_down_motor(status: DiagnosticStatusData | None) -> str | None:
    """The motor that a disconnected bus's reason names, if any."""
    if status is None or status.level != ERROR or not status.message.startswith("disconnected:"):
        return None
    match = _MOTOR_IN_ERROR.search(status.message)
    return match.group(1) if match else None


def check_motor_bus(facts: HandFacts) -> CheckResult:
    name = "motor bus"
    if facts.motor_params is None:
        return skipped(name, "motor_driver not answering (see node motor_driver)")
    status = _status(facts, "motor_driver: bus")
    backend = _param(facts.motor_params, "backend", "?")
    port = _param(facts.motor_params, "port", "")
    baud = _param(facts.motor_params, "baud", "?")
    if status is None:
        return failed(name, f"no /diagnostics from motor_driver ({backend}) in {facts.sample_seconds:g} s",
                      "a longer --timeout on a loaded computer; else the node is stuck: see its log")
    motor = _bus_down_motor(status)
    if motor is not None:
        return skipped(name, f"down because a servo does not answer (see servo {motor})")
    if status.level == ERROR and status.message.startswith("disconnected:"):
        reason = status.message.removeprefix("disconnected:").strip()
        info = facts.ports.get("servos")
        if info is not None and (not info.exists or not info.writable):
            return skipped(name, f"down: {reason} (see port servos)")
        if "cannot open" in reason:
            fix = f"check the U2D2's cable and motor_driver's port ({port}); see the port servos line"
        elif "baud rate" in reason:
            fix = f"set motor_driver's baud to one the adapter supports ({', '.join(map(str, ct.BAUD_RATES.values()))})"
        else:
            fix = (f"check the servos' power (12 V) and the bus cable; every servo must answer at {baud} baud "
                   f"(Dynamixel Wizard 2 scan)")
        return failed(name, f"down: {reason}", fix)
    where = f"{port} at {baud} baud" if backend == "dynamixel" else "sim motors"
    found = f"{backend}, {where}, {status.values.get('reads', '?')} reads"
    if status.level == ERROR:
        return passed(name, f"{found}; a servo faulted (see its line)")
    retries, reads = _int(status.values.get("retries")), _int(status.values.get("reads"))
    if retries > MAX_RETRY_SHARE * max(reads, 1):
        return warned(name, f"{found}, {retries} retries: {status.message}",
                      "check the bus cable and its termination; a retry costs a control cycle")
    return passed(name, found + (f", {retries} retries" if retries else ""))


def _int(text: str | None) -> int:
    try:
        return int(text or 0)
    except ValueError:
        return 0


def _ids(facts: HandFacts) -> dict[str, int]:
    names = _param(facts.motor_params, "motor_names", list(MOTOR_NAMES))
    ids = _param(facts.motor_params, "motor_ids", [1, 2, 3])
    return {str(n): int(i) for n, i in zip(names, ids)}


def _as_bool(text: str) -> bool:
    return text.strip().lower() in ("true", "1", "yes")


def check_servo(facts: HandFacts, motor: str) -> CheckResult:
    name = f"servo {motor}"
    if facts.motor_params is None:
        return skipped(name, "motor_driver not answering (see node motor_driver)")
    ids = _ids(facts)
    if motor not in ids:
        return warned(name, "not in motor_driver's motor_names", "add it if the hand has it")
    servo_id = ids[motor]
    baud = _param(facts.motor_params, "baud", "?")
    backend = _param(facts.motor_params, "backend", "?")
    bus = _status(facts, "motor_driver: bus")
    if bus is None:
        return skipped(name, "no /diagnostics from motor_driver (see motor bus)")
    down_at = _bus_down_motor(bus)
    if down_at == motor:
        reason = bus.message.removeprefix("disconnected:").strip()
        return failed(name, f"id {servo_id} does not answer at {baud} baud ({reason})",
                      f"check its cable and power; if it answers on another ID or baud (Dynamixel Wizard 2 scan) "
                      f"set its ID to {servo_id} and its baud to {baud}, or motor_driver's motor_ids/baud to its own")
    if bus.level == ERROR and bus.message.startswith("disconnected:"):
        return skipped(name, "the motor bus is down (see motor bus)" if down_at is None
                       else f"the bus stopped at servo {down_at} (see its line)")
    status = _status(facts, f"motor_driver: {motor}")
    if status is None:
        return failed(name, f"no /diagnostics status for {motor}", "update the motor driver; see its log")
    v = status.values
    if v.get("id") not in (None, str(servo_id)):
        return failed(name, f"diagnostics report id {v.get('id')}, motor_ids says {servo_id}",
                      "restart the motor driver with the intended motor_ids")
    if "hardware_error" in v and v["hardware_error"] not in ("", "0"):
        bits = int(v["hardware_error"])
        return failed(name, f"hardware error {ct.describe_hardware_error(bits)}",
                      "remove the cause (load, heat, supply voltage), then power-cycle the servo: only a reboot "
                      "clears Hardware Error Status")
    if status.level == ERROR:
        return failed(name, status.message, "remove the cause, then power-cycle the servo (clears its hardware error)")
    if backend != "dynamixel":
        return passed(name, f"id {servo_id}, {backend} motor")
    found = [f"id {servo_id}"]
    missing = []
    model = v.get("model")
    if model is None:
        missing.append("model")
    elif model != str(ct.MODEL_XM430_W350):
        return failed(name, f"model {model} at id {servo_id}, the hand is built with XM430-W350 "
                      f"({ct.MODEL_XM430_W350})", f"fit an XM430-W350 or check that id {servo_id} is this motor")
    else:
        found.append("XM430-W350")
    firmware = v.get("firmware")
    if firmware is None:
        missing.append("firmware")
    else:
        try:
            version = int(firmware)
        except ValueError:
            version = -1
        if version < ct.WATCHDOG_MIN_FIRMWARE:
            return failed(name, f"firmware {firmware}: the Bus Watchdog needs {ct.WATCHDOG_MIN_FIRMWARE} or later",
                          "update its firmware with Dynamixel Wizard 2 (Firmware Update)")
        found.append(f"firmware {version}")
    found.append(f"{baud} baud")
    mode = v.get("operating_mode")
    if mode is None:
        missing.append("operating_mode")
    elif mode not in DRIVER_MODES:
        return failed(name, f"operating mode {mode}: the driver sets {', '.join(DRIVER_MODES)}",
                      "restart the motor driver (it sets the mode at start); another tool on the bus changed it")
    else:
        found.append(f"{mode} mode")
    if "watchdog_fired" in v and _as_bool(v["watchdog_fired"]):
        return failed(name, "its Bus Watchdog fired (the driver went silent) and it holds its goals",
                      "restart the motor driver, which clears and rearms it")
    watchdog = v.get("watchdog_ms")
    if watchdog is None:
        missing.append("watchdog_ms")
    elif watchdog in ("", "0"):
        return failed(name, "Bus Watchdog off: a stalled driver leaves the servo running",
                      f"the motor driver arms it at start: update prisma_motor_driver and the servo's firmware "
                      f"(>= {ct.WATCHDOG_MIN_FIRMWARE})")
    else:
        found.append(f"watchdog {watchdog} ms")
    homed = v.get("homed")
    if homed is None:
        missing.append("homed")
    elif not _as_bool(homed):
        home = node_path(facts.namespace, HOME_ACTION)
        return failed(name, "not homed since power-up: the driver will not move it",
                      f"home it: ros2 action send_goal {home} prisma_msgs/action/HomeMotors \"{{motors: [{motor}]}}\"")
    else:
        found.append("homed")
    if "hardware_error" not in v:
        missing.append("hardware_error")
    if missing:
        return warned(name, ", ".join(found) + f"; not reported by this motor driver: {', '.join(missing)}",
                      "update prisma_motor_driver (its /diagnostics report them)")
    return passed(name, ", ".join(found) + ", no hardware error")


def check_bundles(facts: HandFacts) -> CheckResult:
    name = "bundles"
    if facts.force_params is None:
        return skipped(name, "force_estimator not answering (see node force_estimator); a bundle that does "
                             "not load stops it at start: its log says why")
    fingers = _param(facts.force_params, "fingers", list(FINGERS))
    statuses = {f: _status(facts, f"force_estimator: {f}") for f in fingers}
    absent = [f for f, s in statuses.items() if s is None]
    if absent:
        return failed(name, f"no /diagnostics from force_estimator for {', '.join(absent)}",
                      "a longer --timeout on a loaded computer; else see the force_estimator's log")
    kinds = sorted({s.values.get("model_kind", "?") for s in statuses.values() if s is not None})
    paths = sorted({s.hardware_id for s in statuses.values() if s is not None and s.hardware_id})
    rejected = [f for f, s in statuses.items() if s is not None and s.level != OK]
    found = f"{len(fingers)} finger(s), {'/'.join(kinds)} from {', '.join(paths) or '?'}"
    if rejected:
        return warned(name, f"{found}; rejected samples on {', '.join(rejected)}",
                      "non-finite voltages reached the estimator: see the fingertip lines")
    return passed(name, found)


def run_checks(facts: HandFacts) -> list[CheckResult]:
    """Every check, in the order a bring-up goes: the computer, the graph, the links, the devices."""
    return [
        check_domain(facts),
        *(check_node(facts, node) for node in HAND_NODES),
        check_realtime(facts),
        check_udev(facts),
        check_port(facts, "servos"),
        check_port(facts, "hub"),
        check_hub(facts),
        *(check_fingertip(facts, finger) for finger in FINGERS),
        check_motor_bus(facts),
        *(check_servo(facts, motor) for motor in MOTOR_NAMES),
        check_bundles(facts),
    ]


def exit_status(results: Iterable[CheckResult]) -> int:
    return 1 if any(r.status == FAIL_ for r in results) else 0
