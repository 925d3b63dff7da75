"""Find shipped files (layout, model bundles) in the source tree, a colcon install or a wheel."""
from __future__ import annotations

from pathlib import Path

from prisma_common import share_data

# The layout ships in both packages' share directories, the glove model bundles in prisma_bringup's.
SHARE_PACKAGES = ("stag_glove", "prisma_bringup")


def candidates(relative: str | Path) -> list[Path]:
    """Where a share-relative path such as 'config/glove/layout.yaml' may live."""
    return share_data.candidates(relative, SHARE_PACKAGES)


def resolve(path: str | Path) -> Path:
    """An absolute or cwd-relative path that exists, else the first source/share match.

    Raises FileNotFoundError listing every place looked at, so a missing model or layout file
    fails at start with the path."""
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
