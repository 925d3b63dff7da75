"""prisma-doctor: check a running hand's bring-up in one pass, one line per check.

    prisma-doctor                       # the hand of the default namespace
    prisma-doctor --namespace left      # one hand of a bimanual launch
    prisma-doctor --timeout 10          # a loaded computer: wait longer for the nodes

With no node of the hand running it says so in one line, `FAIL hand: no hand running ...` with how
to start one (or the ROS environment's failure, when that is the cause). Otherwise each line reads
`OK <check>: <what it found>`, `WARN <check>: <advisory> -> <what to do>`, `FAIL <check>: <what is
wrong> -> <how to fix it>` or `SKIP <check>: not checked: <why>` (another line failed first: fix that
one). The exit status is 1 when any line FAILs, else 0 (2 for a bad argument).

Checks, in order:
  ros domain          ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE are valid and nodes are seen
  node <name>         tactile_driver, motor_driver, force_estimator and manipulation each run exactly
                      once in the namespace (a duplicate fails)
  realtime            RLIMIT_RTPRIO (or root / CAP_SYS_NICE) allows the launch's SCHED_FIFO 20
  udev rule           config/udev/99-prisma-hub.rules installed in /etc/udev/rules.d or /lib/udev/rules.d
                      (needed where a port is under /dev)
  port servos|hub     the drivers' serial ports exist and this user may write them (dialout group)
  hub                 the tactile link is up (the hub reports no firmware version: its frames carry
                      protocol version 1, and a frame that parses is from firmware speaking it)
  fingertip <finger>  /prisma/<finger>/taxels streams at about its rate with voltages inside 0..vref, from
                      one publisher (two: a second hand's driver, named, their samples mixed)
  motor bus           the motor driver's bus is connected (a servo that does not answer fails its own line)
  servo <motor>       answers at its ID: model XM430-W350, firmware, operating mode, no hardware error,
                      Bus Watchdog armed and not fired, homed (WARN for what the driver does not report)
  bundles             the force estimator loaded a model bundle for every finger

Everything comes from the running drivers (their parameters, /diagnostics, the taxel topics, the ROS
graph) and from this computer; the doctor never opens a driver's port. With no hand running the one
line says so and the exit status is 1.
"""
from __future__ import annotations

import argparse

from prisma_common.cli_args import ArgumentParser, UserError, command, positive_float, ros_namespace

from .doctor_checks import run_checks
from .doctor_facts import SAMPLE_SECONDS
from .doctor_result import exit_status


@command("prisma-doctor")
def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-doctor", description=__doc__.splitlines()[0],
                            formatter_class=argparse.RawDescriptionHelpFormatter,
                            epilog="\n".join(__doc__.splitlines()[2:]))
    parser.add_argument("--namespace", type=ros_namespace, default="",
                        help="the hand's namespace, as namespace:= of hand.launch.py (default: none)")
    parser.add_argument("--timeout", type=positive_float, default=6.0,
                        help="seconds to find the nodes and collect their parameters, /diagnostics and taxels "
                             f"(default 6; at least {SAMPLE_SECONDS + 2:g})")
    args = parser.parse_args(argv)
    if args.timeout < SAMPLE_SECONDS + 2:
        raise UserError(f"--timeout {args.timeout:g}: at least {SAMPLE_SECONDS + 2:g} s (discovery, parameters "
                        f"and {SAMPLE_SECONDS:g} s of taxels)")
    try:
        from .doctor_graph import gather  # rclpy and the messages: only once the arguments are right
    except ImportError as exc:
        raise UserError(f"{exc.name or exc} not found: source the ROS 2 setup (and install/setup.bash) first") \
            from None
    facts = gather(args.namespace, args.timeout)
    results = run_checks(facts)
    for result in results:
        print(result.line(), flush=True)
    return exit_status(results)


if __name__ == "__main__":
    raise SystemExit(main())
