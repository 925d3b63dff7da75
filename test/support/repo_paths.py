"""Where the tests find the repository's files, wherever the test file lives (test/integration/,
src/<package>/test/): the source tree of this checkout."""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BRINGUP = ROOT / "src" / "prisma_bringup"
CONFIG = BRINGUP / "config"  # node parameter files, model bundles, glove layout
LAUNCH = BRINGUP / "launch"
