import os

from setuptools import find_packages, setup

package_name = "prisma_bringup"
# launch/ and config/ live beside this file. colcon runs it from the package directory and, with
# --symlink-install, from a symlink to it in build/, so the folder is found from this file's real
# location and named relative to the working directory.
ROOT = os.path.relpath(os.path.dirname(os.path.realpath(__file__)))


def share_tree(directory: str) -> list[tuple[str, list[str]]]:
    """data_files entries installing ROOT/directory, subfolders included, under share/<package>/."""
    entries = []
    for folder, subfolders, files in os.walk(os.path.join(ROOT, directory)):
        subfolders[:] = sorted(d for d in subfolders if not d.startswith((".", "__")))
        files = sorted(f for f in files if not f.startswith(".") and not f.endswith(".pyc"))
        if files:
            destination = os.path.join("share", package_name, os.path.relpath(folder, ROOT))
            entries.append((destination, [os.path.join(folder, f) for f in files]))
    return entries


setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ] + share_tree("launch") + share_tree("config"),
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs pytest (setuptools >= 72 ignores tests_require)
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="Launch files, node configuration and model bundles, and prisma-doctor (the bring-up check).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "prisma-doctor = prisma_bringup.doctor:main",
            "doctor = prisma_bringup.doctor:main",  # ros2 run prisma_bringup doctor
        ],
    },
)
