"""docs/architecture.md's topic table, parsed: the topics the launched nodes must publish or serve."""
from __future__ import annotations

import re
from dataclasses import dataclass

from prisma_common.hand import FINGERS
from prisma_testing.repo_paths import ROOT

SHARED_TOPICS = {"/diagnostics"}  # published by every driver


@dataclass(frozen=True)
class TableRow:
    name: str
    type: str
    source: str

    @property
    def is_action(self) -> bool:
        return "/action/" in self.type


def topic_table() -> list[TableRow]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    match = re.search(r"^## Topic table\s*$(.*?)(?=^## |\Z)", text, re.S | re.M)
    if not match:
        return []
    rows = []
    for line in match.group(1).splitlines():
        cells = [c.strip().strip("`").strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not cells[0].startswith("/"):
            continue
        names = [cells[0].replace("<finger>", f) for f in FINGERS] if "<finger>" in cells[0] else [cells[0]]
        rows.extend(TableRow(name, cells[1], cells[2]) for name in names)
    return rows
