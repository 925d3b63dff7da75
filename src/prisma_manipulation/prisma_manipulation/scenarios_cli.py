"""prisma-manip-scenarios: run the paper's scenarios (docs/manipulation.md) in the ROS-free closed loop and
write one PNG per scenario plus summary.json (stop reasons, stop times, forces).

    prisma-manip-scenarios --out docs/img [--only horizontal] [--bundle config/models/cnn2]

With --bundle the controllers see the force estimator's Fz instead of the world's ground truth.
Arguments and the bundle are checked before any scenario runs; each plot and summary.json is
written under a temporary name and renamed when complete (existing ones are replaced).
"""
from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.cli_args import ArgumentParser, check_bundle_dir, command, output_dir
from prisma_common.hand import MOTOR_NAMES
from prisma_force_estimator.force_estimator_core import load_estimator
from prisma_tactile_driver.taxels import EDGES

from .closed_loop import Trace
from .contact_monitor import DEFAULT_K, first_lost_index
from .grasp_controller import GraspController
from .scenarios import SCENARIO_NAMES, Scenario, build

SETTLE_SAMPLES = 10  # 100 ms at 100 Hz: ten velocity-loop time constants
EDGE_COLOURS = {"right": "tab:red", "left": "tab:blue", "top": "tab:green", "bottom": "tab:orange"}


def _say(scenario: str, line: str) -> None:
    print(f"[{scenario}] {line}")


def summarise(sc: Scenario, trace: Trace) -> dict:
    """Stop reason and instants, events, forces. `stop_time_s` is the Manipulate result's stop_time
    (from the goal's start at 0): the sample whose event stopped the motion, named in `stop_event`
    (edge_lost:right, force_reached:thumb, restored:left ...); `end_time_s` is when the goal ended
    for its `reason`. They differ where the goal goes on after its motion stopped: a horizontal
    goal returns to its start angle, a hold goal runs until its timeout, its last restore being
    its stop time."""
    c = sc.controller
    t = np.asarray(trace.stamps_ns) * 1e-9
    stop_event = next((e.what for e in c.events if e.stamp_ns == c.stop_ns
                       and not e.what.startswith(("phase:", "done:"))), None)
    end = next((e.stamp_ns for e in c.events if e.what.startswith("done:")), None)
    out = {"scenario": sc.name, "reason": c.reason, "success": c.success,
           "stop_time_s": None if c.stop_ns is None else round(c.stop_ns * 1e-9, 6),
           "stop_event": stop_event,
           "end_time_s": None if end is None else round(end * 1e-9, 6),
           "events": [{"t_s": e.stamp_ns * 1e-9, "what": e.what} for e in c.events if e.what != "start"],
           "thumb_force_final_n": float(trace.force("thumb")[-1]),
           "index_force_final_n": float(trace.force("index")[-1]),
           "samples": len(t)}
    volts = trace.finger_voltages("thumb")
    for edge in ("right", "top", "left"):
        i = first_lost_index(volts, DEFAULT_K, edge)
        out[f"first_{edge}_lost_s"] = None if i is None else float(t[i])
    if isinstance(c, GraspController):
        for phase, stamp in c.phase_end_ns.items():
            i = trace.index_of(stamp)
            finger = "index" if phase == "close_fingers" else "thumb"
            target = c.finger_force_n if phase == "close_fingers" else c.thumb_force_n
            # overshoot of a phase = its step response: the fingers' until their motor settled
            # (100 ms), the thumb's until the end of the recording
            end = i + SETTLE_SAMPLES if phase == "close_fingers" else len(t) - 1
            for which in ("used", "true"):
                f = trace.force(finger, which)
                out[f"{phase}_{which}_at_stop_n"] = float(f[i])
                out[f"{phase}_{which}_overshoot_n"] = float(f[i:end + 1].max() - target)
    return out


def ending(summary: dict) -> str:
    """How a scenario ended, in its events' words: `timeout at 3.00 s, stop time 1.41 s
    (restored:left)`."""
    text = str(summary["reason"])
    if summary.get("end_time_s") is not None:
        text += f" at {summary['end_time_s']:.2f} s"
    if summary.get("stop_time_s") is not None:
        text += f", stop time {summary['stop_time_s']:.2f} s"
        if summary.get("stop_event"):
            text += f" ({summary['stop_event']})"
    return text


