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
The safe workspace: where the TCP may go, like an industrial controller's safe zone.

A vertical cylinder around the base axis (``radius``, ``z_min`` to ``z_max``) the TCP must
stay in, minus axis-aligned keep-out boxes (a conveyor frame, a bin wall) it must not enter.
The allowed set is closed: the cylinder's surface and the boxes' faces may be touched, so a
pick lying on a conveyor can be the top face of the conveyor's box. The TCP is a point: make
the boxes larger by the size of the tool.

The default cylinder (radius 0.4 m, z from -1.0 to -0.55 m) is the useful workspace of the
default robot (``DeltaGeometry``): its joint limits reach all of it with a margin.
"""

from dataclasses import dataclass
import math
import numbers

import numpy as np

from .compiled import kernel
from .errors import InvalidInputError, WorkspaceError
from .settings import default_of, SETTING_BY_NAME, validate_fields

# Default tolerance of the comparisons [m]: forward kinematics of inverse kinematics returns
# a point within ~1e-15 m, so a place on the boundary must not count as outside. Nothing
# physical; the planner allows the executed motion more (see planner.py).
_TOLERANCE = 1e-9
_BOX_FIELDS = ('xmin', 'ymin', 'zmin', 'xmax', 'ymax', 'zmax')


def _fmt(values):
    """Format numbers as ``(a, b, c)`` for messages."""
    return '(' + ', '.join(f'{value:.6g}' for value in values) + ')'


def boxes_from_flat(values, name='keep_out_boxes'):
    """
    Return keep-out boxes from a flat list of 6 numbers per box, validated.

    Parameters
    ----------
    values : sequence of float, or sequence of sequences of 6 floats
        ``[xmin, ymin, zmin, xmax, ymax, zmax]`` per box [m], flat or grouped by box.
    name : str
        Name used in error messages.

    Returns
    -------
    tuple of tuple of float
        One 6-tuple per box.

    Raises
    ------
    InvalidInputError
        Not numbers, a length that is not a multiple of 6, a non-finite value or a box
        whose minimum is not below its maximum on some axis; the message names it.

    """
    if values is None:
        return ()
    if isinstance(values, (str, bytes)) or not hasattr(values, '__len__'):
        raise InvalidInputError(
            f'{name}: expected a flat list of 6 numbers per box, got {values!r}')
    flat = []
    for item in values:
        if hasattr(item, '__len__') and not isinstance(item, (str, bytes)):
            flat.extend(item)
        else:
            flat.append(item)
    if len(flat) % len(_BOX_FIELDS):
        raise InvalidInputError(
            f'{name}: expected a multiple of 6 values ([xmin, ymin, zmin, xmax, ymax, zmax] '
            f'per box), got {len(flat)} values')
    coordinates = []
    for index, value in enumerate(flat):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise InvalidInputError(f'{name}[{index}]: expected a number, got {value!r}')
        coordinates.append(SETTING_BY_NAME['keep_out_boxes'].check_number(
            value, f'{name}[{index}]'))
    boxes = tuple(tuple(coordinates[start:start + 6])
                  for start in range(0, len(coordinates), 6))
    for index, box in enumerate(boxes):
        for axis in range(3):
            if not box[axis] < box[axis + 3]:
                low, high = _BOX_FIELDS[axis], _BOX_FIELDS[axis + 3]
                raise InvalidInputError(
                    f'{name}[{index}]: expected {low} < {high}, '
                    f'got {box[axis]:g} and {box[axis + 3]:g} m')
    return boxes


@dataclass(frozen=True)
class SafeWorkspace:
    """
    Where the TCP may be: a vertical cylinder about the base axis, minus keep-out boxes.

    Parameters
    ----------
    radius : float
        Largest distance of the TCP from the base axis (the z axis) [m]
        (``workspace_radius`` in :mod:`.settings`, as the ranges of all fields).
    z_min, z_max : float
        Lowest and highest TCP height [m], ``z_min < z_max``.
    keep_out_boxes : sequence
        Axis-aligned boxes the TCP must not enter, ``[xmin, ymin, zmin, xmax, ymax, zmax]``
        each [m], flat (6 numbers per box) or grouped; stored as a tuple of 6-tuples.

    """

    radius: float = default_of('workspace_radius')
    z_min: float = default_of('workspace_z_min')
    z_max: float = default_of('workspace_z_max')
    keep_out_boxes: tuple = default_of('keep_out_boxes')

    def __post_init__(self):
        """Check the bounds and store them as floats, the boxes as a tuple of 6-tuples."""
        validate_fields(self)
        if not self.z_min < self.z_max:
            raise InvalidInputError(
                f'workspace_z_max: expected a value > workspace_z_min = {self.z_min:g} m, '
                f'got {self.z_max:g} m')
        object.__setattr__(self, 'keep_out_boxes', boxes_from_flat(self.keep_out_boxes))

    def describe(self):
        """Return the allowed set in words, for messages."""
        text = (f'r <= {self.radius:g} m from the z axis, z in [{self.z_min:g}, '
                f'{self.z_max:g}] m')
        if self.keep_out_boxes:
            text += f', outside {len(self.keep_out_boxes)} keep-out box(es)'
        return text

    def contains(self, points, tolerance=_TOLERANCE):
        """
        Tell, point by point, whether the TCP may be there.

        Parameters
        ----------
        points : array_like, shape (N, 3) or (3,)
            TCP positions [m]; non-finite rows are outside.
        tolerance : float
            How far beyond a bound or into a box a point still counts as inside [m].

        Returns
        -------
        numpy.ndarray of bool, shape (N,) or ()

        """
        array = np.asarray(points, dtype=float)
        single = array.ndim == 1
        array = np.ascontiguousarray(np.atleast_2d(array))
        ok = np.empty(array.shape[0], dtype=np.bool_)
        _inside_rows(array, self.radius, self.z_min, self.z_max, self.box_table(),
                     float(tolerance), ok)
        return ok[0] if single else ok

    def box_table(self):
        """Return the keep-out boxes as an array (B, 6), the form :func:`inside` takes."""
        return np.array(self.keep_out_boxes, dtype=float).reshape(-1, len(_BOX_FIELDS))

    def check(self, points, name='points', times=None, tolerance=_TOLERANCE):
        """
        Raise :class:`WorkspaceError` naming the first point outside the safe workspace.

        Parameters
        ----------
        points : array_like, shape (N, 3) or (3,)
            TCP positions [m], in time order.
        name : str
            What the points are, for the message (e.g. ``'place'``).
        times : array_like, shape (N,), optional
            Time of each point [s], named in the message.
        tolerance : float
            How far beyond a bound or into a box a point still counts as inside [m].

        Raises
        ------
        WorkspaceError
            With attributes ``index`` (of the first offending point) and ``time`` (its time,
            or None); the message names the point, its time and the bound or box it breaks.

        """
        array = np.asarray(points, dtype=float)
        single = array.ndim == 1
        array = np.atleast_2d(array)
        ok = self.contains(array, tolerance)
        if ok.all():
            return
        index = int(np.argmin(ok))
        point = array[index]
        time = None if times is None else float(np.asarray(times)[index])
        where = name if single else f'{name}[{index}]'
        if time is not None:
            where += f' at t = {time:.4f} s'
        error = WorkspaceError(
            f'{where}: expected a point within the safe workspace ({self.describe()}), '
            f'got {_fmt(point)} m: {self._reason(point, tolerance)}')
        error.index = index
        error.time = time
        raise error

    def _reason(self, point, tolerance):
        """Return which bound or box ``point`` breaks, in words."""
        if not np.isfinite(point).all():
            return 'not finite'
        radial = math.hypot(point[0], point[1])
        if point[2] > self.z_max + tolerance:
            return f'above workspace_z_max = {self.z_max:g} m by {point[2] - self.z_max:.4g} m'
        if point[2] < self.z_min - tolerance:
            return f'below workspace_z_min = {self.z_min:g} m by {self.z_min - point[2]:.4g} m'
        if radial > self.radius + tolerance:
            return (f'{radial:.6g} m from the z axis, beyond workspace_radius = '
                    f'{self.radius:g} m by {radial - self.radius:.4g} m')
        box = _box_of(point[0], point[1], point[2], self.box_table(), tolerance)
        return f'inside keep_out_boxes[{box}] = {list(self.keep_out_boxes[box])} m'


@kernel
def _box_of(x, y, z, boxes, tolerance):
    """Return the first box (B, 6) the point is deeper than ``tolerance`` inside, or -1."""
    for box in range(boxes.shape[0]):
        if (boxes[box, 0] + tolerance < x < boxes[box, 3] - tolerance
                and boxes[box, 1] + tolerance < y < boxes[box, 4] - tolerance
                and boxes[box, 2] + tolerance < z < boxes[box, 5] - tolerance):
            return box
    return -1


@kernel
def _inside_rows(points, radius, z_min, z_max, boxes, tolerance, ok):
    """Fill ``ok`` (N,) with :func:`inside` of every row of ``points``."""
    for row in range(points.shape[0]):
        ok[row] = inside(points[row, 0], points[row, 1], points[row, 2], radius, z_min, z_max,
                         boxes, tolerance)


@kernel
def inside(x, y, z, radius, z_min, z_max, boxes, tolerance):
    """
    Tell whether the point is finite, in the cylinder and in no keep-out box (compiled).

    The one containment test (:meth:`SafeWorkspace.contains` runs it on every row), for
    compiled loops that check points as they make them; ``boxes`` is
    :meth:`SafeWorkspace.box_table`.
    """
    return (abs(x) + abs(y) + abs(z) < np.inf
            and math.hypot(x, y) <= radius + tolerance
            and z_min - tolerance <= z <= z_max + tolerance
            and _box_of(x, y, z, boxes, tolerance) < 0)


@kernel
def clearance(x, y, z, radius, z_min, z_max, boxes, tolerance):
    """
    Return how far a point :func:`inside` the workspace may move and stay inside [m] (compiled).

    Its least distance to the cylinder and to the keep-out boxes, each widened (the boxes
    shrunk) by ``tolerance`` as :func:`inside` widens them; a box is left behind along an
    axis on which the point is outside it. Meaningless for a point not inside.
    """
    distance = min(radius + tolerance - math.hypot(x, y), z - (z_min - tolerance),
                   z_max + tolerance - z)
    for box in range(boxes.shape[0]):
        beyond = max(boxes[box, 0] + tolerance - x, x - (boxes[box, 3] - tolerance),
                     boxes[box, 1] + tolerance - y, y - (boxes[box, 4] - tolerance),
                     boxes[box, 2] + tolerance - z, z - (boxes[box, 5] - tolerance))
        distance = min(distance, beyond)
    return max(distance, 0.0)
