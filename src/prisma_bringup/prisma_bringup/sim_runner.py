"""The off-robot demo: the paper's experiments in closed loop, each recorded as an MCAP bag with a plot,
then one summary (Markdown + JSON) for the whole run.

Hand scenarios (`hand_session.HAND_SCENARIOS`) run with the force estimator's default bundle in the
loop; the glove session (`glove_session`) runs the glove driver and perception cores. Output:

    <out>/summary.md, <out>/summary.json
    <out>/<scenario>.png
    <out>/bags/<scenario>/    (metadata.yaml + <scenario>.mcap: `ros2 bag play <out>/bags/<scenario>`)
"""
from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .bag import BagWriter

GLOVE = "glove"
NS = 1_000_000_000

# The stop each experiment ends with in the paper (DESIGN.md section 6); a run that ends otherwise
# is reported and makes prisma-sim exit 1.
EXPECTED_REASONS = {
    "pinch_grasp": "force_reached",
    "lateral_grasp": "force_reached",
    "horizontal": "edge_lost",
    "vertical": "edge_lost",
    "disturbance": "timeout",  # a hold goal runs until its time is up; the restore happened before
    "combined": "timeout",
    GLOVE: "session_complete",
}


def scenario_names() -> tuple[str, ...]:
    from .hand_session import HAND_SCENARIOS

    return tuple(HAND_SCENARIOS) + (GLOVE,)


@dataclass
class SimOptions:
    out: Path = Path("prisma_sim_out")
    scenarios: list[str] = field(default_factory=lambda: list(scenario_names()))
    bundle: str = "config/models/cnn2"
    glove_objects: int = 4
    plots: bool = True
    seed: int = 0


