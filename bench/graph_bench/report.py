"""The tables of docs/performance.md (markdown) and its plots, from a results.json."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from graph_bench.facts import GLOVE_NODES, HAND_NODES
from graph_bench.hosts import HOSTS_HAND
from graph_bench.stats import median_spread

HAND_HOPS = {"contact_received": "ContactState received at the probe",
             "wrench_received": "WrenchStamped received at the probe",
             "move_accepted": "MoveMotors goal accepted at the motor driver",
             "contact_published": "ContactState published (DDS source time)",
             "wrench_published": "WrenchStamped published (DDS source time)",
             "taxels_published": "TaxelArray published (DDS source time)"}
HOSTS_HOPS = {"contact_received": "ContactState received at the workstation's probe",
              "wrench_received": "WrenchStamped received at the workstation's probe",
              "move_accepted": "MoveMotors goal accepted at the motor driver (robot)",
              "contact_published": "ContactState published (DDS source time)",
              "wrench_published": "WrenchStamped published (DDS source time)"}


def cell(d: dict | None, unit: str = "") -> str:
    """median (min-max over runs) of a stats.median_spread dict."""
    if not d or d.get("median") is None:
        return "-"
    if d.get("runs", 1) > 1:
        return f"{d['median']:.3g}{unit} ({d['min']:.3g}-{d['max']:.3g})"
    return f"{d['median']:.3g}{unit}"


def markdown_hand(results: dict) -> list[str]:
    h = results["hand_summary"]
    out = [f"### CPU at 100 Hz (% of one core, median (min-max) of {h['repeats']} runs)", "",
           "| process | hand graph | relay | ratio graph / relay |", "|---|---|---|---|"]
    for name, row in h["cpu_pct"].items():
        out.append(f"| {name} | {cell(row.get('real'))} | {cell(row.get('relay'))} | {cell(row.get('ratio'))} |")
    out += ["", "### Latency at 100 Hz, 5 fingers (ms; graph: samples stamped during pinch Grasp goals)", "",
            "| from the taxel stamp to | graph p50 | graph p99 | relay p50 | relay p99 | p99 ratio "
            "| samples (graph; relay) |", "|---|---|---|---|---|---|---|"]
    for hop, label in HAND_HOPS.items():
        e = h["latency_ms"][hop]
        out.append(f"| {label} | {cell(e['p50_ms']['real'])} | {cell(e['p99_ms']['real'])} | "
                   f"{cell(e['p50_ms']['relay'])} | {cell(e['p99_ms']['relay'])} | "
                   f"{cell(e['p99_ms']['ratio'])} | {sum(e['n']['real'])}; {sum(e['n']['relay'])} |")
    out += ["", f"Grasps per run (succeeded/sent): {', '.join(h['grasps']['real'])}.",
            f"Other load during the CPU windows (% of one core, all other processes): "
            f"{h['machine']['others_pct']}; 1-min load average at the window's start and end: "
            f"{h['machine']['loadavg_1min']}."]
    if "throughput" in h:  # results.json files written before the scans were counted have none
        t = h["throughput"]
        out += [f"Scans through the whole chain per second of one core the four nodes used, in the probe's "
                f"window (counted): graph {cell(t['real']['scans_per_core_s'])} "
                f"({cell(t['real']['handled_hz'])} scans/s handled), relay {cell(t['relay']['scans_per_core_s'])} "
                f"({cell(t['relay']['handled_hz'])} scans/s).",
                f"Scheduling of the nodes: graph {', '.join(h['rungs']['real'])}; "
                f"relay {', '.join(h['rungs']['relay'])}."]
    return out + [""]


def markdown_sweep(results: dict) -> list[str]:
    out = ["### Scan-rate sweep (5 fingers, pinch grasps running, probe = ros2 bag record)", "",
           "| commanded Hz | graph: received Hz | no wrench | no contact | stale | grasps | "
           "relay: received Hz | no wrench | no contact | sustained (graph; relay) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    rows = {(r["kind"], r["rate_hz"]): r for r in results["sweep"]}
    for rate in sorted({r["rate_hz"] for r in results["sweep"]}):
        g, r = rows.get(("real", rate)), rows.get(("relay", rate))
        if not g or not r:
            continue
        stale = len(g["stale"]) + g["sensor_stale_aborts"]
        out.append(f"| {rate:g} | {g['received_hz']:g} | {g['dropped_wrench']} | {g['dropped_contact']} | "
                   f"{stale} | {g['grasps']} | {r['received_hz']:g} | {r['dropped_wrench']} | "
                   f"{r['dropped_contact']} | {'yes' if g['sustained'] else 'no'}; "
                   f"{'yes' if r['sustained'] else 'no'} |")
    m = results.get("sweep_max_sustained_hz", {})
    out += ["", f"Highest rate sustained from 100 Hz up: graph {m.get('real', 0):g} Hz, "
                f"relay {m.get('relay', 0):g} Hz."]
    rungs = {kind: sorted({v for r in results["sweep"] if r["kind"] == kind for v in r.get("rungs", {}).values()})
             for kind in ("real", "relay")}
    if rungs["real"] or rungs["relay"]:
        out.append(f"Scheduling of the nodes: graph {', '.join(rungs['real'])}; relay {', '.join(rungs['relay'])}.")
    return out + [""]


def markdown_glove(results: dict) -> list[str]:
    runs = {kind: [g for g in results["glove"] if g["kind"] == kind] for kind in ("real", "relay")}
    out = ["### Glove at 7.3 frames/s (% of one core)", "", "| process | glove nodes | relay | ratio |",
           "|---|---|---|---|"]
    for node in GLOVE_NODES:
        real = [g["cpu"]["processes"][node]["cpu_pct"] for g in runs["real"]]
        relay = [g["cpu"]["processes"][node]["cpu_pct"] for g in runs["relay"]]
        ratio = median_spread([a / max(1e-9, b) for a, b in zip(real, relay)])
        out.append(f"| {node} | {cell(median_spread(real))} | {cell(median_spread(relay))} | {cell(ratio)} |")
    rates = [g["rates_hz"].get("/stag/frame") for g in runs["real"]]
    out += ["", f"/stag/frame at the probe: {rates} frames/s."]
    if all("throughput" in g for g in results["glove"]):
        per_core = {k: median_spread([g["throughput"]["frames_per_core_s"] for g in v]) for k, v in runs.items()}
        out.append(f"Frames handled per second of one core the two nodes used, in the probe's window (counted): "
                   f"glove nodes {cell(per_core['real'])}, relay {cell(per_core['relay'])}.")
    return out + [""]


def markdown_markers(results: dict) -> list[str]:
    m = results["markers"]["summary"]
    return ["### Tactile markers (% of one core; median (min-max) of the watched runs)", "",
            "| | tactile_markers | relay (same inputs and MarkerArray, nothing computed) | ratio |",
            "|---|---|---|---|",
            f"| nobody watching | {m['tactile_markers_idle_pct']} | - | - |",
            f"| a display watching | {cell(m['tactile_markers_watched_pct'])} | "
            f"{cell(m['relay_markers_watched_pct'])} | {cell(m['ratio'])} |", "",
            f"The hand graph's four nodes and tactile_markers together: {m['graph_idle_pct']} % of one core "
            f"with nobody watching the markers, {cell(m['graph_watched_pct'])} % with a display watching. "
            f"MarkerArrays received by the display: {m['markers_hz']} /s (relay {m['relay_markers_hz']} /s).", ""]


def markdown_entities(results: dict) -> list[str]:
    out = ["### The manipulation relay with the node's idle entities (% of one core)", "",
           "| relay manipulation | CPU |", "|---|---|"]
    return out + [f"| {k} | {v['manipulation relay %']} |" for k, v in results["entities"].items()] + [""]


def markdown_profile(results: dict) -> list[str]:
    out = ["### Where each node's CPU goes (py-spy, 100 Hz graph with pinch grasps running)", ""]
    for node in HAND_NODES:
        p = results["profile"][node]
        out += [f"**{node}** ({p['cpu_pct']} % of one core while profiled; {p['working_samples']} working samples)",
                "", "| category | % of samples | % of one core |", "|---|---|---|"]
        out += [f"| {c['what']} | {c['samples_pct']} | {c['core_pct']} |" for c in p["categories"]]
        out += ["", "| top functions (self time) | % of samples | % of one core |", "|---|---|---|"]
        out += [f"| `{c['what']}` | {c['samples_pct']} | {c['core_pct']} |" for c in p["self"][:8]]
        out.append("")
    return out


def markdown_hosts(results: dict) -> list[str]:
    h = results["hosts_summary"]
    out = [f"### One host and two hosts: {h.get('graph', 'bimanual.launch.py')} (% of one core, median (min-max) "
           f"of {h['repeats']} runs each)", "", "| processes | one host | two hosts | two / one |", "|---|---|---|---|"]
    for name, row in h["cpu_pct"].items():
        out.append(f"| {name} | {cell(row['one host'])} | {cell(row['two hosts'])} | {cell(row['ratio'])} |")
    out += ["", f"### Latency, {HOSTS_HAND} hand, probe on the workstation (ms)", "",
            "| from the taxel stamp to | one host p50 | two hosts p50 | one host p99 | two hosts p99 | p99 added "
            "| samples (one; two) |", "|---|---|---|---|---|---|---|"]
    for hop, label in HOSTS_HOPS.items():
        e = h["latency_ms"][hop]
        out.append(f"| {label} | {cell(e['p50_ms']['one host'])} | {cell(e['p50_ms']['two hosts'])} | "
                   f"{cell(e['p99_ms']['one host'])} | {cell(e['p99_ms']['two hosts'])} | "
                   f"{cell(e['p99_ms']['added'])} | {sum(e['n']['one host'])}; {sum(e['n']['two hosts'])} |")
    out += ["", f"Grasps (succeeded/sent): one host {', '.join(h['grasps']['one host'])}; two hosts "
                f"{', '.join(h['grasps']['two hosts'])}.", "",
            "### On the link (IP packets and bytes, both hands and the glove)", "",
            "| window | direction | packets/s | bytes/s |", "|---|---|---|---|"]
    for window, label in (("link_idle", "no goal"), ("link_grasping", "pinch grasps on the left hand")):
        for d, row in h[window].items():
            out.append(f"| {label} | {d} | {cell(row['packets_s'])} | {cell(row['bytes_s'])} |")
    out += ["", "| direction | topic | subscribers across | messages/s | serialised bytes/s (one copy) |",
            "|---|---|---|---|---|"]
    out += [f"| {t['direction']} | {t['topic']} | {t['far_subscribers']} | {cell(t['msgs_s'])} | "
            f"{cell(t['bytes_s'])} |" for t in h["crossing"]]
    out += ["", f"Other load during the CPU windows (% of one core): {h['machine']['others_pct']}; 1-min load "
                f"average at each window's start and end: {h['machine']['loadavg_1min']}.", ""]
    return out


# the sections in the page's order: (key in results.json that holds them, its tables)
SECTIONS = (("hand_summary", markdown_hand), ("hosts_summary", markdown_hosts), ("sweep", markdown_sweep),
            ("glove", markdown_glove), ("markers", markdown_markers), ("entities", markdown_entities),
            ("profile", markdown_profile))


def markdown(results: dict) -> str:
    """The tables of docs/performance.md from a results.json: each section it has measurements for."""
    return "\n".join(line for key, section in SECTIONS if results.get(key) for line in section(results))


def _plot_sweep(plt: Any, rows: list[dict], path: Path) -> None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for kind, color in (("real", "C0"), ("relay", "C1")):
        rs = sorted((r for r in rows if r["kind"] == kind), key=lambda r: r["rate_hz"])
        if not rs:
            continue
        x = [r["rate_hz"] for r in rs]
        ax1.plot(x, [r["received_hz"] for r in rs], "o-", color=color, label=f"{kind}: taxel scans received")
        ax2.plot(x, [100 * r["dropped_wrench"] / max(1, r["taxels"]) for r in rs], "o-", color=color,
                 label=f"{kind}: no WrenchStamped")
        ax2.plot(x, [100 * r["dropped_contact"] / max(1, r["taxels"]) for r in rs], "s--", color=color,
                 label=f"{kind}: no ContactState")
    lim = max(r["rate_hz"] for r in rows)
    ax1.plot([0, lim], [0, lim], ":", color="grey", label="commanded")
    ax1.set(xlabel="commanded scan rate (Hz)", ylabel="received scan rate per finger (Hz)",
            title="scans received at the probe", xlim=(0, lim * 1.05), ylim=(0, lim * 1.05))
    ax2.set(xlabel="commanded scan rate (Hz)", ylabel="% of taxel samples",
            title="taxel samples without a wrench / contact")
    ax2.set_yscale("symlog", linthresh=0.1)
    ax2.set_ylim(bottom=0)
    for ax in (ax1, ax2):
        ax.axvline(350, color="red", lw=0.8, ls=":", label="I2C limit, 5 fingers (350 Hz)")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_latency(plt: Any, hand: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, hop, title in zip(axes, ("contact_received", "wrench_received", "move_accepted"),
                              ("taxel stamp -> ContactState at probe", "taxel stamp -> WrenchStamped at probe",
                               "taxel stamp -> MoveMotors goal accepted")):
        for kind, color in (("real", "C0"), ("relay", "C1")):
            for i, r in enumerate(r for r in hand if r["kind"] == kind):
                v = np.sort(np.array(r["samples_ms"][hop]))
                if len(v) == 0:
                    continue
                y = np.arange(1, len(v) + 1) / len(v)
                ax.step(v, y, where="post", color=color, alpha=0.8, ls=("-", "--", ":")[i % 3],
                        label=f"{kind} run {i + 1} (n={len(v)})")
                if len(v) < 60:  # few samples (one per grasp): show each
                    ax.plot(v, y, "o", color=color, ms=3)
        ax.set(xscale="log", xlabel="latency (ms)", ylabel="fraction of samples", title=title)
        ax.axhline(0.99, color="grey", lw=0.6, ls=":")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle("100 Hz, 5 fingers; real = hand.launch.py sim:=true during pinch Grasp goals; "
                 "relay = bench/ros_relay.py", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot(results: dict, plots: Path) -> list[Path]:
    """perf_sweep.png and perf_latency_cdf.png under `plots`, for the parts results.json has."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plots.mkdir(parents=True, exist_ok=True)
    written = []
    if results.get("sweep"):
        written.append(plots / "perf_sweep.png")
        _plot_sweep(plt, results["sweep"], written[-1])
    if results.get("hand"):
        written.append(plots / "perf_latency_cdf.png")
        _plot_latency(plt, results["hand"], written[-1])
    return written
