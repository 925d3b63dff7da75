import os

from setuptools import setup

package_name = "prisma_description"
# urdf/, launch/ and rviz/ live beside this file; colcon runs it from the package directory or, with
# --symlink-install, from a symlink to it in build/
ROOT = os.path.relpath(os.path.dirname(os.path.realpath(__file__)))


def share_folder(directory: str) -> tuple[str, list[str]]:
    """data_files entry installing ROOT/directory's files under share/<package>/directory."""
    folder = os.path.join(ROOT, directory)
    files = sorted(f for f in os.listdir(folder) if not f.startswith("."))
    return os.path.join("share", package_name, directory), [os.path.join(folder, f) for f in files]


setup(
    name=package_name,
    version="0.2.0",
    packages=[],
    data_files=[
        ("share/ament_index/resource_index/packages", [os.path.join(ROOT, "resource", package_name)]),
        ("share/" + package_name, [os.path.join(ROOT, "package.xml")]),
        share_folder("urdf"), share_folder("launch"), share_folder("rviz"),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="PRISMA Hand II robot description: URDF/xacro, display launch file.",
    license="Apache-2.0",
)
