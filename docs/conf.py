"""Sphinx configuration of the handbook: docs/*.md read by MyST, the module reference from docstrings.

Built in CI with warnings as errors: `sphinx-build -W -b html docs <dir>` (pip install -e ".[docs]").
The modules are imported from the checkout (src/<package>/); rclpy, launch and the ROS message
packages are mocked so that the handbook builds on a machine without ROS.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Every ament_python package's import root, as colcon's install or `pip install -e .` would give it.
PACKAGE_ROOTS = sorted(init.parent for init in (ROOT / "src").glob("*/*/__init__.py")
                       if init.parent.name == init.parent.parent.name)
sys.path[:0] = [str(p.parent) for p in PACKAGE_ROOTS]

project = "PRISMA Hand II + STAG glove"
author = "PRISMA Hand suite contributors"
copyright = "the PRISMA Hand suite contributors, Apache License 2.0"
release = "0.2.0"

extensions = ["myst_parser", "sphinx.ext.autodoc"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}  # .rst: the generated reference
root_doc = "index"
exclude_patterns = ["_build"]
templates_path = ["_templates"]

# The Markdown pages link each other as docs/x.md and the README's images as files.
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]


autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_typehints = "signature"  # "description" makes each type a fuzzy cross-reference search: minutes
autodoc_member_order = "bysource"
# ROS is not needed to read the modules: its Python packages are mocked.
autodoc_mock_imports = [
    "rclpy", "launch", "launch_ros", "ament_index_python", "rosidl_runtime_py",
    "action_msgs", "builtin_interfaces", "control_msgs", "diagnostic_msgs", "geometry_msgs",
    "prisma_msgs", "rcl_interfaces", "sensor_msgs", "std_msgs", "std_srvs", "visualization_msgs",
]

html_theme = "alabaster"
html_title = "PRISMA Hand suite handbook"


def docstring_as_written(app, what, name, obj, options, lines: list[str]) -> None:
    """Show each docstring as its author wrote it, in a literal block: the docstrings are plain text
    with Markdown-style `code` (not reStructuredText), and read as reST they would render wrongly
    and warn."""
    if any(line.strip() for line in lines):
        lines[:] = ["::", "", *("    " + line if line else "" for line in lines), ""]


REFERENCE = Path(__file__).resolve().parent / "api"


def reference_pages() -> dict[str, str]:
    """api/<package>.rst -> its text: the package's docstring, then every module's, with members.
    One page per package (not per module) keeps the build under half a minute on 2 cores."""
    pages = {}
    for root in PACKAGE_ROOTS:
        package = root.name
        modules = sorted(p.stem for p in root.glob("*.py") if p.stem != "__init__")
        lines = [package, "=" * len(package), "", f".. automodule:: {package}", ""]
        for module in modules:
            name = f"{package}.{module}"
            lines += [name, "-" * len(name), "", f".. automodule:: {name}", ""]
        pages[f"{package}.rst"] = "\n".join(lines)
    return pages


def write_reference(app) -> None:
    """Generated at every build from the modules in src/ (docs/api/ is not committed); a page is
    rewritten only when its text changes, so that an unchanged page is not read again."""
    REFERENCE.mkdir(exist_ok=True)
    pages = reference_pages()
    for stale in set(p.name for p in REFERENCE.glob("*.rst")) - set(pages):
        (REFERENCE / stale).unlink()
    for name, text in pages.items():
        path = REFERENCE / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def setup(app):
    app.connect("builder-inited", write_reference)
    app.connect("autodoc-process-docstring", docstring_as_written)
