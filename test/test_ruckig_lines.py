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

"""The Ruckig wrapper: its pieces reach the target, and a refusal keeps Ruckig's reason."""

import threading

from ellipath_ros.core.ruckig_lines import _ruckig_rows, _ruckig_solution
import pytest


def _end_state(rows):
    duration, s, v, a, j = rows[-1]
    return (s + duration * (v + duration * (a / 2.0 + duration * j / 6.0)),
            v + duration * (a + duration * j / 2.0), a + duration * j)


def test_pieces_reach_the_target_state_within_the_limits():
    rows, why = _ruckig_solution((0.0, 0.0, 0.0), (0.1, 0.5, 2.0), 4.0, 50.0, 5000.0)
    assert why is None
    assert _end_state(rows) == pytest.approx((0.1, 0.5, 2.0), abs=1e-9)
    assert all(abs(j) <= 5000.0 * (1.0 + 1e-9) for *_, j in rows)
    assert all(abs(a) <= 50.0 * (1.0 + 1e-9) for _, _, _, a, _ in rows)


def test_a_refused_state_keeps_ruckigs_own_text():
    rows, why = _ruckig_solution((0.0, 0.0, 0.0), (0.1, 1.0, 80.0), 4.0, 50.0, 5000.0)
    assert rows is None
    # Ruckig names the offending value and the limit; the wrapper passes that on.
    assert 'acceleration' in why and '80' in why and '50' in why


def test_a_target_too_close_for_its_speed_is_refused_as_running_backwards():
    rows, why = _ruckig_solution((0.0, 0.0, 0.0), (0.001, 2.0, 0.0), 4.0, 50.0, 5000.0)
    assert rows is None and 'backwards' in why
    assert _ruckig_rows((0.0, 0.0, 0.0), (0.001, 2.0, 0.0), 4.0, 50.0, 5000.0) is None


def test_a_start_above_the_speed_limit_brakes_first_and_still_reaches_the_target():
    rows, why = _ruckig_solution((0.0, 3.0, 10.0), (0.5, 0.0, 0.0), 2.0, 20.0, 500.0)
    assert why is None
    # Ruckig's brake pieces come first: the first leaves the start state, above the limit.
    assert rows[0][1:4] == (0.0, 3.0, 10.0)
    assert _end_state(rows) == pytest.approx((0.5, 0.0, 0.0), abs=1e-9)


def test_a_solve_does_not_depend_on_the_solves_before_it():
    # Each thread reuses its Ruckig objects: after a refusal and a braking solve, a solve
    # gives what it gives as the first of a new thread.
    case = ((0.0, 0.2, -3.0), (0.1, 0.5, 2.0), 4.0, 50.0, 5000.0)
    fresh = []
    thread = threading.Thread(target=lambda: fresh.append(_ruckig_solution(*case)))
    thread.start()
    thread.join()
    assert _ruckig_solution((0.0, 0.0, 0.0), (0.1, 1.0, 80.0), 4.0, 50.0, 5000.0)[0] is None
    assert _ruckig_solution((0.0, 3.0, 10.0), (0.5, 0.0, 0.0), 2.0, 20.0, 500.0)[0]
    assert _ruckig_solution(*case) == fresh[0]
    assert fresh[0][1] is None
