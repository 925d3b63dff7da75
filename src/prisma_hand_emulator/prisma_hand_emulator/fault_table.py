"""The emulator's fault commands, in one table (FAULTS) that both ends read: the control socket's
dispatch (`fault_values`: the command known, its tactile link the hand's, its defaults filled in and
its values checked, before EmulatedHand runs its `_fault_<name>`) and prisma-hand-fault, which builds
a subcommand per entry."""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from prisma_common.cli_args import non_negative_float, non_negative_int, positive_int
from prisma_common.control_socket import REPLACE_OBJECT
from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_motor_driver import control_table as ct

from .settings import WORLDS

REQUIRED: Any = None  # a FaultArg without a default: the command needs it


@dataclass(frozen=True)
class FaultArg:
    """One argument of a fault command: the control request's key and prisma-hand-fault's option
    (`dx_mm` -> `--dx-mm`; a positional one keeps its name)."""
    name: str
    type: Callable[[str], Any]  # the CLI's parser of the text; it also picks the emulator's check
    help: str
    default: Any = REQUIRED
    positional: bool = False

    @property
    def flag(self) -> str:
        return self.name if self.positional else "--" + self.name.replace("_", "-")


@dataclass(frozen=True)
class Fault:
    """A command of the control socket: what it does, its arguments and the tactile link it needs
    (None: any). EmulatedHand.apply dispatches on this table to `_fault_<name>`; prisma-hand-fault
    builds its subcommands from it."""
    help: str
    args: tuple[FaultArg, ...] = ()
    link: str | None = None


ON_OFF = ("on", "off")


def on_off(text: str) -> str:
    """`on` or `off` (the CLI's parser; the socket's values are checked the same way)."""
    if text not in ON_OFF:
        raise argparse.ArgumentTypeError(f"{text!r}: say on or off")
    return text


def _one_of(names: tuple[str, ...]) -> str:
    return ", ".join(names[:-1]) + " or " + names[-1]


_FINGER = FaultArg("finger", str, _one_of(FINGERS))
_MOTOR = FaultArg("motor", str, _one_of(MOTOR_NAMES))
_ONE_MOTOR = FaultArg("motor", str, "one motor (default: all)", "")
FAULTS: dict[str, Fault] = {
    "status": Fault("what the emulated hardware is doing (JSON)"),
    "hub-unplug": Fault("unplug the fingertip hub's USB cable (tactile link serial)", (
        FaultArg("seconds", non_negative_float, "plug it back after this long (0 = at hub-replug)", 0.0),),
        link="serial"),
    "hub-replug": Fault("plug the hub back in (a new pty behind the same link; tactile link serial)", link="serial"),
    "hub-garbage": Fault("write garbage bytes on the hub link before the next frame (tactile link serial)", (
        FaultArg("bytes", positive_int, "how many"),), link="serial"),
    "hub-crc": Fault("corrupt the CRC of the next hub frames (tactile link serial)", (
        FaultArg("frames", positive_int, "how many"),), link="serial"),
    "i2c-nack": Fault("a finger's ADC stops acknowledging on the I2C bus (tactile link i2c)", (
        _FINGER,
        FaultArg("count", non_negative_int, "this many addressings, then it recovers (0 = until i2c-clear)", 0)),
        link="i2c"),
    "i2c-glitch": Fault("a finger's next I2C reads return all-zero bytes (tactile link i2c)", (
        _FINGER, FaultArg("count", positive_int, "how many")), link="i2c"),
    "i2c-clear": Fault("every ADC answers again (tactile link i2c)", link="i2c"),
    "servo-error": Fault("set a Hardware Error Status bit on a servo", (
        _MOTOR, FaultArg("bit", str, "0-7 or " + ", ".join(ct.HARDWARE_ERROR_BITS.values())))),
    "servo-silent": Fault("a servo stops answering (off the bus)", (
        _MOTOR, FaultArg("seconds", non_negative_float, "back after this long (0 = at servo-clear)", 0.0))),
    "servo-clear": Fault("hardware error bits cleared and servos answering again (no power cycle)", (_ONE_MOTOR,)),
    "power-cycle": Fault("switch servos off and on: torque off, RAM (LED, bus watchdog, goals) reset, the position "
                         "reported within one turn again; the hand keeps its pose", (_ONE_MOTOR,)),
    "servo-baud": Fault("a servo configured at another baud rate (by another tool): silent at the driver's", (
        _MOTOR, FaultArg("rate", positive_int, "its baud rate (1000000 restores it)"))),
    "servo-place": Fault("turn a motor by hand to an angle (rad of its shaft, between its end stops)", (
        _MOTOR, FaultArg("rad", float, "the angle (rad)"))),
    "push": Fault("push the object across the pads / to a narrower section", (
        FaultArg("dx_mm", float, "slip toward the thumb pad's left side (mm)", 0.0),
        FaultArg("dy_mm", float, "slip toward the thumb pad's top row (mm)", 0.0),
        FaultArg("dwidth_mm", float, "change of the grip width (mm, negative = narrower)", 0.0),
        FaultArg("duration_s", non_negative_float, "over this long (s)", 0.3))),
    "world": Fault("place another object: the hand is posed as that world starts", (
        FaultArg("name", str, ", ".join(WORLDS), positional=True),
        FaultArg("pushes", on_off, "the world's timed pushes: on, as its scenario times them from now, or off "
                 "(then `push` them when you want them, e.g. once a goal runs)", "on"))),
    # the sim hand's ~/replace_object, carried out by the emulator's world (the emulated hand's
    # tactile_driver forwards its ~/replace_object here)
    REPLACE_OBJECT: Fault("put the object the hand let go (it fell) back between the open fingers, as between "
                          "trials; refused while a finger touches it (open the hand first)"),
}
# Each motor's mechanical end stops (rad of the motor shaft from its zero): the open end is its


