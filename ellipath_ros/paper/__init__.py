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
The paper's own material, outside the planner: Choe et al. (2023) reproduced.

The paper's closed forms for the axes and the apex (``equations``), the
comparison paths of its Figure 8 (``comparison``) and its figures
(``plotting``, which needs the ``plot`` extra: matplotlib is imported only
when a figure is drawn). The planner (:mod:`ellipath_ros.core`) never
imports this package; docs/paper_reproduction.md sets its numbers beside the
paper's.
"""

from ellipath_ros.paper.comparison import (
    ComparisonPath, figure8_paths, half_ellipse_length, lame_path, lame_quarter_length,
    lame_quarter_points, proposed_path, symmetric_ellipse_path)
from ellipath_ros.paper.equations import paper_apex, paper_axes
from ellipath_ros.paper.plotting import radius_of_curvature_derivatives, write_figures

__all__ = [
    'ComparisonPath',
    'figure8_paths',
    'half_ellipse_length',
    'lame_path',
    'lame_quarter_length',
    'lame_quarter_points',
    'paper_apex',
    'paper_axes',
    'proposed_path',
    'radius_of_curvature_derivatives',
    'symmetric_ellipse_path',
    'write_figures',
]
