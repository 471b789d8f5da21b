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
Limits of the TCP motion, the share of them the timing constructions aim at, the speed cap.

The constructions aim at ``_*_MARGIN`` of the limits; the rest absorbs what
happens between the steps they are built from (the final check in
:func:`~ellipath_ros.core.timing.time_motion` samples the continuous motion).
"""

from dataclasses import dataclass
import math

import numpy as np

from .compiled import kernel
from .errors import InvalidInputError
from .settings import default_of, validate_fields

# The construction aims at these fractions of the limits; the rest absorbs what happens
# between the steps it is built from (the final check samples the continuous motion).
_SPEED_MARGIN = 0.999
_ACCEL_MARGIN = 0.995
_JERK_MARGIN = 0.995
# Samples of a stretch for constant limits that hold all along it (plus the tightest point).
_LIMIT_SAMPLES = 129


@dataclass(frozen=True)
class CartesianLimits:
    """
    Limits of the TCP motion.

    Attributes
    ----------
    max_speed : float
        Largest TCP speed [m/s], > 0.
    max_accel : float
        Largest norm of the TCP acceleration vector [m/s**2], > 0; the normal
        part v**2 kappa counts.
    max_jerk : float
        Largest norm of the TCP jerk vector [m/s**3], > 0.
    max_accel_jump : float
        Largest step of the acceleration vector at T1 and T2 [m/s**2], >= 0.
        The curvature jumps from 0 (line) to 1/rho_T (arc end) there, so the
        normal acceleration steps by v**2 / rho_T; a step in commanded
        acceleration is a step in motor torque, which excites the arms. The
        default, 25 m/s**2 (half of ``max_accel``), keeps that step moderate
        and costs little: it caps the speed at T1/T2 at sqrt(25 rho_T)
        (0.46 m/s on the paper's example) where the curvature limit alone
        allows about 0.65 m/s. 0 makes the motion stop at T1 and T2.

    """

    max_speed: float = default_of('max_speed')
    max_accel: float = default_of('max_accel')
    max_jerk: float = default_of('max_jerk')
    max_accel_jump: float = default_of('max_accel_jump')

    def __post_init__(self):
        # Practical ranges (core/settings.py): beyond them a motion lasts hours or the
        # arithmetic overflows.
        validate_fields(self)


def _cap_values(speed_cap, s):
    """Call the speed cap on path lengths ``s`` (N,) and check the answer."""
    values = np.asarray(speed_cap(s), dtype=float)
    expected = f'speed_cap: expected positive finite speeds of shape {s.shape} [m/s], got'
    if values.shape != s.shape:
        raise InvalidInputError(f'{expected} shape {values.shape}')
    # All positive and finite: the smallest above 0 (NaN where any is NaN, which fails) and
    # the largest below inf, two reductions instead of two comparisons and two np.all.
    if values.size and not (values.min() > 0.0 and values.max() < math.inf):
        bad = int(np.flatnonzero(~((values > 0.0) & (values < math.inf)))[0])
        raise InvalidInputError(f'{expected} {values[bad]} at s = {s[bad]:.6g} m (sample '
                                f'{bad} of {s.size})')
    return values


@kernel
def _even_samples(start, stop, count):
    """
    Return ``numpy.linspace(start, stop, count)`` (count >= 2), computed as it does.

    Each sample is index * step + start (index / (count - 1) * (stop - start) + start where
    the step rounds to 0), the last ``stop``: the same roundings, a few microseconds less
    per call (NumPy's checks and conversions) where the stretches' samples are asked for.
    """
    samples = np.empty(count)
    delta = stop - start
    divisor = count - 1
    step = delta / divisor
    for index in range(count):
        if step == 0.0:
            samples[index] = index / divisor * delta + start
        else:
            samples[index] = index * step + start
    samples[count - 1] = stop
    return samples
