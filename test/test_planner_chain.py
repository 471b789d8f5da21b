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

"""The cycle's chain of legs and rests, checked whole at its end."""

from ellipath_ros.core import planner
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import TrajectoryRejectedError
from ellipath_ros.core.joint_trajectory import validate_jtc
import numpy as np
import pytest

NAMES = ('joint_1', 'joint_2', 'joint_3')


def _at_rest(times):
    """Return a trajectory at rest at q = 0.1 rad at ``times``."""
    count = len(times)
    return JointTrajectoryData(NAMES, np.asarray(times, dtype=float), np.full((count, 3), 0.1),
                               np.zeros((count, 3)), np.zeros((count, 3)))


def test_a_chain_is_held_read_only_and_checked_whole_at_its_end():
    first = _at_rest([0.0, 0.5])
    chain = planner._hold(planner._concatenate(first, _at_rest([0.0, 0.25])), 0.1)
    np.testing.assert_array_equal(chain.time_from_start, [0.0, 0.5, 0.75, 0.85])
    for array in (chain.time_from_start, chain.positions, chain.velocities,
                  chain.accelerations):
        assert not array.flags.writeable
    validate_jtc(chain, NAMES)
    # A link whose times fall on the chain's last one (1 + 1e-300 is 1): the links are not
    # checked again, the end is, naming the point.
    broken = planner._concatenate(_at_rest([0.0, 1.0]), _at_rest([0.0, 1e-300]))
    with pytest.raises(TrajectoryRejectedError, match=r'^time_from_start\[2\]: expected a time'):
        validate_jtc(broken, NAMES)
