"""The off-robot demo: the paper's experiments in closed loop, each recorded as an MCAP bag with a plot,
then one summary (Markdown + JSON) for the whole run.

Hand scenarios (`hand_session.HAND_SCENARIOS`) run with a force estimator bundle in the loop (the
default `config/models/cnn2`; the summaries name the directory actually used); the glove session
(`glove_session`) runs the glove driver and perception cores. Output:

    <out>/summary.md, <out>/summary.json
    <out>/<scenario>.png
    <out>/bags/<scenario>/    (metadata.yaml + <scenario>.mcap: `ros2 bag play <out>/bags/<scenario>`)

The output directory is written whole or not at all: the run writes `<out>.partial-<pid>/<out>/`
and renames it onto `<out>` when every scenario is done, replacing an earlier run's output there.
A directory that holds anything else is refused before the run starts.

A scenario is as expected when it stops for the paper's reason and every force set point it has
(a grasp phase's finger or thumb force, a force-holding hold goal's thumb force) is met within
`FORCE_TOLERANCE_N`, by the estimated force the controller used and by the true force.
"""
from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from prisma_common.atomic import atomic_output
from prisma_common.bag import BagWriter
from prisma_force_estimator.force_estimator_core import load_estimator as load_bundle_estimator
from prisma_hand_sim.scenario_worlds import SCENARIO_NAMES
from prisma_manipulation.scenarios_cli import ending, plot, summarise

GLOVE = "glove"
TELEOP = "teleop"  # teleop_session.TELEOP, spelled out as the hand scenarios' names are
NS = 1_000_000_000
# hand_session.HAND_SCENARIOS' names, read from the worlds' module so that the command line is built
# without importing the closed loop and torch (test_sim_runner checks that they agree)
HAND_SCENARIO_NAMES = SCENARIO_NAMES

# The stop each experiment ends with in the paper (docs/manipulation.md); a run that ends otherwise
# is reported and makes prisma-sim exit 1.
EXPECTED_REASONS = {
    "pinch_grasp": "force_reached",
    "lateral_grasp": "force_reached",
    "horizontal": "edge_lost",
    "vertical": "edge_lost",
    "disturbance": "timeout",  # a hold goal runs until its time is up; the restore happened before
    "combined": "timeout",
    GLOVE: "session_complete",
    TELEOP: "input_stale",  # the operator's glove falls silent at the end: the motors stop, the goal ends
}

# Largest allowed |force - set point| (N). The pinch grasp's measured step responses peak 0.078 N
# (estimated) / 0.068 N (true) above their set points (docs/manipulation.md: one sample of force
# rise plus the velocity loop's coast, and the estimator's noise); 0.15 N is about twice that, and
# the width of the combined controller's force band (ForceKeeper.band_n).
FORCE_TOLERANCE_N = 0.15
SETTLE_SAMPLES = 10  # as prisma_manipulation.scenarios_cli: a grasp phase's fingers settle in 100 ms


def scenario_names() -> tuple[str, ...]:
    return HAND_SCENARIO_NAMES + (TELEOP, GLOVE)


@dataclass
class SimOptions:
    out: Path = Path("prisma_sim_out")
    scenarios: list[str] = field(default_factory=lambda: list(scenario_names()))
    bundle: str = "config/models/cnn2"
    glove_objects: int = 4
    plots: bool = True
    seed: int = 0
    force_tolerance_n: float = FORCE_TOLERANCE_N


def check_out(out: Path) -> None:
    """FileExistsError unless `out` is missing, empty or an earlier prisma-sim output (which the
    run replaces as a whole): summary.md/json, <scenario>.png and bags/<scenario>/ bags only."""
    out = Path(out)
    if not out.exists() and not out.is_symlink():
        return
    if out.is_symlink() or not out.is_dir():
        raise FileExistsError(f"{out} is a file, not an output directory; give a new directory")
    names = set(scenario_names())
    allowed = {"summary.md", "summary.json", "bags"} | {f"{n}.png" for n in names}
    foreign = [p.name for p in out.iterdir() if p.name not in allowed]
    bags = out / "bags"
    if bags.exists():
        if not bags.is_dir():
            foreign.append("bags")
        else:
            for bag in bags.iterdir():
                inside = [q for q in bag.iterdir()] if bag.is_dir() and bag.name in names else None
                if inside is None or any(q.name != "metadata.yaml" and q.suffix not in (".mcap", ".db3")
                                         for q in inside):
                    foreign.append(f"bags/{bag.name}")
    if foreign:
        shown = ", ".join(sorted(foreign)[:3]) + (", ..." if len(foreign) > 3 else "")
        raise FileExistsError(f"{out} holds files that are not prisma-sim output ({shown}); not replacing it: "
                              f"give a new or empty directory")


