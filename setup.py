# The Python package bimanual_skills (python/bimanual_skills): the C++ core's bindings (_core, built by CMake with
# pybind11) beside the ROS messages genpy puts into the same package. catkin_python_setup() in CMakeLists.txt uses
# this file; nothing else calls it.
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["bimanual_skills"], package_dir={"": "python"}))
