from setuptools import find_packages, setup

package_name = "prisma_node_wiring"

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
    description="The rclpy wiring every node shares: the node process and the sample-stream endpoints.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [],
    },
)
