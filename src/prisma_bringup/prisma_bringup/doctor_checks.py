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

from prisma_common.diagnostics import ERROR, OK
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_common.scheduling import CONTROL_PATH_RT_PRIORITY

from .doctor_facts import (
    HAND_NODES,
    UDEV_RULES,
    HandFacts,
    PortFacts,
    TaxelSample,
    node_path,
    param,
    status_named,
    user_name,
)
from .doctor_motors import check_motor_bus, check_servo
from .doctor_result import CheckResult, failed, passed, skipped, warned

# the highest ROS_DOMAIN_ID whose DDS ports exist (0-101 is the range clear of Linux's ephemeral
# ports; above it works where few ports are in use, as the tests' domains do)
MAX_DOMAIN_ID = 232
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
# the fingertip hub scans at 100 Hz (firmware HUB_RATE_HZ); a stream under half its rate is failing
MIN_RATE_SHARE = 0.5
# a pad reading all of its taxels at ~0 V has a dark LED or an unpowered ADC; at ~vref it is saturated
DARK_V = 0.01
SATURATED_SHARE = 0.99


def _launch_hint(facts: HandFacts) -> str:
    ns = facts.namespace.strip("/")
    domain = facts.env.get("ROS_DOMAIN_ID", "") or "unset (0)"
    return (f"start the hand (ros2 launch prisma_bringup hand.launch.py{' namespace:=' + ns if ns else ''}), "
            f"or run the doctor with the ROS_DOMAIN_ID of the shell that launched it (this one: {domain})")


# ---- the checks ------------------------------------------------------------------------------
def _environment_failure(facts: HandFacts) -> CheckResult | None:
    """The domain line's failure when ROS_DOMAIN_ID or ROS_AUTOMATIC_DISCOVERY_RANGE cannot work."""
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
    discovery = _discovery(facts)
    if discovery not in DISCOVERY_RANGES:
        return failed(name, f"ROS_AUTOMATIC_DISCOVERY_RANGE={discovery!r} is not one of {', '.join(DISCOVERY_RANGES)}",
                      "unset it or export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET")
    if discovery == "OFF":
        return failed(name, "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: no node finds another",
                      "unset it or export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (LOCALHOST: this computer only)")
    return None


def _discovery(facts: HandFacts) -> str:
    return facts.env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() or "SUBNET"


def _domain_found(facts: HandFacts) -> str:
    domain_text = facts.env.get("ROS_DOMAIN_ID", "").strip() or "unset (0)"
    return f"ROS_DOMAIN_ID {domain_text}, discovery {_discovery(facts)}, {len(facts.nodes)} node(s) seen"


def check_domain(facts: HandFacts) -> CheckResult:
    bad = _environment_failure(facts)
    if bad is not None:
        return bad
    if not facts.nodes:
        return failed("ros domain", _domain_found(facts), _launch_hint(facts))
    return passed("ros domain", _domain_found(facts))


def check_hand_running(facts: HandFacts) -> CheckResult | None:
    """The one line when no node of the hand runs in the namespace (every other line would fail or
    skip for that one reason), else None: the ROS environment's failure where it is wrong (its fix
    first), else `FAIL hand: no hand running ...` with how to start one."""
    if any(node_path(facts.namespace, node) in facts.nodes for node in HAND_NODES):
        return None
    bad = _environment_failure(facts)
    if bad is not None:
        return bad
    where = f"namespace '{facts.namespace.strip('/')}'" if facts.namespace.strip("/") else "the root namespace"
    elsewhere = sorted({n.rsplit("/", 1)[0] or "/" for n in facts.nodes if n.rsplit("/", 1)[-1] in HAND_NODES})
    found = f"no hand running in {where} ({_domain_found(facts)})"
    if elsewhere:
        ns = elsewhere[0].strip("/")
        found += f"; a hand runs in {', '.join(elsewhere)}: " + (f"--namespace {ns}" if ns else "no --namespace")
    return failed("hand", found, _launch_hint(facts))


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


def check_realtime(facts: HandFacts, rt_priority: int = CONTROL_PATH_RT_PRIORITY) -> CheckResult:
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
                  f"add the line `{user_name()} - rtprio {rt_priority}` to /etc/security/limits.conf, then log "
                  "in again (docs/real_hand.md, 'Real-time limits')")


def _ports_used(facts: HandFacts) -> dict[str, str]:
    """role -> port of the drivers on serial links (none for sim or i2c backends)."""
    ports = {}
    if param(facts.motor_params, "backend") == "dynamixel":
        ports["servos"] = str(param(facts.motor_params, "port", ""))
    if param(facts.tactile_params, "backend") == "serial":
        ports["hub"] = str(param(facts.tactile_params, "port", ""))
    return ports