def load_estimator(bundle: str | Path):
    """The force estimator of a bundle path, as the node resolves it (BundleError if it is not one)."""
    return load_bundle_estimator(bundle, threads=1)


def _rel(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def _goal_rows(recording) -> list[dict]:
    """Each goal the recorder saw, for summary.json: when it was accepted and ended (s), its status
    and feedback count."""
    return [{"action": g.action, "accepted_s": g.accepted_ns / NS,
             "ended_s": None if g.ended_ns is None else g.ended_ns / NS, "status": g.status,
             "feedback": g.feedback} for g in recording.goals]


def force_errors(scenario, trace) -> dict[str, dict]:
    """Each force set point of the scenario and how far the force strayed from it (N).

    Grasp: each force-controlled phase, over its step response from the stop sample (the window
    the overshoot in docs/manipulation.md is measured over: the fingers' until their motor settled,
    the thumb's until the end of the recording). A hold goal with use_force: the thumb force at the
    end of the run (the keeper restores it whenever it falls out of its band). Errors for the
    estimated force the controller used and for the true force."""
    import numpy as np

    c = scenario.controller
    checks: dict[str, dict] = {}
    preset = getattr(c, "preset", None)
    if preset is not None:  # GraspController
        n = len(trace.stamps_ns)
        for phase, stamp in c.phase_end_ns.items():
            if phase == "close_fingers" and not preset.force_controlled_fingers:
                continue  # a lateral grasp closes its fingers to a position, not a force
            fingers = preset.force_fingers if phase == "close_fingers" else ("thumb",)
            target = c.finger_force_n if phase == "close_fingers" else c.thumb_force_n
            i = trace.index_of(stamp)
            end = min(i + SETTLE_SAMPLES, n - 1) if phase == "close_fingers" else n - 1
            entry = {"set_point_n": target}
            for which in ("used", "true"):
                force = np.mean([trace.force(f, which)[i:end + 1] for f in fingers], axis=0)
                entry[f"{which}_error_n"] = float(np.max(np.abs(force - target)))
            checks[phase] = entry
    keeper = getattr(c, "force_keeper", None)
    if keeper is not None:
        entry = {"set_point_n": keeper.target_n}
        for which in ("used", "true"):
            entry[f"{which}_error_n"] = float(abs(trace.force("thumb", which)[-1] - keeper.target_n))
        checks["hold_thumb_force"] = entry
    return checks


def _finish(summary: dict, options: SimOptions, root: Path, name: str, draw: Callable[[Path], None],
            started: float) -> dict:
    """A session's summary completed: its plot `<name>.png` drawn by `draw` into a staged path (with
    options.plots) and the session's wall time since `started` (time.perf_counter)."""
    if options.plots:
        path = root / f"{name}.png"
        with atomic_output(path) as staged:
            draw(staged)
        summary["plot"] = _rel(path, root)
    summary["wall_s"] = time.perf_counter() - started
    return summary


def run_hand(name: str, options: SimOptions, estimator, progress: Callable[[str], None],
             root: Path | None = None) -> dict:
    """One hand scenario into `root` (default options.out): its bag, plot and summary."""

    from .hand_session import HAND_SCENARIOS, HandRecorder, goal_result

    root = options.out if root is None else root
    spec = HAND_SCENARIOS[name]
    started = time.perf_counter()
    scenario = spec.make(estimator)
    bag = root / "bags" / name
    with BagWriter(bag) as writer:
        recorder = HandRecorder(scenario, writer, spec.action)
        trace = scenario.run(progress=lambda line: progress(f"[{name}] {line}"))
        recording = recorder.finish()
    summary = summarise(scenario, trace)
    summary["scenario"] = name
    summary["thumb_force_used_final_n"] = float(trace.force("thumb", "used")[-1])
    summary["index_force_used_final_n"] = float(trace.force("index", "used")[-1])
    checks = force_errors(scenario, trace)
    worst = max((max(e["used_error_n"], e["true_error_n"]) for e in checks.values()), default=None)
    done = scenario.loop.finished  # the goal's result, as the manipulation node returns it
    result = None if done is None else goal_result(done)
    first_ns, last_ns = recording.first_ns or 0, recording.last_ns or 0
    summary.update({
        "description": spec.description,
        "action": spec.action,
        "goal": spec.goal,
        "bundle": str(estimator.path),
        "result": result,
        "force_set_points": checks,
        "force_error_n": worst,
        "force_tolerance_n": options.force_tolerance_n,
        "force_within_tolerance": worst is None or worst <= options.force_tolerance_n,
        "samples": recording.samples,  # every sample incl. the one the goal started on
        "rate_hz": NS / scenario.loop.period_ns,
        "duration_s": (last_ns - first_ns) / NS,
        "bag": _rel(bag, root),
        "topics": dict(sorted(recording.counts.items())),
        "goals": _goal_rows(recording),
    })
    return _finish(summary, options, root, name, lambda staged: plot(scenario, trace, staged), started)


def run_glove(options: SimOptions, progress: Callable[[str], None], root: Path | None = None) -> dict:
    from .glove_session import plot, run_glove_session, summarise

    root = options.out if root is None else root
    started = time.perf_counter()
    bag = root / "bags" / GLOVE
    with BagWriter(bag) as writer:
        recording = run_glove_session(writer, objects=options.glove_objects, seed=options.seed,
                                      progress=lambda line: progress(f"[{GLOVE}] {line}"))
    summary = summarise(recording)
    summary.update({"bag": _rel(bag, root), "topics": dict(sorted(recording.counts.items()))})
    return _finish(summary, options, root, GLOVE, lambda staged: plot(recording, staged), started)


def run_teleop(options: SimOptions, estimator, progress: Callable[[str], None], root: Path | None = None) -> dict:
    from .teleop_session import plot, run_teleop_session, summarise

    root = options.out if root is None else root
    started = time.perf_counter()
    bag = root / "bags" / TELEOP
    with BagWriter(bag) as writer:
        trace, recording = run_teleop_session(writer, estimator, progress=lambda line: progress(f"[{TELEOP}] {line}"))
    summary = summarise(trace)
    summary.update({"bundle": str(estimator.path), "bag": _rel(bag, root), "samples": recording.samples,
                    "topics": dict(sorted(recording.counts.items())),
                    "force_tolerance_n": options.force_tolerance_n,
                    "force_within_tolerance": summary["force_error_n"] <= options.force_tolerance_n,
                    "goals": _goal_rows(recording)})
    return _finish(summary, options, root, TELEOP, lambda staged: plot(trace, summary, staged), started)


def run(options: SimOptions, progress: Callable[[str], None] = print, estimator=None) -> list[dict]:
    """Run the chosen scenarios; write bags, plots, summary.json and summary.md as options.out.

    Checks first (unknown scenario: ValueError; output in the way: FileExistsError; the bundle:
    BundleError), then writes the whole output directory under a temporary name and renames it onto
    options.out when done. `estimator` saves loading options.bundle again."""
    unknown = [s for s in options.scenarios if s not in scenario_names()]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; have {list(scenario_names())}")
    if not options.force_tolerance_n > 0:
        raise ValueError(f"force tolerance must be > 0 N, got {options.force_tolerance_n}")
    check_out(options.out)
    if estimator is None and any(name != GLOVE for name in options.scenarios):
        estimator = load_estimator(options.bundle)
    if estimator is not None:
        progress(f"force estimator: {estimator.model_kind} from {estimator.path}")
    summaries = []
    with atomic_output(options.out) as root:
        root.mkdir()
        for name in options.scenarios:
            progress(f"[{name}] running")
            if name == GLOVE:
                summary = run_glove(options, progress, root)
            elif name == TELEOP:
                summary = run_teleop(options, estimator, progress, root)
            else:
                summary = run_hand(name, options, estimator, progress, root)
            summary["expected_reason"] = EXPECTED_REASONS.get(name)
            summary["reason_as_expected"] = summary["reason"] == summary["expected_reason"]
            summary["as_expected"] = summary["reason_as_expected"] and summary.get("force_within_tolerance", True)
            summaries.append(summary)
            progress(f"[{name}] " + (ending(summary) if name not in (GLOVE, TELEOP) else summary["reason"])
                     + (f", force set point miss {summary['force_error_n']:.3f} N"
                        if summary.get("force_error_n") is not None else "")
                     + f" ({summary['wall_s']:.1f} s) -> {options.out / summary['bag']}")
        (root / "summary.json").write_text(json.dumps(summaries, indent=2) + "\n")
        (root / "summary.md").write_text(markdown(summaries))
    return summaries


def failures(summaries: list[dict]) -> list[str]:
    """One line per scenario that is not as expected: the stop reason, or the force set point missed."""
    lines = []
    for s in summaries:
        if not s.get("reason_as_expected", s["as_expected"]):
            lines.append(f"{s['scenario']}: stopped with {s['reason']}, expected {s['expected_reason']}")
        if not s.get("force_within_tolerance", True):
            worst = max(s["force_set_points"].items(),
                        key=lambda kv: max(kv[1]["used_error_n"], kv[1]["true_error_n"]))
            phase, e = worst
            lines.append(f"{s['scenario']}: {phase} missed its {e['set_point_n']:g} N set point by "
                         f"{max(e['used_error_n'], e['true_error_n']):.3f} N (estimated {e['used_error_n']:.3f}, "
                         f"true {e['true_error_n']:.3f}); tolerance {s['force_tolerance_n']:g} N")
    return lines


def _fmt(value, digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def markdown(summaries: list[dict]) -> str:
    hand = [s for s in summaries if s["scenario"] not in (GLOVE, TELEOP)]
    glove = [s for s in summaries if s["scenario"] == GLOVE]
    teleop = [s for s in summaries if s["scenario"] == TELEOP]
    lines = ["# prisma-sim summary", ""]
    if hand:
        bundles = sorted({s["bundle"] for s in hand if s.get("bundle")})
        tolerance = hand[0].get("force_tolerance_n", FORCE_TOLERANCE_N)
        lines += [
            f"Hand: closed loop at 100 Hz, controllers on the Fz of the force estimator bundle "
            f"{', '.join(f'`{b}`' for b in bundles) or '(none)'}; forces in N at the end of the run "
            f"(estimated / true). Ended: when the goal ended for its stop reason. Stop time: the sample "
            f"whose event (named) stopped the motion, a Manipulate result's stop_time; a horizontal goal "
            f"returns to its start angle after it, a hold goal runs on until its timeout. Set point miss: "
            f"the largest |force - set point| of the scenario's force set points (estimated or true; "
            f"tolerance {tolerance:g} N; - = none).", "",
            "| scenario | stop reason | expected | success | ended (s) | stop time (s) | thumb Fz | index Fz | "
            "set point miss (N) | samples | bag |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for s in hand:
            thumb = f"{_fmt(s.get('thumb_force_used_final_n'))} / {_fmt(s['thumb_force_final_n'])}"
            index = f"{_fmt(s.get('index_force_used_final_n'))} / {_fmt(s['index_force_final_n'])}"
            miss = _fmt(s.get("force_error_n"), 3)
            if not s.get("force_within_tolerance", True):
                miss += " (over)"
            stop = _fmt(s["stop_time_s"]) + (f" ({s['stop_event']})" if s.get("stop_event") else "")
            lines.append(f"| {s['scenario']} | {s['reason']} | {'yes' if s['as_expected'] else 'NO'} | "
                         f"{s['success']} | {_fmt(s.get('end_time_s'))} | {stop} | {thumb} | {index} | {miss} | "
                         f"{s['samples']} | {s['bag']} |")
        lines.append("")
        for s in hand:
            events = ", ".join(f"{e['what']} at {e['t_s']:.2f} s" for e in s["events"]
                               if not e["what"].startswith("phase"))
            lines.append(f"- **{s['scenario']}**: {s['description']}. Events: {events or 'none'}.")
        lines.append("")
    for s in teleop:
        peak = {which: max(p.values()) for which, p in s["peak_force_n"].items()}
        lines += [
            f"Teleop: {s['description']}. Ended {s['reason']} at {s['end_time_s']:.2f} s "
            f"({'as expected' if s['as_expected'] else 'NOT as expected'}): every motor stopped "
            f"{s['stopped_after_silent_s']:.2f} s after the glove's last sample ({s['glove_silent_s']:.2f} s); "
            f"held the ball at fingers {s['held_fingers_rad']:.2f} rad, thumb {s['held_thumb_flexion_rad']:.2f} rad, "
            f"peak pad force {peak['used']:.3f} N estimated / {peak['true']:.3f} N true against the "
            f"{s['touch_limit_n']:g} N touch limit; thumb rotation swept {s['thumb_rotation_range_rad'][0]:.2f} .. "
            f"{s['thumb_rotation_range_rad'][1]:.2f} rad; {s['samples']} samples; bag {s['bag']}.", ""]
    for s in glove:
        lines += [
            f"Glove: {s['frames']} frames over {s['duration_s']:.1f} s, {s['shorted_frames']} shorted (dropped), "
            f"{s['contact_frames']} with contact; {s['object_correct']}/{len(s['grasps'])} objects recognised; "
            f"stop reason {s['reason']} ({'as expected' if s['as_expected'] else 'NOT as expected'}); "
            f"bag {s['bag']}.", "",
            f"Weight: {s['weight_note']}.", "",
            "| object in hand | /stag/object (last while held) | decisions | weight true (g) "
            "| /stag/weight median (g) | linear baseline (g) | hand pose |",
            "|---|---|---|---|---|---|---|",
        ]
        for g in s["grasps"]:
            lines.append(f"| {g['truth']} | {g['decision'] or '-'} | {g['decisions']} "
                         f"| {_fmt(g['true_weight_g'], 0)} | "
                         f"{_fmt(g['weight_g'], 0)} | {_fmt(g['baseline_weight_g'], 0)} | {g['pose'] or '-'} |")
        lines.append("")
    return "\n".join(lines)
