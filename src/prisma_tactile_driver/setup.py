from setuptools import find_packages, setup

package_name = "prisma_tactile_driver"

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
    description="Fingertip sensor hub driver: Arduino serial, direct I2C and simulated backends.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "tactile_driver = prisma_tactile_driver.tactile_driver_node:main",
            "prisma-tactile-calset = prisma_tactile_driver.cli:calset_main",
            "prisma-tactile-pad-plot = prisma_tactile_driver.cli:pad_plot_main",
            "prisma-tactile-hub-emulator = prisma_tactile_driver.cli:hub_emulator_main",
        ],
    },
)
