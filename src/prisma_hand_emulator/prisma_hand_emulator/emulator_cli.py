"""prisma-hand-emulator and prisma-hand-fault: the hand's hardware emulated, and faults injected into it.

    prisma-hand-emulator                          # devices in /tmp/prisma_hand_emulator
    prisma-hand-emulator --dir /tmp/left --world horizontal --tactile-link i2c
    prisma-hand-fault hub-unplug --seconds 1      # another shell, while it runs
    prisma-hand-fault servo-error --motor fingers --bit overload
    prisma-hand-fault status
    prisma-hand-fault replace-object              # the ball the hand let go back between the fingers

`ros2 launch prisma_bringup hand.launch.py hardware:=emulated` starts the emulator with the drivers
on its devices; prisma-hand-fault reaches it with the same --dir (`emulator_dir:=` of the launch).
"""
from __future__ import annotations

import argparse
import json
import signal
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    command,
    non_negative_float,
    non_negative_int,
    positive_float,
)
from prisma_common.control_socket import reply_text, send
from prisma_common.scheduling import apply_priority_from_env
from prisma_motor_driver.dynamixel_emulator import stderr_log

from .fault_table import FAULTS, REQUIRED
from .hand_emulator import EmulatedHand
from .settings import DEFAULT_DIR, DEFAULT_WORLD, TACTILE_LINKS, WORLDS, EmulatorPaths, EmulatorSettings


@command("prisma-hand-emulator")
def emulator_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-hand-emulator", description=__doc__.splitlines()[0],
                            formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_devices_help())
    parser.add_argument("--dir", type=Path, default=DEFAULT_DIR,
                        help=f"where the devices appear (default {DEFAULT_DIR}); created if missing")
    parser.add_argument("--rate", type=positive_float, default=100.0, help="hub scans per second (default 100)")
    parser.add_argument("--world", choices=WORLDS, default=DEFAULT_WORLD,
                        help="object and pose, as hand.launch.py sim_object:= names them: an object "
                             "presented to the open hand (pinch_ball = a foam ball let go once held, as "
                             "sim:=true; none = an empty hand) or a prisma-sim scenario's start "
                             f"(default {DEFAULT_WORLD})")
    parser.add_argument("--tactile-link", choices=TACTILE_LINKS, default="serial",
                        help="how the pads reach the host, as tactile_driver's backend: serial = the "
                             "fingertip hub on <dir>/hub, i2c = the pads' bus on <dir>/i2c.sock (default "
                             "serial); faults of the other link are refused")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="pad noise seed")
    parser.add_argument("--seconds", type=non_negative_float, default=0.0,
                        help="stop after this long (0 = until Ctrl-C or SIGTERM)")
    parser.add_argument("--linger", type=non_negative_float, default=1.0,
                        help="after Ctrl-C or SIGTERM keep the devices up this long (default 1 s): drivers "
                             "shut down with it still turn their torque off; a second signal stops at once")
    args = parser.parse_args(argv)
    try:  # the emulated hardware is on the control path too (hand.launch.py hardware:=emulated)
        scheduling = apply_priority_from_env()
    except ValueError as exc:
        raise UserError(str(exc)) from None

    try:
        if args.dir.exists() and not args.dir.is_dir():
            raise UserError(f"--dir {args.dir} is not a directory; choose another path")
    except OSError as exc:  # a path that cannot even be looked at: a name too long, a loop of links
        raise UserError(f"--dir {args.dir}: {exc.strerror or exc}; choose another path") from None
    paths = EmulatorPaths(args.dir.absolute())  # the drivers, started elsewhere, need whole paths
    hand = EmulatedHand(paths, EmulatorSettings(rate_hz=args.rate, world=args.world, seed=args.seed,
                                                tactile_link=args.tactile_link), log=stderr_log)
    stop = threading.Event()
    signals: list[int] = []

    def on_signal(number: int, _frame: Any) -> None:
        signals.append(number)
        if len(signals) > 1 or not args.linger:
            stop.set()
        else:
            _later(args.linger, stop.set)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    if args.seconds:
        _later(args.seconds, stop.set)
    try:
        hand.start()
    except FileExistsError as exc:  # something that is not an emulator's at one of the paths
        raise UserError(f"--dir {args.dir}: {exc}") from None
    except OSError as exc:  # no permission to create the directory or a device there
        raise UserError(f"--dir {args.dir}: {exc.strerror or exc}; choose another path") from None
    try:
        pads = f"hub {paths.hub}" if args.tactile_link == "serial" else f"i2c {paths.i2c}"
        print(f"emulated hand ({args.world}, {args.rate:g} Hz): servos {paths.servos}, {pads}, "
              f"control {paths.control}" + (f"; {scheduling}" if scheduling else ""), flush=True)
        ticks = hand.run(stop)
    finally:
        hand.close()
    print(f"emulated hand stopped after {ticks} scans", flush=True)
    return 0


