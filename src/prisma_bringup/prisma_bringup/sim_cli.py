"""`prisma-sim`: the off-robot entry point.

Until the closed-loop scenarios are wired in, it prints the node graph of the topic table and the
interfaces registered in the typestore, so a fresh install can be checked end to end.
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

from .typestore import find_interface_dir, registered_prisma_types

ARCHITECTURE = Path(__file__).resolve().parents[3] / "docs" / "architecture.md"


def topic_table(markdown: str) -> list[tuple[str, str, str]]:
    """(topic, type, publishing node) rows of the 'Topic table' section."""
    section = markdown.split("## Topic table", 1)[-1]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0].startswith("/"):
            rows.append((cells[0], cells[1], cells[2]))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="prisma-sim", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    print(f"prisma_msgs interfaces from {find_interface_dir()}:")
    for name in registered_prisma_types():
        if not re.search(r"_(SendGoal|GetResult)_", name):
            print(f"  {name}")
    if ARCHITECTURE.exists():
        print("\nnode graph (publisher -> topic [type]):")
        for topic, msgtype, node in topic_table(ARCHITECTURE.read_text()):
            print(f"  {node:<17} -> {topic:<26} [{msgtype}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
