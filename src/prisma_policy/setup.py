from setuptools import find_packages, setup

package_name = "prisma_policy"

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
    description="prisma-policy: a behaviour-cloning policy learned from a LeRobot dataset of demonstrations, "
                "tried in the closed-loop sim against the scripted Grasp.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "prisma-policy = prisma_policy.cli:main",
            "policy = prisma_policy.policy_node:main",
        ],
    },
)
