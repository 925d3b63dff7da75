from setuptools import find_packages, setup

package_name = "prisma_visualization"

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
    description="RViz views of the hand: the fingertip taxels, contact and force drawn on the model, the fingers "
                "drawn where the tendons let them under load.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "tactile_markers = prisma_visualization.tactile_markers_node:main",
            "tendon_stretch = prisma_visualization.tendon_stretch_node:main",
        ],
    },
)
