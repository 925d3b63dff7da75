from setuptools import find_packages, setup

package_name = "prisma_hand_emulator"

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
    description="The hand's hardware emulated in one process (hand.launch.py hardware:=emulated): Dynamixel "
                "servos and the fingertip hub on ptys or the pads' I2C bus on a socket, from one hand/world "
                "model, with faults injected over a control socket.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "prisma-hand-emulator = prisma_hand_emulator.emulator_cli:emulator_main",
            "prisma-hand-fault = prisma_hand_emulator.emulator_cli:fault_main",
        ],
    },
)
