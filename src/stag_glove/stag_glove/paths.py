"""Find shipped files (layout, model bundles) in the source tree or in a colcon install."""
from __future__ import annotations

import os
from pathlib import Path

# src/stag_glove/stag_glove/paths.py -> workspace root three levels up from the package dir.
SOURCE_ROOT = Path(__file__).resolve().parents[3]
SHARE_PACKAGES = ("stag_glove", "prisma_bringup")


def candidates(relative: str | Path) -> list[Path]:
    """Where a workspace-relative path such as 'config/glove/layout.yaml' may live."""
    relative = Path(relative)
    found = [SOURCE_ROOT / relative]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            found += [Path(prefix) / "share" / package / relative for package in SHARE_PACKAGES]
    return found


def resolve(path: str | Path) -> Path:
    """An absolute or cwd-relative path that exists, else the first workspace/share match.

    Raises FileNotFoundError listing every place looked at, so a missing model or layout file
    fails at start with the path (DESIGN.md section 8)."""
    path = Path(path).expanduser()
    if path.is_absolute() or path.exists():
        if path.exists():
            return path
        raise FileNotFoundError(f"{path} does not exist")
    looked = [path.resolve(), *candidates(path)]
    for candidate in looked[1:]:
        if candidate.exists():
            return candidate
    raise FileNotFoundError(f"{path} not found; looked in: " + ", ".join(map(str, looked)))
