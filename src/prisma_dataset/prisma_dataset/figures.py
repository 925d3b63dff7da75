"""The figures prisma-dataset draws (`show --plot`, `replay --plot`): pyplot without a display, and a
figure written whole or not at all."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from prisma_common.atomic import atomic_output


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (no display needed), imported when a command draws: the
    commands that do not stay fast to start."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, title: str, out: Path) -> Path:
    """`fig` titled, laid out and written to `out` (staged, renamed when complete), then closed."""
    fig.suptitle(title)
    fig.tight_layout()
    with atomic_output(out) as staged:
        fig.savefig(staged, dpi=80)
    pyplot().close(fig)
    return out
