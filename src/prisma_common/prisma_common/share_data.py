"""Where the files the suite ships are found: model bundles, the glove layout, node parameter files
and the prisma_msgs message definitions.

They are kept once in the repository and installed the way ROS installs a package's data, under
`share/<package>/` of an install prefix, so one lookup serves every way of running the suite:

- source tree (`pip install -e .`, `colcon build --symlink-install`): the package's source folder
  `src/<package>/` (prisma_bringup: `config/`, `launch/`; prisma_msgs: `msg/`, `action/`);
- colcon install (`ros2 run`, `ros2 launch`): `<prefix>/share/<package>/` of each prefix on
  AMENT_PREFIX_PATH, in order (the lookup of ament_index_python's get_package_share_directory,
  done here without importing it so that the ROS-free tools work in a plain venv);
- wheel (`pip install .`): `<prefix>/share/<package>/` of the Python environment, where
  pyproject.toml's [tool.setuptools.data-files] puts the same files.

Imports nothing from ROS and no other workspace package (prisma_common is at the bottom of the graph).
"""
from __future__ import annotations

import os
import site
import sys
import sysconfig
from collections.abc import Iterable
from pathlib import Path

# What share/<package>/ holds lives in the package's source folder, src/<package>/.
SOURCE_DIR = Path("src")


def source_root(module_file: str | Path = __file__) -> Path | None:
    """The repository root when `module_file` (this module) is in the source tree, else None."""
    # src/prisma_common/prisma_common/share_data.py; resolve() follows the symlink
    # colcon --symlink-install puts in build/. Installed copies (site-packages, install/) have no
    # src/prisma_msgs/package.xml three levels up.
    parents = Path(module_file).resolve().parents
    root = parents[3] if len(parents) > 3 else None
    return root if root is not None and (root / "src" / "prisma_msgs" / "package.xml").is_file() else None


SOURCE_ROOT: Path | None = source_root()


def _unique(paths: Iterable[Path]) -> list[Path]:
    seen: set[Path] = set()
    out = []
    for path in paths:
        if path not in seen:
            seen.add(path)
            out.append(path)
    return out


def install_prefixes() -> list[Path]:
    """Prefixes holding share/<package>/: colcon's (AMENT_PREFIX_PATH) first, then the Python
    environment's, where a wheel's data files go (the venv or system prefix, Debian's /usr/local,
    the user base of `pip install --user`)."""
    ament = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    python = [Path(sys.prefix), Path(sysconfig.get_path("data"))]
    if site.ENABLE_USER_SITE:
        python.append(Path(site.getuserbase()))
    return _unique(ament + python)


def workspace_root(directory: Path) -> Path | None:
    """`directory` when it is this repository's root (a workspace a tool is run from), else None."""
    return directory if (directory / "src" / "prisma_msgs" / "package.xml").is_file() else None


def package_directories(package: str) -> list[Path]:
    """Every directory that may hold `package`'s share/ contents, in lookup order: the source
    tree's (of these modules, then of the workspace the tool runs in: a copy install does not know
    its sources, but a bundle retrained in the workspace must win over the installed one), then
    share/<package> of each install prefix (existing or not)."""
    found = []
    for root in (SOURCE_ROOT, workspace_root(Path.cwd())):
        if root is not None:
            found.append(root / SOURCE_DIR / package)
    found += [prefix / "share" / package for prefix in install_prefixes()]
    return _unique(found)


def candidates(relative: str | Path, packages: Iterable[str]) -> list[Path]:
    """Where a share-relative path such as 'config/models/cnn2' may be, in lookup order."""
    return _unique(directory / relative for package in packages for directory in package_directories(package))


def find(relative: str | Path, packages: Iterable[str]) -> Path | None:
    """The first existing candidate of `relative` (file or directory), or None."""
    return next((path for path in candidates(relative, packages) if path.exists()), None)
