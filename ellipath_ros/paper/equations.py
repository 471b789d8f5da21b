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
The paper's own closed forms for the axes and the apex (eqs. 15-25).

The planner works with the conjugate semi-diameter form of
:mod:`ellipath_ros.core.geometry`, which has no 0/0 at h = 0; these equations
are kept to reproduce the paper's printed numbers and its Figure 2, and the
tests check that both forms agree.
"""

import math

import numpy as np


def paper_axes(half_width, h, phi):
    """
    Return (a, b) of the ellipse of angle ``phi`` by the paper's eqs. (15)-(20).

    Valid for phi strictly beyond the critical angle (D, E != 0); used to
    reproduce the paper and for its Figure 2.
    """
    s, c = math.sin(phi), math.cos(phi)
    d = half_width * math.sin(2 * phi) + 2 * h * s * s
    e = half_width * math.sin(2 * phi) - 2 * h * c * c
    f = half_width * half_width * s * s - h * h * c * c
    g = half_width * half_width * c * c - h * h * s * s
    return math.sqrt(d * f / e + g), math.sqrt(f + e * g / d)


def paper_apex(a, b, phi):
    """
    Return the apex (x*, y*) by the paper's eqs. (21)-(25), as a (2,) array.

    Eq. (24) gives tan(theta*); of its two solutions we take the upper one.
    """
    big_a = math.cos(phi) ** 2 / a ** 2 + math.sin(phi) ** 2 / b ** 2
    big_b = math.sin(2 * phi) / a ** 2 - math.sin(2 * phi) / b ** 2
    theta = math.atan((2 * big_a * a * math.cos(phi) + big_b * a * math.sin(phi))
                      / (2 * big_a * b * math.sin(phi) - big_b * b * math.cos(phi)))
    candidates = []
    for candidate in (theta, theta + math.pi):
        candidates.append((
            a * math.cos(phi) * math.cos(candidate) - b * math.sin(phi) * math.sin(candidate),
            a * math.sin(phi) * math.cos(candidate) + b * math.cos(phi) * math.sin(candidate)))
    return np.array(max(candidates, key=lambda point: point[1]))
