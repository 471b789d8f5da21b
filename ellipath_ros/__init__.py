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
Elliptical pick-and-place trajectory planning for Delta robots (Choe et al., 2023).

* ``ellipath_ros.core``: the ROS-free planner (NumPy and Ruckig); its public API
  is ``ellipath_ros.core.__all__``.
* ``ellipath_ros.paper``: the paper's own equations, Figure 8 comparison paths
  and figures; the planner never imports it.
* ``parameters``, ``conversions``, ``node``: the ROS 2 layer (``ellipath_node``).
* ``cli``, ``demo``, ``bench``: the front ends (the ``ellipath`` command).
"""

__version__ = '0.1.0'
