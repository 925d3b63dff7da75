"""Single benchmark entry point (docs/architecture.md, Benchmarks).

    python bench/run.py [--only NAME] [--json FILE]

Every module bench/bench_*.py exposes BENCHMARKS, a list of `Benchmark`. Each prints as a row:
name, measured, unit, needed, ratio = measured / needed (higher is better).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass
class Benchmark:
    name: str
    measure: Callable[[], float]  # returns the measured value in `unit`
    unit: str
    need: float  # the rate the hardware needs, in `unit`
    notes: dict = field(default_factory=dict)  # measure() may fill extra figures (p99 latency...)


@dataclass
class Row:
    name: str
    value: float
    unit: str
    need: float
    ratio: float
    notes: dict


def discover() -> list[Benchmark]:
    found: list[Benchmark] = []
    for path in sorted(HERE.glob("bench_*.py")):
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module
        spec.loader.exec_module(module)
        found.extend(module.BENCHMARKS)
    return found


def run(benchmarks: list[Benchmark]) -> list[Row]:
    rows = []
    for bench in benchmarks:
        value = float(bench.measure())
        rows.append(Row(bench.name, value, bench.unit, bench.need, value / bench.need, bench.notes))
    return rows


def format_table(rows: list[Row]) -> str:
    header = f"{'name':<24} {'measured':>14} {'unit':<12} {'needed':>10} {'ratio':>10}"
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(f"{r.name:<24} {r.value:>14.1f} {r.unit:<12} {r.need:>10.1f} {r.ratio:>10.1f}")
        for key, value in r.notes.items():
            lines.append(f"    {key}: {value}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", help="run only this benchmark (repeatable)")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON to this file")
    args = parser.parse_args(argv)
    benchmarks = discover()
    if args.only:
        unknown = set(args.only) - {b.name for b in benchmarks}
        if unknown:
            parser.error(f"unknown benchmark(s) {sorted(unknown)}; have {[b.name for b in benchmarks]}")
        benchmarks = [b for b in benchmarks if b.name in args.only]
    rows = run(benchmarks)
    print(format_table(rows))
    if args.json:
        args.json.write_text(json.dumps(
            [{"name": r.name, "value": r.value, "unit": r.unit, "need": r.need, "ratio": r.ratio,
              **({"notes": r.notes} if r.notes else {})} for r in rows], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
