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

"""
Start ellipath_node with the package's default parameters (config/ellipath.yaml).

    ros2 launch ellipath_ros ellipath.launch.py
    ros2 launch ellipath_ros ellipath.launch.py \
        trajectory_topic:=/delta_controller/joint_trajectory params_file:=/path/to/my.yaml

Needs ros2launch (part of a ROS 2 Jazzy install, not of the pip-only setup; there, run
``ellipath_node --ros-args --params-file config/ellipath.yaml`` instead).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    """Return the launch description: one ellipath_node and its two arguments."""
    default_params = os.path.join(
        get_package_share_directory('ellipath_ros'), 'config', 'ellipath.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value=default_params,
            description='Parameter file of ellipath_node'),
        DeclareLaunchArgument(
            'trajectory_topic', default_value='joint_trajectory',
            description="Topic of the joint_trajectory_controller's trajectory input"),
        Node(
            package='ellipath_ros',
            executable='ellipath_node',
            name='ellipath_node',
            parameters=[LaunchConfiguration('params_file')],
            remappings=[('joint_trajectory', LaunchConfiguration('trajectory_topic'))],
            output='screen',
        ),
    ])
