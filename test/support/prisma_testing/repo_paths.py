"""Where the tests find the repository's files, wherever the test file lives (test/integration/,
src/<package>/test/): the source tree of this checkout."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[3]
BRINGUP = ROOT / "src" / "prisma_bringup"
CONFIG = BRINGUP / "config"  # node parameter files, model bundles, glove layout
LAUNCH = BRINGUP / "launch"


def node_parameters(path: Path, node: str) -> dict[str, Any]:
    """A node's section of a parameter file (keyed by the node's name, bare or `/**/`-prefixed)."""
    sections = yaml.safe_load(path.read_text())
    (key,) = [k for k in sections if k.split("/")[-1] == node]
    return sections[key]["ros__parameters"]
