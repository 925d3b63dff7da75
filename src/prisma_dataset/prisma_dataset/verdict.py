"""A check's verdict as prisma-dataset prints it (`check`, `replay`): one line when nothing is wrong,
else how many problems and each on a line of its own."""
from __future__ import annotations

from collections.abc import Sequence


def verdict_lines(label: str, problems: Sequence[str], ok: str, wrong: str) -> list[str]:
    """`  <label>: <ok>`, or `  <label>: <count> <wrong>` and the problems indented below it."""
    if not problems:
        return [f"  {label}: {ok}"]
    return [f"  {label}: {len(problems)} {wrong}", *(f"    {problem}" for problem in problems)]