class FaultError(ValueError):
    """A fault command that names something the emulator does not have; the message says what."""


LINK_NAMES = {"serial": "fingertip hub's serial link", "i2c": "host's I2C bus"}


def fault_values(command: str, args: dict[str, Any], tactile_link: str) -> dict[str, Any]:
    """The arguments `command` runs with on a hand wired with `tactile_link`: the table's defaults
    under `args`, each value checked as the CLI would (the socket takes any JSON). FaultError for an
    unknown command (`status` is a request, not a fault), a fault of the other tactile link (with the
    reason and how to get that link) or a value out of range, naming it."""
    fault = FAULTS.get(command)
    if fault is None or command == "status":
        raise FaultError(f"unknown command {command!r}")
    if fault.link is not None and fault.link != tactile_link:
        raise FaultError(f"{command}: the pads are on the {LINK_NAMES[tactile_link]} here "
                         f"(tactile link {tactile_link}), which has no such fault; it needs the "
                         f"{LINK_NAMES[fault.link]} (prisma-hand-emulator --tactile-link {fault.link}, "
                         f"hand.launch.py tactile_backend:={fault.link})")
    values = {a.name: a.default for a in fault.args if a.default is not REQUIRED} | args
    for arg in fault.args:
        check = _VALUE_CHECKS.get(arg.type)
        if check is not None and arg.name in values:
            check(arg.name, values[arg.name])
    return values


def _check_on_off(name: str, value: Any) -> None:
    if value not in ON_OFF:
        raise FaultError(f"{name} {value!r}: must be on or off")


def _check_positive(name: str, value: Any) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
        raise FaultError(f"{name} {value!r}: must be a number > 0")


def _check_non_negative(name: str, value: Any) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not value >= 0 or not math.isfinite(value):
        raise FaultError(f"{name} {value!r}: must be a number >= 0")


# a FaultArg's CLI type -> the emulator's check of a value that came over the socket
_VALUE_CHECKS: dict[Callable[[str], Any], Callable[[str, Any], None]] = {
    positive_int: _check_positive, non_negative_int: _check_non_negative, non_negative_float: _check_non_negative,
    on_off: _check_on_off}