def set_points(sc: Scenario) -> list[tuple[float, str]]:
    """The normal forces the goal controls, (N, legend label): a grasp's force-controlled phases,
    a hold's kept thumb force."""
    c = sc.controller
    points = []
    if isinstance(c, GraspController):
        if c.preset.force_controlled_fingers:
            points.append((c.finger_force_n, f"finger set point {c.finger_force_n:g} N"))
        points.append((c.thumb_force_n, f"thumb set point {c.thumb_force_n:g} N"))
    keeper = getattr(c, "force_keeper", None)
    if keeper is not None:
        points.append((keeper.target_n, f"thumb force kept at {keeper.target_n:g} N"))
    return points


def plot(sc: Scenario, trace: Trace, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(trace.stamps_ns) * 1e-9
    volts = trace.finger_voltages("thumb")
    fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True, gridspec_kw={"height_ratios": [1.3, 0.8, 1, 0.8]})
    ax = axes[0]
    # colour the edges the scenario is about: rows for vertical, lateral columns otherwise
    edges = ("top", "bottom") if sc.name == "vertical" else ("right", "left")
    labelled = set()
    for i in range(9):
        edge = next((e for e in edges if i in EDGES[e]), None)
        label = None if edge in labelled else (f"{edge} {'-'.join(map(str, EDGES[edge]))}" if edge else "others")
        labelled.add(edge)
        ax.plot(t, volts[:, i], color="0.6" if edge is None else EDGE_COLOURS[edge], lw=1, label=label)
    ax.plot(t, trace.array("thresholds")[:, 0], "k--", lw=1.5, label=f"v_t = {DEFAULT_K} v_a")
    ax.set_ylabel("thumb taxels (V)")
    ax.legend(loc="best", fontsize=8, ncol=4)
    ax = axes[1]
    xy = trace.array("contact_xy")[:, 0]
    ax.plot(t, xy[:, 0], label="contact x (+ left)")
    ax.plot(t, xy[:, 1], label="contact y (+ top)")
    ax.set_ylabel("thumb pad contact (mm)")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[2]
    used = "estimated" if sc.loop.estimator is not None else "true"  # what the controller steered by
    ax.plot(t, trace.force("thumb"), "k", lw=1, label="thumb Fz true")
    ax.plot(t, trace.force("thumb", "used"), "k:", lw=1, label=f"thumb Fz used ({used})")
    ax.plot(t, trace.force("index"), "m", lw=1, label="index Fz true")
    ax.plot(t, trace.force("index", "used"), "m:", lw=1, label=f"index Fz used ({used})")
    for (target, label), colour in zip(set_points(sc), ("tab:olive", "tab:cyan")):
        ax.axhline(target, color=colour, lw=1, ls="--", label=label)
    ax.set_ylabel("normal force (N)")
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax = axes[3]
    for m, name in enumerate(MOTOR_NAMES):
        ax.plot(t, trace.array("positions")[:, m], label=name)
    ax.set_ylabel("motor position (rad)")
    ax.set_xlabel("time (s)")
    ax.legend(fontsize=8)
    stops = [e for e in sc.controller.events
             if e.what.startswith(("edge_lost", "force_reached", "closed", "restored", "joint_limit", "returned"))]
    for e in stops:
        for a in axes:
            a.axvline(e.stamp_ns * 1e-9, color="0.3", lw=0.8, ls=":")
    # the events name their instants above the plots, clear of the curves and the legends
    named = axes[0].secondary_xaxis("top")
    named.set_xticks([e.stamp_ns * 1e-9 for e in stops], [e.what for e in stops], fontsize=7)
    fig.suptitle(f"{sc.name}: {ending(summarise(sc, trace))}")
    fig.tight_layout()
    with atomic_output(path) as staged:  # whole or not at all
        fig.savefig(staged, dpi=110)
    plt.close(fig)


@command("prisma-manip-scenarios", "prisma_force_estimator.bundle:BundleError")
def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-manip-scenarios", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=output_dir, default=Path("manipulation_scenarios"),
                        help="directory for <scenario>.png and summary.json")
    parser.add_argument("--only", action="append", choices=SCENARIO_NAMES)
    parser.add_argument("--bundle", type=Path, help="force-estimator bundle: controllers use its Fz")
    args = parser.parse_args(argv)
    estimator = None
    if args.bundle:
        check_bundle_dir(args.bundle)
        estimator = load_estimator(args.bundle)
    summaries = []
    for name in args.only or SCENARIO_NAMES:
        print(f"[{name}] running")
        sc = build(name, estimator=estimator)
        trace = sc.run(progress=functools.partial(_say, name))
        summary = summarise(sc, trace)
        summaries.append(summary)
        plot(sc, trace, args.out / f"{name}.png")
        print(f"[{name}] {ending(summary)} -> {args.out / (name + '.png')}")
    with atomic_output(args.out / "summary.json") as staged:
        staged.write_text(json.dumps(summaries, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
