# The package is declared in setup.cfg; colcon's ament_python build still runs this file.
from setuptools import setup

setup()
