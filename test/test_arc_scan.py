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

"""The path-space scan's shortcuts give exactly what the plain computations give."""

from ellipath_ros.core import optimal_profile
from ellipath_ros.core.arc_scan import _Scan
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.limits import CartesianLimits
import numpy as np


def _bisected_time(scan, s_query):
    """Return the time at s_query by 60 bisections through ``state`` (the plain reference)."""
    index = min(max(int(np.searchsorted(scan.s, s_query, side='right')) - 1, 0),
                len(scan.j) - 1)
    low, high = scan.t[index], scan.t[min(index + 1, len(scan.t) - 1)]
    for _ in range(60):
        middle = 0.5 * (low + high)
        if scan.state(middle)[0] < s_query:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def _constructed_scan(seed):
    """Return a scan of random constant-jerk pieces, states chained exactly as a scan's."""
    rng = np.random.default_rng(seed)
    scan = _Scan(0.0, 0.5, 0.0, 1.0)
    for _ in range(40):
        h, jerk = rng.uniform(2e-5, 1e-3), rng.uniform(-2000.0, 2000.0)
        s, v, a = scan.s[-1], scan.v[-1], scan.a[-1]
        scan.t.append(scan.t[-1] + h)
        scan.s.append(s + h * (v + h * (a / 2.0 + h * jerk / 6.0)))
        scan.v.append(v + h * (a + h * jerk / 2.0))
        scan.a.append(a + h * jerk)
        scan.j.append(jerk)
    return scan


def test_time_at_is_the_plain_bisection_to_the_last_bit():
    for seed in range(5):
        scan = _constructed_scan(seed)
        queries = np.concatenate((scan.s, np.linspace(scan.s[0], scan.s[-1], 97)[1:-1]))
        for s_query in queries:
            assert scan.time_at(s_query) == _bisected_time(scan, s_query)


def _forward_scan(path, forget_readings):
    """Return the forward scan of the whole arc from rest speed 0.3 m/s (until it stops)."""
    planner = optimal_profile._ArcPlanner(path, CartesianLimits(), None)
    scan = _Scan(0.0, 0.3, 0.0, planner.length)
    while True:
        if forget_readings:
            scan.reading = None
        if not planner.forward.advance(scan):
            return scan


def test_a_step_starts_from_the_reading_the_table_gives():
    # Each step hands its end state's table reading to the next: the same states result as
    # when every step reads the table afresh.
    for path in (plan_path([0, 0, -0.8], [0.3, 0, -0.75]),
                 plan_path([0.1, -0.05, -0.9], [-0.15, 0.1, -0.78])):
        carried, fresh = _forward_scan(path, False), _forward_scan(path, True)
        assert len(carried.s) > 100
        for name in ('t', 's', 'v', 'a', 'j'):
            assert getattr(carried, name) == getattr(fresh, name)
        assert carried.status == fresh.status