def _later(seconds: float, action: Callable[[], None]) -> None:
    timer = threading.Timer(seconds, action)
    timer.daemon = True  # the run may end sooner
    timer.start()


def _devices_help() -> str:
    return ("devices in --dir: servos (pty, motor_driver port), hub (pty, tactile_driver port; --tactile-link "
            "serial) or i2c.sock (tactile_driver i2c_socket; --tactile-link i2c), control.sock (prisma-hand-fault)")


def fault_parser() -> ArgumentParser:
    """prisma-hand-fault's parser: a subcommand per entry of the emulator's FAULTS table."""
    parser = ArgumentParser(prog="prisma-hand-fault", description="Inject a fault into the running emulated hand")
    parser.add_argument("--dir", type=Path, default=DEFAULT_DIR,
                        help=f"the emulator's --dir (default {DEFAULT_DIR})")
    commands = parser.add_subparsers(dest="command", required=True, metavar="command",
                                     parser_class=ArgumentParser)
    for name, fault in FAULTS.items():
        sub = commands.add_parser(name, help=fault.help, description=fault.help)
        for arg in fault.args:
            if arg.positional:
                sub.add_argument(arg.flag, help=arg.help)
            elif arg.default is REQUIRED:
                sub.add_argument(arg.flag, type=arg.type, required=True, help=arg.help)
            else:
                sub.add_argument(arg.flag, type=arg.type, default=arg.default,
                                 help=f"{arg.help} (default {arg.default!r})")
    return parser


def fault_request(argv: list[str] | None = None) -> str:
    """What prisma-hand-fault prints for `argv` (its parser's errors exit as argparse's do); UserError
    for an emulator that cannot be reached or refuses. A test sends its faults through this in its own
    process: a process started per fault took seconds beside a control path at real-time priority."""
    args = fault_parser().parse_args(argv)
    values = {k: v for k, v in vars(args).items() if k not in ("dir", "command")}
    try:
        reply = send(EmulatorPaths(args.dir).control, args.command, values)
    except ConnectionError as exc:
        raise UserError(f"{exc}: {unreachable_hint(args.dir)}") from None
    except OSError as exc:
        raise UserError(str(exc)) from None
    if "status" in reply:
        return json.dumps(reply["status"], indent=2)
    ok, text = reply_text(reply)
    if not ok:
        raise UserError(text if text.startswith(f"{args.command}: ") else f"{args.command}: {text}")
    return text


def unreachable_hint(directory: Path) -> str:
    """How to reach the emulator prisma-hand-fault did not find in `directory`: the one a launch
    started is in its emulator_dir, or start one."""
    default = f" (default {DEFAULT_DIR})" if directory == DEFAULT_DIR else ""
    return (f"a hand launched with `hardware:=emulated emulator_dir:=DIR` is reached with `prisma-hand-fault "
            f"--dir DIR ...` (the launch's emulator_dir{default}); or start one here: "
            f"`prisma-hand-emulator --dir {directory}` or "
            f"`ros2 launch prisma_bringup hand.launch.py hardware:=emulated emulator_dir:={directory.absolute()}`")


@command("prisma-hand-fault")
def fault_main(argv: list[str] | None = None) -> int:
    print(fault_request(argv))
    return 0
