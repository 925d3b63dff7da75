from glob import glob
import os

from setuptools import find_packages, setup

package_name = "stag_glove"
# config/ lives at the workspace root, beside src/ (the node YAML and model bundles are installed
# by prisma_bringup; the glove layout is installed here).
ROOT = os.path.join("..", "..")

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config/glove", glob(os.path.join(ROOT, "config", "glove", "*.yaml"))),
    ],
    install_requires=["setuptools"],
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
