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
Pure conversions between ROS messages and the planning core's arrays and results.

Nothing here needs a running node: every function takes plain values or messages and returns
messages or NumPy arrays, so each can be tested on its own.
"""

from dataclasses import dataclass
import functools
import struct

from builtin_interfaces.msg import Duration
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from geometry_msgs.msg import Point
import numpy as np
from std_msgs.msg import ColorRGBA
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory
from trajectory_msgs.msg import JointTrajectoryPoint
from visualization_msgs.msg import Marker
from visualization_msgs.msg import MarkerArray

_NANOSECONDS_PER_SECOND = 1_000_000_000
# The serialized form that rclpy's publish() takes as bytes: CDR (XCDR1), little-endian, after
# a 4-byte encapsulation header; each primitive aligned to its size from the end of that
# header. The header's stamp is the message's first field.
_CDR_LITTLE_ENDIAN = b'\x00\x01\x00\x00'
_CDR_STAMP = struct.Struct('<iI')
_CDR_STAMP_OFFSET = len(_CDR_LITTLE_ENDIAN)
_CDR_UINT32 = struct.Struct('<I')
_POINT_ARRAYS = ('positions', 'velocities', 'accelerations')

MARKER_NAMESPACE = 'ellipath'
# Points of the LINE_STRIP per leg of the cycle.
MARKER_SAMPLES_PER_LEG = 64
_LINE_WIDTH = 0.002  # m
_KNOT_DIAMETER = 0.006  # m
_APEX_DIAMETER = 0.012  # m
_PATH_COLOUR = ColorRGBA(r=0.1, g=0.8, b=0.2, a=1.0)
_KNOT_COLOUR = ColorRGBA(r=0.2, g=0.4, b=1.0, a=1.0)
_APEX_COLOUR = ColorRGBA(r=1.0, g=0.3, b=0.1, a=1.0)


def pose_position(pose_stamped):
    """
    Return the position of a geometry_msgs/PoseStamped as a float array (3,) [m].

    The orientation is not used: the Delta robot has three translational degrees of freedom.
    Non-finite coordinates are returned as they are; the caller validates them.
    """
    position = pose_stamped.pose.position
    return np.array([position.x, position.y, position.z], dtype=float)


def pose_array_positions(pose_array):
    """Return the positions of a geometry_msgs/PoseArray as a float array (N, 3) [m]."""
    return np.array([[pose.position.x, pose.position.y, pose.position.z]
                     for pose in pose_array.poses], dtype=float).reshape(-1, 3)


def joint_positions_by_name(joint_state, joint_names):
    """
    Pick the positions of ``joint_names`` out of a sensor_msgs/JointState.

    Parameters
    ----------
    joint_state : sensor_msgs.msg.JointState
        Joint state in any joint order, possibly with other joints.
    joint_names : Sequence[str]
        Wanted joints, in the wanted order.

    Returns
    -------
    numpy.ndarray or None
        Positions (len(joint_names),) [rad], or None when a wanted joint is missing, has no
        position or a non-finite one.

    """
    if len(joint_state.position) != len(joint_state.name):
        return None
    by_name = dict(zip(joint_state.name, joint_state.position))
    try:
        positions = np.array([by_name[name] for name in joint_names], dtype=float)
    except KeyError:
        return None
    return positions if np.all(np.isfinite(positions)) else None


def duration_from_seconds(seconds):
    """Return builtin_interfaces/Duration for a non-negative time [s], rounded to 1 ns."""
    sec, nanosec = divmod(int(round(seconds * _NANOSECONDS_PER_SECOND)),
                          _NANOSECONDS_PER_SECOND)
    return Duration(sec=sec, nanosec=nanosec)


def seconds_from_duration(duration):
    """Return a builtin_interfaces/Duration as float seconds."""
    return duration.sec + duration.nanosec / _NANOSECONDS_PER_SECOND


def seconds_from_time(stamp):
    """Return a builtin_interfaces/Time as float seconds."""
    return stamp.sec + stamp.nanosec / _NANOSECONDS_PER_SECOND


def joint_trajectory_message(trajectory, frame_id, stamp):
    """
    Convert the core's JointTrajectoryData to a trajectory_msgs/JointTrajectory.

    Parameters
    ----------
    trajectory : ellipath_ros.core.joint_trajectory.JointTrajectoryData
        Joint names, times (K,) [s] and positions, velocities, accelerations (K, 3).
    frame_id : str
        Robot base frame for the header.
    stamp : builtin_interfaces.msg.Time
        Header stamp; zero tells the controller to start on receipt.

    Returns
    -------
    trajectory_msgs.msg.JointTrajectory
        One point per knot, with positions, velocities, accelerations and time_from_start.

    """
    rows = zip(np.asarray(trajectory.time_from_start, dtype=float).tolist(),
               np.asarray(trajectory.positions, dtype=float).tolist(),
               np.asarray(trajectory.velocities, dtype=float).tolist(),
               np.asarray(trajectory.accelerations, dtype=float).tolist())
    return JointTrajectory(
        header=Header(frame_id=frame_id, stamp=stamp),
        joint_names=list(trajectory.joint_names),
        points=[JointTrajectoryPoint(positions=positions, velocities=velocities,
                                     accelerations=accelerations,
                                     time_from_start=duration_from_seconds(time))
                for time, positions, velocities, accelerations in rows])


@dataclass(frozen=True)
class SerializedTrajectory:
    """
    A trajectory_msgs/JointTrajectory serialized for ``publish()``, and what it holds.

    Attributes
    ----------
    data : bytes
        The message with header stamp zero, serialized as rclpy serializes it (CDR,
        little-endian; padding bytes zero).
    trajectory : ellipath_ros.core.joint_trajectory.JointTrajectoryData
        Exactly the values in ``data``: the times as whole nanoseconds, in seconds.
    last_time_from_start : builtin_interfaces.msg.Duration
        The last point's time_from_start.

    """

    data: bytes
    trajectory: JointTrajectoryData
    last_time_from_start: Duration

    def stamped(self, stamp):
        """Return the serialized message with header stamp ``stamp`` (builtin_interfaces/Time)."""
        return b''.join((self.data[:_CDR_STAMP_OFFSET],
                         _CDR_STAMP.pack(stamp.sec, stamp.nanosec),
                         self.data[_CDR_STAMP_OFFSET + _CDR_STAMP.size:]))


class _CdrWriter:
    """Appends CDR fields, each aligned from the end of the encapsulation header."""

    def __init__(self):
        self.parts = [_CDR_LITTLE_ENDIAN]
        self.size = 0  # bytes after the encapsulation header

    def raw(self, data, alignment=1):
        padding = -self.size % alignment
        self.parts += [bytes(padding), data]
        self.size += padding + len(data)

    def string(self, text):
        encoded = text.encode() + b'\0'
        self.raw(_CDR_UINT32.pack(len(encoded)), 4)
        self.raw(encoded)


def _point_layout(offset, joints):
    """
    Return (field offsets, size) of a JointTrajectoryPoint serialized from ``offset``.

    The offsets are relative to the point's start: the count and values of positions,
    velocities and accelerations, effort's count (it stays empty) and time_from_start. A
    point's layout depends on its start modulo 8 (the doubles' alignment).
    """
    fields = {}
    end = offset
    for name in _POINT_ARRAYS:
        end += -end % 4
        fields[name + '_count'] = end - offset
        end += 4 + (-(end + 4) % 8)
        fields[name] = end - offset
        end += 8 * joints
    end += -end % 4
    fields['effort_count'] = end - offset
    fields['time_from_start'] = end + 4 - offset
    return fields, end + 4 + _CDR_STAMP.size - offset


@functools.lru_cache(maxsize=16)
def _point_dtype(offset, joints):
    """
    Return the structured dtype of a JointTrajectoryPoint serialized from ``offset``.

    Its fields are :func:`_point_layout`'s: each array's count (uint32) and values (float64),
    and time_from_start's ``sec`` (int32) and ``nanosec`` (uint32), little-endian; its size
    is the point's, so that an array of them is a run of serialized points.
    """
    layout, size = _point_layout(offset, joints)
    names, formats, offsets = [], [], []
    for name in _POINT_ARRAYS:
        names += [name + '_count', name]
        formats += ['<u4', ('<f8', (joints,))]
        offsets += [layout[name + '_count'], layout[name]]
    names += ['sec', 'nanosec']
    formats += ['<i4', '<u4']
    offsets += [layout['time_from_start'], layout['time_from_start'] + 4]
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets, 'itemsize': size})


def serialized_joint_trajectory(trajectory, frame_id):
    """
    Serialize the core's JointTrajectoryData as a trajectory_msgs/JointTrajectory, stamp zero.

    The message of :func:`joint_trajectory_message` (times rounded to whole nanoseconds the
    same way), written straight from the arrays: building the message's objects point by
    point and serializing them cost about 30 times as much (1.7 ms for 61 points). Publish
    ``SerializedTrajectory.stamped(stamp)``: rclpy publishes bytes as they are.

    Returns
    -------
    SerializedTrajectory

    """
    nanoseconds = np.rint(np.asarray(trajectory.time_from_start, dtype=float)
                          * _NANOSECONDS_PER_SECOND).astype(np.int64)
    seconds, nanoseconds_left = np.divmod(nanoseconds, _NANOSECONDS_PER_SECOND)
    arrays = [np.ascontiguousarray(getattr(trajectory, name), dtype='<f8')
              for name in _POINT_ARRAYS]
    count, joints = arrays[0].shape
    writer = _CdrWriter()
    writer.raw(_CDR_STAMP.pack(0, 0), 4)
    writer.string(frame_id)
    writer.raw(_CDR_UINT32.pack(len(trajectory.joint_names)), 4)
    for name in trajectory.joint_names:
        writer.string(name)
    writer.raw(_CDR_UINT32.pack(count), 4)
    # The first point's layout depends on where it starts; the second starts 4 bytes past a
    # multiple of 8, and so does every later one (such a point's size is a multiple of 8).
    first = _point_dtype(writer.size, joints)
    rest = _point_dtype(writer.size + first.itemsize, joints)
    for dtype, rows in ((first, slice(0, 1)), (rest, slice(1, count))):
        # Zeros: the padding and effort's count.
        block = np.zeros(rows.stop - rows.start, dtype)
        for name, values in zip(_POINT_ARRAYS, arrays):
            block[name + '_count'] = joints
            block[name] = values[rows]
        block['sec'], block['nanosec'] = seconds[rows], nanoseconds_left[rows]
        writer.parts.append(block.tobytes())
    return SerializedTrajectory(
        b''.join(writer.parts),
        JointTrajectoryData(tuple(trajectory.joint_names),
                            seconds + nanoseconds_left / _NANOSECONDS_PER_SECOND, *arrays),
        Duration(sec=int(seconds[-1]), nanosec=int(nanoseconds_left[-1])))


def joint_trajectory_data(message):
    """
    Convert a trajectory_msgs/JointTrajectory back to the core's JointTrajectoryData.

    The inverse of :func:`joint_trajectory_message` (times as whole nanoseconds); used to
    check the message that is actually published with ``validate_jtc``.

    Raises
    ------
    ellipath_ros.core.errors.InvalidInputError
        The points do not form K rows of 3 finite values with increasing times.

    """
    points = message.points
    return JointTrajectoryData(
        joint_names=tuple(message.joint_names),
        time_from_start=[seconds_from_duration(point.time_from_start) for point in points],
        positions=[point.positions for point in points],
        velocities=[point.velocities for point in points],
        accelerations=[point.accelerations for point in points])


def _format_value(value):
    """Format one diagnostics value."""
    if isinstance(value, (float, np.floating)):
        return f'{float(value):.9g}'
    return str(value)


def number_ranges(numbers):
    """
    Write increasing integers as ranges: ``[5, 6, 7, 9]`` gives ``'5-7 9'``.

    The inverse of :func:`numbers_in_ranges`; a status naming many pairs stays short.
    """
    ranges = []
    for number in numbers:
        if ranges and number == ranges[-1][1] + 1:
            ranges[-1][1] = number
        else:
            ranges.append([number, number])
    return ' '.join(str(first) if first == last else f'{first}-{last}'
                    for first, last in ranges)


def numbers_in_ranges(text):
    """Return the integers written by :func:`number_ranges` (``'5-7 9'``: 5, 6, 7, 9)."""
    numbers = []
    for item in text.split():
        first, _, last = item.partition('-')
        numbers.extend(range(int(first), int(last or first) + 1))
    return numbers


def serialized_diagnostic_array(stamp, statuses):
    """
    Serialize a diagnostic_msgs/DiagnosticArray stamped ``stamp`` for ``publish()``.

    ``statuses``: (name, hardware_id, level, message, values) each: a DiagnosticStatus with
    ``level`` (``DiagnosticStatus.OK``, ``WARN`` or ``ERROR``), the summary ``message`` (the
    reason of a rejection, or ``'planned'``), and one KeyValue per item of the mapping
    ``values``, in its order (floats with 9 significant digits, everything else with
    ``str``). Written as rclpy serializes it (CDR, little-endian): rclpy publishes bytes as
    they are (test/test_serialized_diagnostics.py compares them with rclpy's serialization of
    the message). Publishing the message object instead leaked memory in the node inside
    rclpy's conversion of it (docs/reliability.md, "The node over time").
    """
    writer = _CdrWriter()
    writer.raw(_CDR_STAMP.pack(stamp.sec, stamp.nanosec), 4)
    writer.string('')  # header.frame_id
    writer.raw(_CDR_UINT32.pack(len(statuses)), 4)
    for name, hardware_id, level, message, values in statuses:
        writer.raw(bytes(level))
        for text in (name, message, hardware_id):
            writer.string(text)
        writer.raw(_CDR_UINT32.pack(len(values)), 4)
        for key, value in values.items():
            writer.string(str(key))
            writer.string(_format_value(value))
    return b''.join(writer.parts)


def _points(array):
    """Convert an array (N, 3) to a list of geometry_msgs/Point."""
    return [Point(x=x, y=y, z=z) for x, y, z in np.asarray(array, dtype=float).tolist()]


def _marker(header, marker_id, marker_type, diameter, colour):
    """Return an ADD marker with identity orientation, uniform scale and one colour."""
    marker = Marker(header=header, ns=MARKER_NAMESPACE, id=marker_id, type=marker_type,
                    action=Marker.ADD, color=colour)
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = diameter
    return marker


def path_markers(plan, frame_id, stamp, samples_per_leg=MARKER_SAMPLES_PER_LEG):
    """
    Visualise a planned cycle as a visualization_msgs/MarkerArray.

    The array starts with a DELETEALL marker so the markers of the previous plan vanish, then
    holds a LINE_STRIP of the TCP path sampled along every leg, a SPHERE_LIST of the
    trajectory knots and one SPHERE at the apex of every leg.

    Parameters
    ----------
    plan : ellipath_ros.core.planner.CyclePlan
        The planned cycle.
    frame_id : str
        Robot base frame.
    stamp : builtin_interfaces.msg.Time
        Header stamp of every marker.
    samples_per_leg : int
        Points of the LINE_STRIP per leg.

    """
    header = Header(frame_id=frame_id, stamp=stamp)
    delete_all = Marker(header=header, ns=MARKER_NAMESPACE, action=Marker.DELETEALL)
    path = np.concatenate([
        leg.path.at_lengths(np.linspace(0.0, leg.path.length, samples_per_leg)).position
        for leg in plan.legs])
    line = _marker(header, 0, Marker.LINE_STRIP, _LINE_WIDTH, _PATH_COLOUR)
    line.points = _points(path)
    knots = _marker(header, 1, Marker.SPHERE_LIST, _KNOT_DIAMETER, _KNOT_COLOUR)
    knots.points = _points(np.concatenate([leg.knot_positions for leg in plan.legs]))
    markers = [delete_all, line, knots]
    for index, leg in enumerate(plan.legs):
        apex = _marker(header, 2 + index, Marker.SPHERE, _APEX_DIAMETER, _APEX_COLOUR)
        apex.pose.position.x, apex.pose.position.y, apex.pose.position.z = (
            np.asarray(leg.path.apex, dtype=float).tolist())
        markers.append(apex)
    return MarkerArray(markers=markers)
