from setuptools import find_packages, setup

package_name = "prisma_teleop"

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},  # colcon test runs pytest (setuptools >= 72 ignores tests_require)
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="Teleoperation: a hand-pose glove retargeted onto the hand's three motors, the STAG glove's poses "
                "onto its grasps, through the manipulation node's touch-limited goals.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "teleop = prisma_teleop.teleop_node:main",
            "synthetic_glove = prisma_teleop.synthetic_glove_node:main",
            "prisma-teleop-stag-session = prisma_teleop.cli:stag_session_main",
        ],
    },
)
