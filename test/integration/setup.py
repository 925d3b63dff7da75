from setuptools import setup

package_name = "prisma_integration_tests"

# A test-only package, as ros2/system_tests' are: it exists so that `colcon test` runs the tests
# in this folder (pytest in this directory, configured by the repository's pyproject.toml).
setup(
    name=package_name,
    version="0.2.0",
    packages=[],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},
    zip_safe=True,
    maintainer="PRISMA developers",
    maintainer_email="dev@prisma-hand.org",
    description="Cross-package, node, launch and bag tests of the PRISMA hand and STAG glove suite.",
    license="Apache-2.0",
)
