import os
from glob import glob

from setuptools import find_packages, setup

package_name = "stag_glove"
# config/ lives in prisma_bringup (src/prisma_bringup/config, which it installs all of; the glove
# layout is installed here too so the glove nodes find it without prisma_bringup). colcon runs this
# file from the package directory and, with --symlink-install, from a symlink to it in build/, so
# that folder is found from this file's real location and named relative to the working directory.
BRINGUP = os.path.relpath(os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "prisma_bringup"))

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config/glove", glob(os.path.join(BRINGUP, "config", "glove", "*.yaml"))),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs pytest (setuptools >= 72 ignores tests_require)
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="STAG scalable tactile glove: readout driver, frame processing and perception networks.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "glove_driver = stag_glove.glove_driver_node:main",
            "glove_perception = stag_glove.glove_perception_node:main",
            "stag-make-dataset = stag_glove.cli:make_dataset_main",
            "stag-train-classifier = stag_glove.cli:train_classifier_main",
            "stag-train-weight = stag_glove.cli:train_weight_main",
            "stag-train-pose = stag_glove.cli:train_pose_main",
            "stag-glove-correlation = stag_glove.cli:correlation_main",
        ],
    },
)
