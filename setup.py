# Copyright 2026 The ellipath_ros authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""Install ellipath_ros: the planning core, the CLI and the ROS 2 node."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ellipath_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    python_requires='>=3.10',
    install_requires=['setuptools', 'numpy', 'numba>=0.59', 'ruckig>=0.12'],
    extras_require={
        'plot': ['matplotlib>=3.5'],
        'bench': ['toppra>=0.6'],
        'test': ['pytest', 'pytest-timeout', 'hypothesis'],
    },
    zip_safe=True,
    maintainer='ellipath_ros maintainers',
    maintainer_email='maintainers@ellipath.invalid',
    description='Elliptical pick-and-place trajectory planner for Delta robots (ROS 2 Jazzy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'ellipath = ellipath_ros.cli:main',
            'ellipath_node = ellipath_ros.node_entry:main',
        ],
    },
)
