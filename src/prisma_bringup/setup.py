from glob import glob
import os

from setuptools import find_packages, setup

package_name = "prisma_bringup"
# launch/ and config/ live at the workspace root, beside src/.
ROOT = os.path.join("..", "..")

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", glob(os.path.join(ROOT, "launch", "*.launch.py"))),
        ("share/" + package_name + "/config", glob(os.path.join(ROOT, "config", "*.yaml"))),
    ] + [
        ("share/" + package_name + "/config/models/" + os.path.basename(bundle), glob(os.path.join(bundle, "*")))
        for bundle in sorted(glob(os.path.join(ROOT, "config", "models", "*")))
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="Launch files, off-robot closed-loop simulation runner and bag tools.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "prisma-sim = prisma_bringup.sim_cli:main",
        ],
    },
)
