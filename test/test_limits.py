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

"""The speed cap's check (positive, finite, the right shape) and the stretches' even samples."""

import math

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.limits import _cap_values, _even_samples
import numpy as np
import pytest

_S = np.linspace(0.0, 0.3, 129)


@pytest.mark.parametrize('bad', [0.0, -0.0, -1.0, math.nan, math.inf, -math.inf])
@pytest.mark.parametrize('where', [0, 64, 128])
def test_one_bad_speed_among_good_ones_is_refused(bad, where):
    values = np.full(_S.shape, 2.0)
    values[where] = bad
    # The message names the first bad speed and where it is.
    with pytest.raises(InvalidInputError, match=(
            rf'^speed_cap: expected positive finite .* got {bad} at s = {_S[where]:.6g} m '
            rf'\(sample {where} of {_S.size}\)$')):
        _cap_values(lambda s: values, _S)


def test_a_wrong_shape_is_refused_and_good_speeds_pass_as_floats():
    with pytest.raises(InvalidInputError, match=r'got shape \(3,\)'):
        _cap_values(lambda s: np.ones(3), _S)
    single = (1.0 + _S).astype(np.float32)
    speeds = _cap_values(lambda s: single, _S)
    assert speeds.dtype == np.float64 and np.array_equal(speeds, single)
    assert _cap_values(lambda s: [], np.empty(0)).shape == (0,)


def test_even_samples_are_numpys_linspace_to_the_last_bit():
    rng = np.random.default_rng(11)
    cases = [(0.0, 0.3, 129), (0.3, 0.0, 129), (-0.2, 0.7, 2049), (1.0, 1.0, 5), (0.0, 5e-324, 9),
             (0.0, 1e-310, 3), (-1e-320, 1e-320, 4), (0.0, 1.0, 2)]
    cases += [(*rng.uniform(-2.0, 2.0, 2), int(rng.integers(2, 5000))) for _ in range(200)]
    for start, stop, count in cases:
        expected = np.linspace(start, stop, count)
        for even_samples in (_even_samples, _even_samples.py_func):
            assert even_samples(start, stop, count).tobytes() == expected.tobytes(), (
                start, stop, count)
