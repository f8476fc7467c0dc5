"""Packaging for cdr_translator (ament_python; also pip-installable)."""

from glob import glob
import os

from setuptools import find_packages
from setuptools import setup

package_name = 'cdr_translator'

setup(
    name=package_name,
    version='0.1.0',
    # only the three libraries: bench/, scripts/ and tests/ are not installed
    packages=find_packages(include=['cdr_translator', 'cdr_translator.*', 'cdr_wire',
                                    'cdr_wire.*', 'msg_tools', 'msg_tools.*']),
    # the ROS 2 .msg texts cdr_wire ships (it needs no ROS message packages)
    package_data={'cdr_wire': ['msg/*/*.msg', 'py.typed'], 'msg_tools': ['py.typed'],
                  'cdr_translator': ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        (os.path.join('share', package_name), ['package.xml']),
        (os.path.join('share', package_name, 'config'), sorted(glob('config/*.yaml'))),
        # the *.launch.py files and launch_common.py, which they load by path
        (os.path.join('share', package_name, 'launch'), sorted(glob('launch/*.py'))),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'pyyaml', 'threadpoolctl'],
    zip_safe=True,
    maintainer='cdr_translator maintainers',
    maintainer_email='maintainers@example.com',
    description=(
        'Cosserat-rod kinestatic solver and ROS 2 node for the dual-continuum-joint '
        'translator leg of a Continuum Delta Robot.'
    ),
    license='Apache-2.0',
    # the robot atlas (cdr_translator/robot/atlas.py) only; make setup installs them
    extras_require={'test': ['pytest'],
                    'atlas': ['dask', 'distributed', 'xarray', 'zarr', 'tqdm', 'matplotlib']},
    entry_points={
        'console_scripts': [
            'translator_node = cdr_translator.ros.translator_node:main',
            'cdr_node = cdr_translator.ros.cdr_node:main',
        ],
    },
)
