# Used by catkin_python_setup(); not for pip install.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["cottonsim_perception", "cottonsim_perception.ros"], package_dir={"": "src"}))
