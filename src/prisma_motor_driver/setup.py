from setuptools import find_packages, setup

package_name = "prisma_motor_driver"

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
    description="Dynamixel and simulated motors: Protocol 2.0 codec, bus, servo emulator, motor driver core and node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "motor_driver = prisma_motor_driver.motor_driver_node:main",
        ],
    },
)
