from setuptools import find_packages, setup

package_name = "prisma_force_estimator"

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
    description="Neural taxel-to-wrench estimation: training, evaluation and inference node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "force_estimator = prisma_force_estimator.force_estimator_node:main",
            "prisma-train-force = prisma_force_estimator.cli:train_main",
            "prisma-eval-force = prisma_force_estimator.cli:eval_main",
            "prisma-estimate-bag = prisma_force_estimator.cli:estimate_bag_main",
        ],
    },
)
