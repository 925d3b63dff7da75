"""prisma-doctor's lines about the motors: the Dynamixel bus (`check_motor_bus`) and each servo
(`check_servo`: it answers, no hardware error, and, on the dynamixel backend, the model, firmware,
operating mode, Bus Watchdog and homing the driver needs). One fault, one failing line: a servo that
does not answer fails its own line, and the bus line, which it brought down, says SKIP."""
from __future__ import annotations

import re
from collections.abc import Mapping

from prisma_common.diagnostics import ERROR, DiagnosticStatusData
from prisma_common.hand import MOTOR_NAMES
from prisma_common.topics import HOME_MOTORS_ACTION
from prisma_motor_driver import control_table as ct

from .doctor_facts import HandFacts, node_path, param, status_named
from .doctor_result import CheckResult, failed, passed, skipped, warned

# operating modes the motor driver uses (velocity goals, position goals, homing)
DRIVER_MODES = ("velocity", "extended_position", "current_based_position", "position")
# a lost status packet now and then is normal on a loaded host; more than this share of the reads is a bus problem
MAX_RETRY_SHARE = 0.01


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
    status = status_named(facts, "motor_driver: bus")
    backend = param(facts.motor_params, "backend", "?")
    port = param(facts.motor_params, "port", "")
    baud = param(facts.motor_params, "baud", "?")
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
    names = param(facts.motor_params, "motor_names", list(MOTOR_NAMES))
    ids = param(facts.motor_params, "motor_ids", [1, 2, 3])
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
    baud = param(facts.motor_params, "baud", "?")
    backend = param(facts.motor_params, "backend", "?")
    bus = status_named(facts, "motor_driver: bus")
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
    status = status_named(facts, f"motor_driver: {motor}")
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
    home = node_path(facts.namespace, HOME_MOTORS_ACTION)
    return _check_servo_settings(name, v, servo_id, f"{baud} baud", home, motor)


def _check_servo_settings(name: str, v: Mapping[str, str], servo_id: int, baud: str, home: str,
                          motor: str) -> CheckResult:
    """A Dynamixel servo that answers without a fault: the model, firmware, operating mode, Bus
    Watchdog and homing its diagnostics `v` report against what the driver needs (`home`: the home
    action's name for the fix). A value this motor driver does not report yet is a WARN."""
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
    found.append(baud)
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
