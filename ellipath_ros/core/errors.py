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
Exception hierarchy of the planning core and small input validators.

Every error carries a short machine-readable ``kind`` (used by the CLI's JSON
error object and the node's diagnostics) and a message of the form
"<name>: expected <allowed>, got <value>".
"""

import math

import numpy as np


class EllipathError(Exception):
    """Base class of every error the planner raises on purpose."""

    kind = 'error'


class InvalidInputError(EllipathError, ValueError):
    """A value is malformed: NaN, infinite, out of its allowed range."""

    kind = 'invalid_input'


class DegenerateGeometryError(EllipathError, ValueError):
    """The pick/place geometry admits no path of the requested kind."""

    kind = 'degenerate_geometry'


class UnreachableError(EllipathError):
    """A point of the motion lies outside the robot's workspace or joint range."""

    kind = 'unreachable'


class LimitError(EllipathError):
    """A planned motion would break a velocity, acceleration or jerk limit."""

    kind = 'limit'


class WorkspaceError(EllipathError):
    """A point of the motion lies outside the safe workspace or inside a keep-out box."""

    kind = 'workspace'


class MissedError(EllipathError):
    """A belt object leaves the tracking window before the robot can be on it."""

    kind = 'missed'


class LateReleaseError(EllipathError):
    """A belt pick's stamp was past, or too close, every time it was about to be published."""

    kind = 'late'


def require_finite(name, value):
    """Return ``value`` as float, or raise if it is not a finite number."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name}: expected a finite number, got {value!r}') from None
    if not math.isfinite(number):
        raise InvalidInputError(f'{name}: expected a finite number, got {number!r}')
    return number


def require_range(name, value, low=-math.inf, high=math.inf, *, low_open=False,
                  high_open=False, unit=''):
    """
    Return ``value`` as float, or raise if it is not finite and within the range.

    Parameters
    ----------
    name : str
        Name of the value, used in the message.
    value : float
        The value to check.
    low, high : float
        Bounds of the allowed range.
    low_open, high_open : bool
        Whether the bound itself is excluded.
    unit : str
        Unit shown in the message, e.g. ``'m'``.

    """
    number = require_finite(name, value)
    too_low = number <= low if low_open else number < low
    too_high = number >= high if high_open else number > high
    if too_low or too_high:
        left = '(' if low_open else '['
        right = ')' if high_open else ']'
        suffix = f' {unit}' if unit else ''
        raise InvalidInputError(
            f'{name}: expected a value in {left}{low:g}, {high:g}{right}{suffix}, '
            f'got {number!r}')
    return number


def require_point(name, value):
    """Return ``value`` as a float array of shape (3,), or raise naming the bad entry."""
    try:
        point = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name}: expected 3 finite numbers, got {value!r}') from None
    if point.shape != (3,):
        raise InvalidInputError(
            f'{name}: expected 3 coordinates (x, y, z), got shape {point.shape}')
    # Three floats tested one by one: np.all(np.isfinite(point)) cost ten times as much.
    x, y, z = point.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise InvalidInputError(f'{name}: expected finite coordinates, got {[x, y, z]}')
    return point