def check_port(facts: HandFacts, role: str) -> CheckResult:
    name = f"port {role}"
    driver = "motor_driver" if role == "servos" else "tactile_driver"
    params = facts.motor_params if role == "servos" else facts.tactile_params
    if params is None:
        return skipped(name, f"no parameters from {node_path(facts.namespace, driver)} (see node {driver})")
    port = _ports_used(facts).get(role)
    if port is None:
        return passed(name, f"{driver} backend {param(params, 'backend')}: no serial port")
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
    backend = param(facts.tactile_params, "backend", "?")
    status = status_named(facts, "tactile_driver: hub")
    if status is None:
        return failed(name, f"no /diagnostics from tactile_driver ({backend}) in {facts.sample_seconds:g} s",
                      "a longer --timeout on a loaded computer; else the node is stuck: see its log")
    link_error = status.values.get("last_error", "") if status.level == ERROR else ""
    if status.level == ERROR:
        port = param(facts.tactile_params, "port", "")
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
        return passed(name, f"serial {param(facts.tactile_params, 'port', '')}, {frames} frames; {version}")
    return passed(name, f"{backend} link up ({status.message})")


def check_fingertip(facts: HandFacts, finger: str) -> CheckResult:
    name = f"fingertip {finger}"
    if facts.tactile_params is None:
        return skipped(name, "tactile_driver not answering (see node tactile_driver)")
    fingers = param(facts.tactile_params, "fingers", list(FINGERS))
    if finger not in fingers:
        return warned(name, "not on this hub (tactile_driver's fingers)", "add it to fingers if the hand has it")
    hub = status_named(facts, "tactile_driver: hub")
    if hub is not None and hub.level == ERROR:
        return skipped(name, "the hub link is down (see hub)")
    sample = facts.taxels.get(finger, TaxelSample(0, facts.sample_seconds))
    backend = param(facts.tactile_params, "backend", "sim")
    expected = 100.0 if backend == "serial" else float(param(facts.tactile_params, "rate_hz", 100.0))
    vref = float(param(facts.tactile_params, "vref", 3.3))
    topic = node_path(facts.namespace, f"prisma/{finger}/taxels")
    publishers = list(facts.taxel_publishers.get(finger, ()))
    if len(publishers) > 1:
        # two drivers' samples interleave: their stamps and counters mix, so no rate or range is theirs
        count = "two" if len(publishers) == 2 else str(len(publishers))
        return failed(name, f"{count} publishers on {topic}: {', '.join(sorted(publishers))}",
                      "stop the extra one (a second launch of the hand, or a node started by hand: "
                      "`ros2 topic info -v " + topic + "`); a second hand needs its own namespace:=")
    if sample.messages == 0:
        return failed(name, f"nothing on {topic} in {sample.seconds:.1f} s",
                      f"check the {finger} pad's cable to the hub and its mux channel; the hub leaves an absent "
                      "pad out of its finger mask")
    if sample.driver_hz < MIN_RATE_SHARE * expected:
        return failed(name, f"{sample.driver_hz:.0f} Hz on {topic}, expected ~{expected:.0f} Hz",
                      "the hub or the driver falls behind: check the udev rule (latency timer), the CPU load, "
                      "the realtime line")
    found = f"{sample.driver_hz:.0f} Hz, {sample.min_v:.2f}-{sample.max_v:.2f} V"
    if sample.max_v < DARK_V:
        return failed(name, f"{found}: every taxel at 0 V (dark LEDs or an unpowered ADC)",
                      f"check the {finger} pad's supply and its cable")
    if sample.min_v >= SATURATED_SHARE * vref:
        return failed(name, f"{found}: every taxel at vref {vref:g} V (saturated)",
                      f"check the {finger} pad for light leaking in, a short, or vref ({vref:g} V)")
    if sample.min_v < 0 or sample.max_v > vref:
        return failed(name, f"{found}: outside 0-{vref:g} V", "check tactile_driver's vref parameter")
    if sample.rate_hz < MIN_RATE_SHARE * sample.driver_hz:
        # the driver keeps its rate; this process, starved, dropped messages of the best-effort topic
        found += f" (this check took in {sample.rate_hz:.0f} Hz of it: the computer is busy)"
    return passed(name, found)



def check_bundles(facts: HandFacts) -> CheckResult:
    name = "bundles"
    if facts.force_params is None:
        return skipped(name, "force_estimator not answering (see node force_estimator); a bundle that does "
                             "not load stops it at start: its log says why")
    fingers = param(facts.force_params, "fingers", list(FINGERS))
    statuses = {f: status_named(facts, f"force_estimator: {f}") for f in fingers}
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
    """Every check, in the order a bring-up goes: the computer, the graph, the links, the devices;
    one line when no hand runs at all."""
    nothing = check_hand_running(facts)
    if nothing is not None:
        return [nothing]
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


