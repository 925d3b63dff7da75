"""Release metadata of every package (each package.xml under src/ and test/integration, found, not
listed): the Apache-2.0 LICENSE at the root and named by every package, one version number across
package.xml, setup.cfg and pyproject.toml, and a CHANGELOG.rst per package in the format
`catkin_generate_changelog` writes (REP 132), its newest section that version."""
from __future__ import annotations

import hashlib
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from setuptools.config.setupcfg import read_configuration

from prisma_testing.repo_paths import ROOT

PACKAGES = sorted([p.parent for p in (ROOT / "src").glob("*/package.xml")] + [ROOT / "test" / "integration"])
# sha256 of https://www.apache.org/licenses/LICENSE-2.0.txt, as colcon and trio ship it
APACHE_2_0_SHA256 = "cfc7749b96f63bd31c3c42b5c471bf756814053e847c10f3eb003417bc523d30"
SECTION = re.compile(r"^(\d+\.\d+\.\d+) \((\d{4}-\d{2}-\d{2})\)$")


def package_name(folder: Path) -> str:
    return ET.parse(folder / "package.xml").getroot().findtext("name")


def setup_metadata(folder: Path, key: str) -> str | None:
    """[metadata] key of folder/setup.cfg, where a Python package declares itself (None for a package
    with none: prisma_msgs, an ament_cmake package)."""
    if not (folder / "setup.cfg").is_file():
        return None
    return read_configuration(folder / "setup.cfg")["metadata"].get(key)


def pyproject() -> dict:
    tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def test_every_package_is_found():
    names = {package_name(p) for p in PACKAGES}
    assert {"prisma_msgs", "prisma_common", "prisma_node_wiring", "prisma_bringup", "stag_glove",
            "prisma_integration_tests"} <= names and len(names) == len(PACKAGES)


def test_license_at_the_root_is_the_apache_2_0_text():
    text = (ROOT / "LICENSE").read_text()
    assert text.split()[:4] == ["Apache", "License", "Version", "2.0,"]
    assert "END OF TERMS AND CONDITIONS" in text
    assert hashlib.sha256(text.encode()).hexdigest() == APACHE_2_0_SHA256, "LICENSE differs from the canonical text"


@pytest.mark.parametrize("folder", PACKAGES, ids=lambda p: p.name)
def test_every_package_names_the_license(folder):
    licenses = [e.text for e in ET.parse(folder / "package.xml").getroot().iter("license")]
    assert licenses == ["Apache-2.0"]
    assert setup_metadata(folder, "license") in ("Apache-2.0", None)


def test_pyproject_names_the_license():
    assert pyproject()["license"] == {"text": "Apache-2.0"}


def versions() -> dict[str, str]:
    """Where a version is written -> the version."""
    found = {"pyproject.toml": pyproject()["version"]}
    for folder in PACKAGES:
        where = folder.relative_to(ROOT)
        found[f"{where}/package.xml"] = ET.parse(folder / "package.xml").getroot().findtext("version")
        setup_version = setup_metadata(folder, "version")
        if setup_version is not None:
            found[f"{where}/setup.cfg"] = setup_version
    return found


def test_one_version_number_everywhere():
    found = versions()
    assert len(found) >= 2 * len(PACKAGES)  # every package.xml, the setup.cfg files and pyproject.toml
    assert len(set(found.values())) == 1, found
    assert re.fullmatch(r"\d+\.\d+\.\d+", found["pyproject.toml"])


@pytest.mark.parametrize("folder", PACKAGES, ids=lambda p: p.name)
def test_every_package_has_a_changelog_whose_newest_section_is_its_version(folder):
    path = folder / "CHANGELOG.rst"
    assert path.is_file(), f"{path.relative_to(ROOT)} missing (catkin_generate_changelog writes it)"
    lines = path.read_text().splitlines()
    title = f"Changelog for package {package_name(folder)}"
    assert lines[:4] == ["^" * len(title), title, "^" * len(title), ""]
    sections = [(i, SECTION.match(line)) for i, line in enumerate(lines) if SECTION.match(line)]
    assert sections, f"{path.relative_to(ROOT)}: no 'X.Y.Z (YYYY-MM-DD)' section"
    for index, match in sections:
        assert lines[index + 1] == "-" * len(lines[index]), f"{path.relative_to(ROOT)}:{index + 2}: underline"
        bullets = []
        for line in lines[index + 2:]:
            if SECTION.match(line):
                break
            if line.startswith("* "):
                bullets.append(line)
        assert bullets, f"{path.relative_to(ROOT)}: section {match.group(1)} lists no change"
    numbers = [tuple(int(n) for n in m.group(1).split(".")) for _, m in sections]
    assert numbers == sorted(numbers, reverse=True), "newest section first"
    assert sections[0][1].group(1) == versions()["pyproject.toml"]