def _fresh_dir(path: Path) -> Path:
    """A bag directory to write: an earlier (or interrupted) run's bag of the same scenario is replaced;
    anything else there is left alone."""
    if path.exists():
        foreign = [p.name for p in path.iterdir() if p.name != "metadata.yaml" and p.suffix not in (".mcap", ".db3")]
        if foreign or not path.is_dir():
            raise FileExistsError(f"{path} holds files that are not a bag ({', '.join(foreign[:3])}); not overwriting")
        shutil.rmtree(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _rel(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def run_hand(name: str, options: SimOptions, estimator, progress: Callable[[str], None]) -> dict:
    from prisma_manipulation.scenarios_cli import plot, summarise

    from .hand_session import HAND_SCENARIOS, HandRecorder

    spec = HAND_SCENARIOS[name]
    started = time.perf_counter()
    scenario = spec.make()
    bag = _fresh_dir(options.out / "bags" / name)
    with BagWriter(bag) as writer:
        recorder = HandRecorder(scenario, writer, estimator, spec.action)
        trace = scenario.run(progress=lambda line: progress(f"[{name}] {line}"))
        recording = recorder.finish()
    summary = summarise(scenario, trace)
    summary["scenario"] = name
    summary["thumb_force_used_final_n"] = float(trace.force("thumb", "used")[-1])
    summary["index_force_used_final_n"] = float(trace.force("index", "used")[-1])
    c = scenario.controller
    summary.update({
        "description": spec.description,
        "action": spec.action,
        "goal": spec.goal,
        "result": ({"success": c.success, "reason": c.reason,
                    "finger_force": c.finger_force, "thumb_force": c.thumb_force} if spec.action == "grasp" else
                   {"success": c.success, "stop_reason": c.reason,
                    "stop_time": None if c.stop_ns is None else (c.stop_ns - c.start_ns) / NS}),
        "samples": recording.samples,  # every sample incl. the one the goal started on
        "rate_hz": NS / scenario.loop.period_ns,
        "duration_s": (recording.last_ns - recording.first_ns) / NS,
        "bag": _rel(bag, options.out),
        "topics": dict(sorted(recording.counts.items())),
        "goals": [{"action": g.action, "accepted_s": g.accepted_ns / NS,
                   "ended_s": None if g.ended_ns is None else g.ended_ns / NS, "status": g.status,
                   "feedback": g.feedback} for g in recording.goals],
    })
    if options.plots:
        path = options.out / f"{name}.png"
        plot(scenario, trace, path)
        summary["plot"] = _rel(path, options.out)
    summary["wall_s"] = time.perf_counter() - started
    return summary


def run_glove(options: SimOptions, progress: Callable[[str], None]) -> dict:
    from .glove_session import plot, run_glove_session, summarise

    started = time.perf_counter()
    bag = _fresh_dir(options.out / "bags" / GLOVE)
    with BagWriter(bag) as writer:
        recording = run_glove_session(writer, objects=options.glove_objects, seed=options.seed,
                                      progress=lambda line: progress(f"[{GLOVE}] {line}"))
    summary = summarise(recording)
    summary.update({"bag": _rel(bag, options.out), "topics": dict(sorted(recording.counts.items()))})
    if options.plots:
        path = options.out / f"{GLOVE}.png"
        plot(recording, path)
        summary["plot"] = _rel(path, options.out)
    summary["wall_s"] = time.perf_counter() - started
    return summary


def run(options: SimOptions, progress: Callable[[str], None] = print) -> list[dict]:
    """Run the chosen scenarios; write summary.json and summary.md into options.out."""
    unknown = [s for s in options.scenarios if s not in scenario_names()]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; have {list(scenario_names())}")
    options.out.mkdir(parents=True, exist_ok=True)
    summaries = []
    estimator = None
    for name in options.scenarios:
        progress(f"[{name}] running")
        if name == GLOVE:
            summary = run_glove(options, progress)
        else:
            if estimator is None:
                from prisma_force_estimator.bundle import resolve_bundle_path
                from prisma_force_estimator.inference import ForceEstimator

                estimator = ForceEstimator.from_bundle(resolve_bundle_path(options.bundle), threads=1)
                progress(f"force estimator: {estimator.model_kind} from {estimator.path}")
            summary = run_hand(name, options, estimator, progress)
        summary["expected_reason"] = EXPECTED_REASONS.get(name)
        summary["as_expected"] = summary["reason"] == summary["expected_reason"]
        summaries.append(summary)
        progress(f"[{name}] {summary['reason']}"
                 + (f", stop at {summary['stop_time_s']:.2f} s" if summary.get("stop_time_s") is not None else "")
                 + f" ({summary['wall_s']:.1f} s) -> {options.out / summary['bag']}")
    (options.out / "summary.json").write_text(json.dumps(summaries, indent=2) + "\n")
    (options.out / "summary.md").write_text(markdown(summaries))
    return summaries


def _fmt(value, digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def markdown(summaries: list[dict]) -> str:
    hand = [s for s in summaries if s["scenario"] != GLOVE]
    glove = [s for s in summaries if s["scenario"] == GLOVE]
    lines = ["# prisma-sim summary", ""]
    if hand:
        lines += [
            "Hand: closed loop at 100 Hz, controllers on the force estimator's Fz (default bundle); "
            "forces in N at the end of the run (estimated / true).", "",
            "| scenario | stop reason | expected | success | stop time (s) | thumb Fz | index Fz | samples | bag |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for s in hand:
            thumb = f"{_fmt(s.get('thumb_force_used_final_n'))} / {_fmt(s['thumb_force_final_n'])}"
            index = f"{_fmt(s.get('index_force_used_final_n'))} / {_fmt(s['index_force_final_n'])}"
            lines.append(f"| {s['scenario']} | {s['reason']} | {'yes' if s['as_expected'] else 'NO'} | "
                         f"{s['success']} | {_fmt(s['stop_time_s'])} | {thumb} | {index} | {s['samples']} | "
                         f"{s['bag']} |")
        lines.append("")
        for s in hand:
            events = ", ".join(f"{e['what']} at {e['t_s']:.2f} s" for e in s["events"] if not e["what"].startswith("phase"))
            lines.append(f"- **{s['scenario']}**: {s['description']}. Events: {events or 'none'}.")
        lines.append("")
    for s in glove:
        lines += [
            f"Glove: {s['frames']} frames over {s['duration_s']:.1f} s, {s['shorted_frames']} shorted (dropped), "
            f"{s['contact_frames']} with contact; {s['object_correct']}/{len(s['grasps'])} objects recognised; "
            f"stop reason {s['reason']} ({'as expected' if s['as_expected'] else 'NOT as expected'}); "
            f"bag {s['bag']}.", "",
            "| object in hand | /stag/object (last while held) | decisions | weight true (g) | /stag/weight median (g) | linear baseline (g) | hand pose |",
            "|---|---|---|---|---|---|---|",
        ]
        for g in s["grasps"]:
            lines.append(f"| {g['truth']} | {g['decision'] or '-'} | {g['decisions']} | {_fmt(g['true_weight_g'], 0)} | "
                         f"{_fmt(g['weight_g'], 0)} | {_fmt(g['baseline_weight_g'], 0)} | {g['pose'] or '-'} |")
        lines.append("")
    return "\n".join(lines)
