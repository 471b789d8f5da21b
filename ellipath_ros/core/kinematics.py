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
Closed-form kinematics of the rotary (Clavel) Delta robot, vectorised over points.

Conventions, shared by the whole package: SI units, base frame with z up, the robot works below its
base so the tool centre point (TCP, the effector centre) has z < 0. Arm ``i`` (i = 0, 1, 2)
sits at azimuth ``120 deg * i`` from +x towards +y; its actuator axis is horizontal, tangent to
the base circle of radius ``R`` at ``A_i = R e_i`` with ``e_i`` the radial unit vector. The
joint angle ``q_i`` is the angle of upper arm ``i`` below the base plane: ``q = 0`` horizontal
pointing outwards, ``q > 0`` pointing down. With ``z`` the vertical unit vector:

* elbow ``B_i = A_i + L1 (cos q_i e_i - sin q_i z)``,
* forearm joint on the effector ``C_i = p + r e_i``, ``p`` the TCP,
* constraint ``|C_i - B_i| = L2`` (the parallelogram forearm keeps the effector level).

Every function takes arrays of shape (N, 3) (points or joint angles, one row per sample) and
returns arrays of shape (N, 3); a single sample of shape (3,) gives a result of shape (3,).
Errors name the index of the first offending sample; an :class:`UnreachableError` raised here
also carries that index as its ``index`` attribute.
"""

from dataclasses import dataclass
import math

from ellipath_ros.core.compiled import kernel
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.settings import default_of
from ellipath_ros.core.settings import validate_fields
import numpy as np

# |s_i . b_i| / (L1 L2) (IK) and |det A| / L2^3 (FK) below this count as singular: the rates
# would be amplified by more than a million.
_SINGULARITY_TOLERANCE = 1e-6

_AZIMUTHS = 2.0 * np.pi * np.arange(3) / 3.0
# Row i: radial unit vector e_i, tangential unit vector t_i of arm i.
_RADIAL = np.stack([np.cos(_AZIMUTHS), np.sin(_AZIMUTHS), np.zeros(3)], axis=1)
_TANGENT = np.stack([-np.sin(_AZIMUTHS), np.cos(_AZIMUTHS), np.zeros(3)], axis=1)
# Their x and y columns, contiguous, for the compiled loops.
_RADIAL_X, _RADIAL_Y = (np.ascontiguousarray(_RADIAL[:, axis]) for axis in (0, 1))
_TANGENT_X, _TANGENT_Y = (np.ascontiguousarray(_TANGENT[:, axis]) for axis in (0, 1))


@dataclass(frozen=True)
class DeltaGeometry:
    """
    Dimensions and joint position limits of a rotary Delta robot.

    Parameters
    ----------
    base_radius : float
        ``R``, base centre to actuator axis [m].
    effector_radius : float
        ``r``, effector centre (TCP) to forearm joint [m].
    upper_arm : float
        ``L1``, actuator axis to elbow [m].
    forearm : float
        ``L2``, elbow to effector joint (parallelogram length) [m].
    joint_min, joint_max : float
        Joint position limits [rad], the same for the three arms.

    Notes
    -----
    Default joint limits, for the default dimensions (R 0.200, r 0.045, L1 0.350, L2 0.800 m):

    * ``joint_max = 1.95 rad`` (111.7 deg, arm pointing down and inwards). At
      ``acos((r - R) / L1) = 2.03 rad`` the elbow crosses the circle of the effector joints
      (``R + L1 cos q = r``): beyond it the forearm leans outwards, the parallelogram folds
      towards its flipped configuration and the three elbows crowd under the base centre.
      1.95 rad keeps the elbow 26 mm outside that circle.
    * ``joint_min = -0.85 rad`` (-48.7 deg, arm raised). The upper arm rises at most
      ``L1 sin 0.85 = 0.26 m`` above the actuator plane, keeping it clear of the base structure
      and motor housings, and away from the folded elbow of high, off-centre poses.
    * The useful workspace, the cylinder of radius 0.4 m around the base axis for
      z in [-1.0, -0.55] m, needs q in [-0.796, 1.919] rad (sampled on a fine grid), so it is
      reachable with a margin of at least 0.03 rad at both limits.

    """

    base_radius: float = default_of('base_radius')
    effector_radius: float = default_of('effector_radius')
    upper_arm: float = default_of('upper_arm')
    forearm: float = default_of('forearm')
    joint_min: float = default_of('joint_min')
    joint_max: float = default_of('joint_max')

    def __post_init__(self):
        """Check every dimension and store them as floats."""
        validate_fields(self)
        offset = abs(self.base_radius - self.effector_radius)
        # A forearm no longer than the radial offset cannot hang the effector below the base.
        require_range('forearm', self.forearm, offset, low_open=True, unit='m')
        if not self.joint_min < self.joint_max:
            raise InvalidInputError(
                f'joint_max: expected a value > joint_min = {self.joint_min:g} '
                f'rad, got {self.joint_max:g}')


@dataclass(frozen=True)
class JointLimits:
    """
    Velocity and acceleration limits of the three actuators.

    Parameters
    ----------
    max_velocity : float
        Largest allowed ``|q_dot|`` [rad/s].
    max_acceleration : float
        Largest allowed ``|q_ddot|`` [rad/s^2].

    """

    max_velocity: float = default_of('max_joint_velocity')
    max_acceleration: float = default_of('max_joint_accel')

    def __post_init__(self):
        """Check that both limits are finite and positive, and store them as floats."""
        validate_fields(self)


def _unreachable(message, index):
    """Build an UnreachableError that remembers the index of the offending sample."""
    error = UnreachableError(message)
    error.index = int(index)
    return error


def _fmt(row):
    """Format one sample as ``(a, b, c)`` for messages."""
    return '(' + ', '.join(f'{value:.6g}' for value in row) + ')'


def _as_rows(name, value):
    """Return ``value`` as a float array (N, 3) and whether the input was a single (3,) row."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name}: expected an array of shape (N, 3) or (3,), '
                                f'got {value!r}') from None
    single = array.shape == (3,)
    if single:
        array = array[np.newaxis, :]
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidInputError(
            f'{name}: expected an array of shape (N, 3) or (3,), got shape {array.shape}')
    # The whole-array test first: a per-row reduction over 3 columns costs ten times as much.
    if not np.isfinite(array).all():
        index = int(np.argmin(np.isfinite(array).all(axis=1)))
        raise InvalidInputError(
            f'{name}[{index}]: expected finite values, got {_fmt(array[index])}')
    return array, single


def _same_shape(name, array, reference, reference_name):
    """Raise unless ``array`` has as many rows as ``reference``."""
    if array.shape != reference.shape:
        raise InvalidInputError(f'{name}: expected shape {reference.shape} like '
                                f'{reference_name}, got shape {array.shape}')


def inverse_kinematics(points, geometry, *, name='points'):
    """
    Joint angles that put the TCP at the given points (closed form, elbow-out branch).

    Parameters
    ----------
    points : array_like, shape (N, 3) or (3,)
        TCP positions in the base frame [m].
    geometry : DeltaGeometry
        Robot dimensions and joint position limits.
    name : str
        Name of ``points`` in error messages.

    Returns
    -------
    numpy.ndarray, shape (N, 3) or (3,)
        Joint angles ``q`` [rad], column i for arm i.

    Raises
    ------
    InvalidInputError
        ``points`` has the wrong shape or a non-finite entry.
    UnreachableError
        A point is above the base plane, outside the sphere an arm can reach, or needs a joint
        angle outside ``[joint_min, joint_max]``; the message names the first such point.

    """
    array, single = _as_rows(name, points)
    q, status, arms = _ik(array, geometry)
    if status.any():
        row = int(np.argmax(status != _IK_OK))
        raise _joint_failure(array, row, int(status[row]), int(arms[row]), q[row, arms[row]],
                             geometry, name)
    return q[0] if single else q


def _ik(points, geometry):
    """Return :func:`_ik_rows`' joint angles, status and failing arm of every row."""
    q = np.empty(points.shape)
    status = np.empty(points.shape[0], dtype=np.int8)
    arms = np.empty(points.shape[0], dtype=np.int8)
    _ik_rows(np.ascontiguousarray(points), *_joint_geometry(geometry)[:9],
             _limit_trig(geometry), q, status, arms)
    return q, status, arms


def reachable(points, geometry):
    """
    Tell, point by point, whether inverse kinematics succeeds.

    Parameters
    ----------
    points : array_like, shape (N, 3) or (3,)
        TCP positions in the base frame [m]; non-finite rows count as unreachable.
    geometry : DeltaGeometry
        Robot dimensions and joint position limits.

    Returns
    -------
    numpy.ndarray of bool, shape (N,) or ()
        True where the point is below the base, inside every arm's sphere and within the
        joint position limits.

    """
    array = np.asarray(points, dtype=float)
    single = array.shape == (3,)
    if single:
        array = array[np.newaxis, :]
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidInputError(
            f'points: expected an array of shape (N, 3) or (3,), got shape {array.shape}')
    # A non-finite row fails in the kernel: NaN compares false with every bound.
    ok = _ik(array, geometry)[1] == _IK_OK
    return ok[0] if single else ok


def check_reachable(points, geometry, *, name='points'):
    """
    Raise :class:`UnreachableError` naming the first point inverse kinematics cannot serve.

    Same parameters and errors as :func:`inverse_kinematics`; returns None.
    """
    inverse_kinematics(points, geometry, name=name)


def forward_kinematics(q, geometry, *, name='q', strict=True):
    """
    TCP positions for the given joint angles (closed-form three-sphere intersection).

    The effector centre is at distance ``L2`` from the three points ``S_i = B_i - r e_i``, so
    it lies on the line through the circumcentre of the triangle ``S_0 S_1 S_2``, normal to
    its plane, at height ``sqrt(L2^2 - rho^2)`` with ``rho`` the circumradius. Of the two
    solutions the lower one (the one below the base, z < 0) is returned.

    Parameters
    ----------
    q : array_like, shape (N, 3) or (3,)
        Joint angles [rad], column i for arm i. Joint position limits are not checked here.
    geometry : DeltaGeometry
        Robot dimensions.
    name : str
        Name of ``q`` in error messages.
    strict : bool
        If False, rows that cannot be assembled come back as NaN instead of raising (used to
        measure how far an interpolated joint path strays).

    Returns
    -------
    numpy.ndarray, shape (N, 3) or (3,)
        TCP positions in the base frame [m].

    Raises
    ------
    InvalidInputError
        ``q`` has the wrong shape or a non-finite entry.
    UnreachableError
        With ``strict``: the forearms cannot close the loop (spheres do not meet), the sphere
        centres are collinear, or the lower solution is not below the base; names the first
        such sample.

    """
    array, single = _as_rows(name, q)
    points = _forward(array, geometry, name, strict)
    return points[0] if single else points


def _forward(q, geometry, name, strict=True):
    """
    Three-sphere intersection of every row; see :func:`forward_kinematics`.

    The centre of forearm sphere i is ``(radial_i cos az_i, radial_i sin az_i, height_i)``;
    with ``a = c0 - c2`` and ``b = c1 - c2`` the circumcentre lies at
    ``((|a|^2 b - |b|^2 a) x n) / (2 |n|^2)`` from c2 (``n = a x b``), and the effector
    below it along the unit normal (:func:`_forward_row`).
    """
    q = np.ascontiguousarray(q, dtype=float)
    points = np.empty(q.shape)
    status = np.empty(q.shape[0], dtype=np.int8)
    _forward_rows(q, *_kernel_geometry(geometry)[:5], points, status)
    if strict:
        _raise_unassembled(q, status, name)
    return points


def _kernel_geometry(geometry):
    """Return the dimensions the compiled rows take, in :func:`_tcp_state`'s order."""
    return (_RADIAL_X, _RADIAL_Y, geometry.base_radius - geometry.effector_radius,
            geometry.upper_arm, geometry.forearm ** 2,
            _SINGULARITY_TOLERANCE * geometry.forearm ** 3)


def _raise_unassembled(q, status, name):
    """Raise for the first row of ``status`` that could not be assembled, if any."""
    bad = (status != _ASSEMBLED) & (status != _COPLANAR)
    if not bad.any():
        return
    index = int(np.argmax(bad))
    why = {_COLLINEAR: 'the three forearm spheres have collinear centres',
           _APART: 'the three forearms cannot meet at one effector',
           _ABOVE: 'the effector would be above the base plane'}[int(status[index])]
    raise _unreachable(f'{name}[{index}]: expected joint angles of an assembled robot, '
                       f'got {_fmt(q[index])} rad: {why}', index)


def largest_magnitude_per_row(values):
    """
    Return max(|values[n, 0]|, |values[n, 1]|, |values[n, 2]|) per row n of (N, 3), (N,).

    The same numbers as ``np.abs(values).max(axis=1)`` at a fraction of its cost
    (a reduction over 3 columns is mostly overhead).
    """
    magnitude = np.abs(values)
    return np.maximum(np.maximum(magnitude[:, 0], magnitude[:, 1]), magnitude[:, 2])


def _check_inputs(points, q, extras, names):
    """Convert points, q and the extra (N, 3) arrays, checking that their shapes agree."""
    point_array, single = _as_rows(names[0], points)
    q_array, _ = _as_rows(names[1], q)
    _same_shape(names[1], q_array, point_array, names[0])
    converted = []
    for extra, extra_name in zip(extras, names[2:]):
        array, _ = _as_rows(extra_name, extra)
        _same_shape(extra_name, array, point_array, names[0])
        converted.append(array)
    return point_array, q_array, converted, single


def joint_velocities(points, q, velocities, geometry, *, name='points'):
    """
    Joint rates for the given TCP velocities (analytic Jacobian).

    Differentiating ``|s_i|^2 = L2^2`` with ``s_i = C_i - B_i`` gives the standard Delta form
    ``A p_dot = B q_dot`` with rows ``A_i = s_i^T`` and ``B = diag(s_i . dB_i/dq_i)``.

    Parameters
    ----------
    points : array_like, shape (N, 3) or (3,)
        TCP positions [m].
    q : array_like, same shape
        Joint angles at ``points`` [rad], i.e. ``inverse_kinematics(points)``.
    velocities : array_like, same shape
        TCP velocities [m/s].
    geometry : DeltaGeometry
        Robot dimensions.
    name : str
        Name of ``points`` in error messages.

    Returns
    -------
    numpy.ndarray, same shape
        Joint velocities ``q_dot`` [rad/s].

    Raises
    ------
    UnreachableError
        A pose is at (or within a relative 1e-6 of) an IK singularity.

    """
    points, q, (velocities,), single = _check_inputs(
        points, q, (velocities,), (name, 'q', 'velocities'))
    qdot, _ = _rates(points, q, velocities, np.zeros(points.shape), None, geometry, name)
    return qdot[0] if single else qdot


def joint_accelerations(points, q, velocities, accelerations, qdot, geometry, *,
                        name='points'):
    """
    Joint accelerations for the given TCP accelerations (time derivative of the constraint).

    With ``s_i`` the forearm vector, ``b_i = dB_i/dq_i`` and ``c_i = d^2B_i/dq_i^2``, the
    derivative of ``s_i . p_dot = (s_i . b_i) q_dot_i`` gives
    ``q_ddot_i = (s_i . p_ddot + |s_dot_i|^2 - (s_i . c_i) q_dot_i^2) / (s_i . b_i)`` with
    ``s_dot_i = p_dot - b_i q_dot_i``.

    Parameters
    ----------
    points : array_like, shape (N, 3) or (3,)
        TCP positions [m].
    q : array_like, same shape
        Joint angles at ``points`` [rad].
    velocities : array_like, same shape
        TCP velocities [m/s].
    accelerations : array_like, same shape
        TCP accelerations [m/s^2].
    qdot : array_like, same shape
        Joint velocities [rad/s], i.e. :func:`joint_velocities` of the same samples.
    geometry : DeltaGeometry
        Robot dimensions.
    name : str
        Name of ``points`` in error messages.

    Returns
    -------
    numpy.ndarray, same shape
        Joint accelerations ``q_ddot`` [rad/s^2].

    Raises
    ------
    UnreachableError
        A pose is at (or within a relative 1e-6 of) an IK singularity.

    """
    points, q, (velocities, accelerations, qdot), single = _check_inputs(
        points, q, (velocities, accelerations, qdot),
        (name, 'q', 'velocities', 'accelerations', 'qdot'))
    _, qddot = _rates(points, q, velocities, accelerations, qdot, geometry, name)
    return qddot[0] if single else qddot


def _rates(points, q, velocities, accelerations, qdot, geometry, name):
    """
    Return (q_dot, q_ddot) of :func:`_rate_point` for every row, raising at a singularity.

    ``qdot`` given (N, 3): the accelerations are computed with it, and it is returned.
    """
    given = qdot is not None
    rates = np.array(qdot, dtype=float) if given else np.empty(points.shape)
    qddot = np.empty(points.shape)
    geometry_args = _joint_geometry(geometry)
    row, arm, diagonal = _rate_rows(
        *(np.ascontiguousarray(value) for value in (points, velocities, accelerations, q)),
        *geometry_args[:2], *geometry_args[4:6], geometry_args[9], rates, qddot, given)
    if row >= 0:
        raise _joint_failure(points, row, _IK_SINGULAR, arm, diagonal, geometry, name)
    return rates, qddot


def joint_motion(points, velocities, accelerations, geometry, *, name='points'):
    """
    Joint positions, velocities and accelerations of a TCP motion, in one pass.

    The same as :func:`inverse_kinematics`, :func:`joint_velocities` and
    :func:`joint_accelerations` in turn, with the inputs checked and the arm
    vectors computed once.

    Parameters
    ----------
    points, velocities, accelerations : array_like, shape (N, 3)
        TCP positions [m], velocities [m/s] and accelerations [m/s^2].
    geometry : DeltaGeometry
        The robot's dimensions and joint position limits.
    name : str
        What ``points`` are called in error messages.

    Returns
    -------
    tuple of numpy.ndarray
        ``q`` [rad], ``q_dot`` [rad/s] and ``q_ddot`` [rad/s^2], each (N, 3).

    Raises
    ------
    InvalidInputError
        Wrong shapes or non-finite entries.
    UnreachableError
        As :func:`inverse_kinematics`, or a pose at an IK singularity.

    """
    cos_q, sin_q, qdot, qddot = joint_trig_motion(points, velocities, accelerations, geometry,
                                                  name=name)
    q = joint_angles(cos_q, sin_q)
    if np.shape(points) == (3,):
        return q[0], qdot[0], qddot[0]
    return q, qdot, qddot


def joint_trig_motion(points, velocities, accelerations, geometry, *, name='points'):
    """
    Return :func:`joint_motion` with cos q and sin q for q: (cos q, sin q, q_dot, q_ddot).

    For callers that read the joint angles of a few rows only: :func:`joint_angles` of
    rows of cos q and sin q gives the same bits as :func:`joint_motion`'s q there. The
    rates need only cos q and sin q, and the joint limits are judged without an ``atan2``
    away from them (:func:`_inside_joint_limits`). The inputs, the errors and their order
    are :func:`joint_motion`'s; the results are always (N, 3).
    """
    return joint_trig_peaks(points, velocities, accelerations, geometry, name=name)[:4]


def joint_trig_peaks(points, velocities, accelerations, geometry, *, name='points'):
    """
    Return :func:`joint_trig_motion` and the largest |q_dot| and |q_ddot|, in one pass.

    The peaks, floats, come last: (cos q, sin q, q_dot, q_ddot, peak q_dot, peak q_ddot).
    Float (N, 3) arrays in C order, as the planner makes them, go to the compiled pass as
    they are, which stops at a non-finite rate (the IK at a non-finite point); anything else,
    and any row that fails, take the checks that name the problem first.
    """
    arrays = (points, velocities, accelerations)
    if all(isinstance(array, np.ndarray) and array.dtype == np.float64 and array.ndim == 2
           and array.shape[1] == 3 and array.flags.c_contiguous for array in arrays) and (
               points.shape == velocities.shape == accelerations.shape):
        row, _, _, _, results = _trig_rows(*arrays, geometry)
        if row < 0:
            return results
    points, _ = _as_rows(name, points)
    converted = []
    for extra, extra_name in ((velocities, 'velocities'), (accelerations, 'accelerations')):
        array, _ = _as_rows(extra_name, extra)
        _same_shape(extra_name, array, points, name)
        converted.append(array)
    row, status, arm, value, results = _trig_rows(
        *(np.ascontiguousarray(array) for array in (points, *converted)), geometry)
    if row >= 0:
        raise _joint_failure(points, row, status, arm, value, geometry, name)
    return results


def _trig_rows(points, velocities, accelerations, geometry):
    """Return :func:`_joint_trig_rows`' failure (row -1: none) and the results it makes."""
    cos_q, sin_q, qdot, qddot = (np.empty(points.shape) for _ in range(4))
    peaks = np.empty(2)
    row, status, arm, value = _joint_trig_rows(
        points, velocities, accelerations, *_joint_geometry(geometry), _limit_trig(geometry),
        cos_q, sin_q, qdot, qddot, peaks)
    return row, status, arm, value, (cos_q, sin_q, qdot, qddot, float(peaks[0]),
                                     float(peaks[1]))


def joint_angles(cos_q, sin_q):
    """Return the joint angles ``atan2(sin_q, cos_q)`` [rad] of rows (N, 3), as IK has them."""
    q = np.empty(np.shape(cos_q))
    _angle_rows(np.ascontiguousarray(cos_q, dtype=float),
                np.ascontiguousarray(sin_q, dtype=float), q)
    return q


def joint_speed_caps(points, directions, geometry, limit, *, rows=False, extra=None):
    """
    Return ``limit / max_i |dq_i/ds|`` (N,) along (N, 3) unit ``directions``, or None.

    ``dq/ds`` are the joint rates of :func:`joint_motion` at the finite (N, 3) ``points``
    moving along ``directions`` at unit speed (the largest below 1e-12 counts as 1e-12).
    Nothing is raised: a point out of reach, beyond a joint limit or at an IK singularity
    gives None, for the caller to name it its own way. The joint angles themselves are not
    computed: a point's limits are judged from cos q and sin q, with an ``atan2`` only near
    a limit (:func:`_inside_joint_limits`). With ``rows``, ``points`` and ``directions`` are
    float arrays of coordinate rows (3, N) in C order (as
    :meth:`~ellipath_ros.core.geometry.PickPlacePath.rows_at_lengths` makes them), taken
    as they are. ``extra`` (3,), a finite point that must be reachable too (else None), has
    no cap.
    """
    if not rows:
        points, directions = (np.ascontiguousarray(np.asarray(values, dtype=float).T)
                              for values in (points, directions))
    caps = np.empty(points.shape[1])
    extra = (math.nan,) * 3 if extra is None else tuple(np.asarray(extra, dtype=float).tolist())
    assembled = _speed_cap_rows(points, directions, extra, *_joint_geometry(geometry),
                                _limit_trig(geometry), float(limit), caps)
    return caps if assembled else None


def _limit_trig(geometry):
    """
    Return the cosines and sines of the joint limits, and whether they may be used.

    :func:`_inside_joint_limits` uses them only for limits inside (-pi, pi) less than pi
    apart: then both cross products positive mean an angle strictly between them.
    """
    low, high = geometry.joint_min, geometry.joint_max
    usable = -math.pi < low and high < math.pi and high - low < math.pi
    return math.cos(low), math.sin(low), math.cos(high), math.sin(high), usable


def _joint_geometry(geometry):
    """Return the arm directions and dimensions :func:`_joint_trig_rows` takes, in order."""
    return (_RADIAL_X, _RADIAL_Y, _TANGENT_X, _TANGENT_Y,
            geometry.base_radius - geometry.effector_radius, geometry.upper_arm,
            geometry.forearm, geometry.joint_min, geometry.joint_max,
            _SINGULARITY_TOLERANCE * (geometry.upper_arm * geometry.forearm))


def _joint_failure(points, row, status, arm, value, geometry, name):
    """
    Return the error naming row ``row`` of ``points`` that inverse kinematics cannot serve.

    The one naming of the kernels' failures (:func:`_ik_trig_point`, :func:`_rate_point`):
    ``status`` is their code, ``arm`` the arm that fails and ``value`` its joint angle
    (``_IK_LIMIT``) or ``s_i . b_i`` (``_IK_SINGULAR``).
    """
    point = points[row]
    where = f'{name}[{row}]: expected a point reachable by the robot, got {_fmt(point)} m'
    if status == _IK_ABOVE:
        return _unreachable(f'{where}, above the base plane (z must be < 0)', row)
    if status == _IK_OUTSIDE:
        radial = (point[0] * _RADIAL_X[arm] + point[1] * _RADIAL_Y[arm]
                  + geometry.effector_radius - geometry.base_radius)
        tangential = point[0] * _TANGENT_X[arm] + point[1] * _TANGENT_Y[arm]
        reach = math.hypot(radial, point[2])
        fore_sq = geometry.forearm ** 2 - tangential ** 2
        fore = math.sqrt(fore_sq) if fore_sq > 0.0 else 0.0
        side = 'far from' if reach > geometry.upper_arm + fore else 'close to'
        return _unreachable(
            f'{where}, outside the sphere of arm {arm}: too {side} its actuator axis for '
            f'upper arm {geometry.upper_arm:g} m and forearm {geometry.forearm:g} m', row)
    if status == _IK_LIMIT:
        return _unreachable(
            f'{where}, joint limit: arm {arm} needs q={value:.6g} rad, outside '
            f'[{geometry.joint_min:g}, {geometry.joint_max:g}] rad', row)
    scale = geometry.upper_arm * geometry.forearm
    return _unreachable(
        f'{name}[{row}]: expected a point away from singularities, got a pose where '
        f'forearm {arm} is perpendicular to its elbow path (|s.b|/(L1 L2) = '
        f'{abs(value) / scale:.3g}): the joint rates are unbounded', row)


def tcp_derivatives(q, qdot, qddot, qdddot, geometry, *, name='q', strict=True):
    """
    TCP position, velocity, acceleration and jerk of a joint motion, exactly (no differences).

    Differentiating the loop constraint ``|s_i|^2 = L2^2`` of arm i once, twice and three
    times (``s_i`` the forearm vector, ``b_i``, ``c_i`` and ``-b_i`` the first three
    derivatives of the elbow by ``q_i``) gives three linear systems with the same matrix
    ``A`` (rows ``s_i``):
    ``s_i . p_dot = (s_i . b_i) q_dot_i``,
    ``s_i . p_ddot = s_i . (c_i q_dot_i^2 + b_i q_ddot_i) - |s_dot_i|^2`` and
    ``s_i . p_dddot = s_i . (-b_i q_dot_i^3 + 3 c_i q_dot_i q_ddot_i + b_i q_dddot_i)
    - 3 s_dot_i . s_ddot_i``, solved with ``A^-1`` from cross products.

    Parameters
    ----------
    q, qdot, qddot, qdddot : numpy.ndarray, shape (N, 3)
        Joint positions [rad] and their first three time derivatives.
    geometry : DeltaGeometry
        Robot dimensions.
    name : str
        Name of ``q`` in error messages.
    strict : bool
        If False, rows that cannot be assembled, or are at a direct-kinematics
        singularity (where the rates are undefined), come back as NaN instead of raising.

    Returns
    -------
    tuple of numpy.ndarray
        Position [m], velocity [m/s], acceleration [m/s^2] and jerk [m/s^3], each (N, 3).

    Raises
    ------
    UnreachableError
        With ``strict``: as :func:`forward_kinematics`, or a pose where the forearms are
        coplanar (``|det A| / L2^3`` below 1e-6).

    """
    q = np.ascontiguousarray(q, dtype=float)
    rates = [np.ascontiguousarray(value, dtype=float) for value in (qdot, qddot, qdddot)]
    points, velocity, acceleration, jerk = (np.empty(q.shape) for _ in range(4))
    status = np.empty(q.shape[0], dtype=np.int8)
    _tcp_rows(q, *rates, *_kernel_geometry(geometry), points, velocity, acceleration, jerk,
              status)
    if strict:
        _raise_unassembled(q, status, name)
        if (status == _COPLANAR).any():
            index = int(np.argmax(status == _COPLANAR))
            raise _unreachable(
                f'{name}[{index}]: expected joint angles away from singularities, got '
                f'{_fmt(q[index])} rad where the forearms are coplanar', index)
    return points, velocity, acceleration, jerk


# Compiled per-row forms of the vectorised formulas below: the same IEEE operations in the
# same order (see compiled.py), so their results equal the NumPy ones bit for bit, without
# the NumPy call per operation that made a few hundred rows cost as much as a million.
# Status codes of a row, in the order the errors are reported.
_ASSEMBLED, _COLLINEAR, _APART, _ABOVE, _COPLANAR = range(5)


@kernel
def _forward_row(q0, q1, q2, rx, ry, offset, upper, forearm_sq, points, row):
    """Write the TCP of joint angles (q0, q1, q2) into ``points[row]``; return its status."""
    status, x, y, z = _forward_point(math.cos(q0), math.sin(q0), math.cos(q1), math.sin(q1),
                                     math.cos(q2), math.sin(q2), rx, ry, offset, upper,
                                     forearm_sq)
    points[row, 0], points[row, 1], points[row, 2] = x, y, z
    return status


@kernel(inline=True)
def _forward_point(cos0, sin0, cos1, sin1, cos2, sin2, rx, ry, offset, upper, forearm_sq):
    """Return (status, x, y, z): the TCP of joint angles given by their cosines and sines."""
    radial0 = offset + upper * cos0
    radial1 = offset + upper * cos1
    radial2 = offset + upper * cos2
    height0 = -upper * sin0
    height1 = -upper * sin1
    height2 = -upper * sin2
    cx2, cy2 = radial2 * rx[2], radial2 * ry[2]
    ax, ay, az = radial0 * rx[0] - cx2, radial0 * ry[0] - cy2, height0 - height2
    bx, by, bz = radial1 * rx[1] - cx2, radial1 * ry[1] - cy2, height1 - height2
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    normal_sq = nx * nx + ny * ny + nz * nz
    a_sq = ax * ax + ay * ay + az * az
    b_sq = bx * bx + by * by + bz * bz
    collinear = normal_sq <= (1e-12 * math.sqrt(a_sq * b_sq)) ** 2
    safe_sq = 1.0 if collinear else normal_sq
    ux, uy, uz = a_sq * bx - b_sq * ax, a_sq * by - b_sq * ay, a_sq * bz - b_sq * az
    scale = 0.5 / safe_sq
    tx, ty, tz = ((uy * nz - uz * ny) * scale, (uz * nx - ux * nz) * scale,
                  (ux * ny - uy * nx) * scale)
    height_sq = forearm_sq - (tx * tx + ty * ty + tz * tz)
    # NaN stays NaN, as np.maximum keeps it.
    down = math.sqrt(0.0 if height_sq < 0.0 else height_sq) / math.sqrt(safe_sq)
    if nz < 0.0:
        down = -down
    x, y, z = cx2 + tx - down * nx, cy2 + ty - down * ny, height2 + tz - down * nz
    status = _ASSEMBLED
    if collinear:
        status = _COLLINEAR
    elif height_sq < 0.0:
        status = _APART
    elif z >= 0.0:
        status = _ABOVE
    return status, x, y, z


@kernel
def _forward_rows(q, rx, ry, offset, upper, forearm_sq, points, status):
    """:func:`_forward_row` of every row of ``q`` (N, 3); unassembled rows get NaN."""
    for row in range(q.shape[0]):
        status[row] = _forward_row(q[row, 0], q[row, 1], q[row, 2], rx, ry, offset, upper,
                                   forearm_sq, points, row)
        if status[row] != _ASSEMBLED:
            points[row, :] = np.nan


@kernel
def _tcp_rows(q, qdot, qddot, qdddot, rx, ry, offset, upper, forearm_sq, coplanar, points,
              velocity, acceleration, jerk, status):
    """
    Per row, :func:`tcp_derivatives`: position, velocity, acceleration, jerk; status.

    A row that cannot be assembled is NaN throughout; a coplanar one (``|det A|``
    below ``coplanar``) has NaN derivatives, as ``1 / NaN`` gives in the vectorised form.
    """
    for row in range(q.shape[0]):
        state, p, v, a, j = _tcp_state(
            (q[row, 0], q[row, 1], q[row, 2]), (qdot[row, 0], qdot[row, 1], qdot[row, 2]),
            (qddot[row, 0], qddot[row, 1], qddot[row, 2]),
            (qdddot[row, 0], qdddot[row, 1], qdddot[row, 2]), rx, ry, offset, upper,
            forearm_sq, coplanar, 3)
        status[row] = state
        for axis in range(3):
            points[row, axis], velocity[row, axis] = p[axis], v[axis]
            acceleration[row, axis], jerk[row, axis] = a[axis], j[axis]


@kernel(inline=True)
def _tcp_state(q, qdot, qddot, qdddot, rx, ry, offset, upper, forearm_sq, coplanar, order):
    """
    :func:`tcp_derivatives` of one joint state; return (status, p, v, a, j).

    ``q`` and its time derivatives are 3-tuples (one entry per arm); so are the TCP
    position and its derivatives returned. Derivatives above ``order`` (1 to 3) are
    not computed (returned as 0). A pose that cannot be assembled has a NaN position
    and derivatives; a coplanar one (``|det A|`` below ``coplanar``) NaN derivatives.
    Plain floats throughout: the per-arm vectors of :func:`_arm_vectors` and the columns
    of ``A^-1 det A`` stay in registers.
    """
    trig = ((math.cos(q[0]), math.sin(q[0])), (math.cos(q[1]), math.sin(q[1])),
            (math.cos(q[2]), math.sin(q[2])))
    state, px, py, pz = _forward_point(trig[0][0], trig[0][1], trig[1][0], trig[1][1],
                                       trig[2][0], trig[2][1], rx, ry, offset, upper,
                                       forearm_sq)
    if state != _ASSEMBLED:
        px, py, pz = np.nan, np.nan, np.nan
    arms = (_arm_vectors(px, py, pz, trig[0][0], trig[0][1], rx[0], ry[0], offset, upper),
            _arm_vectors(px, py, pz, trig[1][0], trig[1][1], rx[1], ry[1], offset, upper),
            _arm_vectors(px, py, pz, trig[2][0], trig[2][1], rx[2], ry[2], offset, upper))
    # Columns k of A^-1 det A: s_(k+1) x s_(k+2).
    columns = (_cross(arms[1], arms[2]), _cross(arms[2], arms[0]), _cross(arms[0], arms[1]))
    s0 = arms[0]
    determinant = 0.0 + s0[0] * columns[0][0] + s0[1] * columns[0][1] + s0[2] * columns[0][2]
    singular = abs(determinant) < coplanar
    if singular and state == _ASSEMBLED:
        state = _COPLANAR
    inverse_det = 1.0 / (np.nan if singular else determinant)
    zero = (0.0, 0.0, 0.0)
    velocity = _solve(_speed_rhs(arms[0], qdot[0]), _speed_rhs(arms[1], qdot[1]),
                      _speed_rhs(arms[2], qdot[2]), columns, inverse_det)
    if order < 2:
        return state, (px, py, pz), velocity, zero, zero
    acceleration = _solve(_accel_rhs(arms[0], qdot[0], qddot[0], velocity),
                          _accel_rhs(arms[1], qdot[1], qddot[1], velocity),
                          _accel_rhs(arms[2], qdot[2], qddot[2], velocity), columns,
                          inverse_det)
    if order < 3:
        return state, (px, py, pz), velocity, acceleration, zero
    jerk = _solve(_jerk_rhs(arms[0], qdot[0], qddot[0], qdddot[0], velocity, acceleration),
                  _jerk_rhs(arms[1], qdot[1], qddot[1], qdddot[1], velocity, acceleration),
                  _jerk_rhs(arms[2], qdot[2], qddot[2], qdddot[2], velocity, acceleration),
                  columns, inverse_det)
    return state, (px, py, pz), velocity, acceleration, jerk


@kernel
def _arm_vectors(px, py, pz, cos_q, sin_q, rx, ry, offset, upper):
    """
    Return arm's forearm vector s, elbow derivatives b and c by q, s.b and s.c (11 floats).

    ``s = C - B`` (effector joint minus elbow), ``b = dB/dq``, ``c = d^2B/dq^2``.
    """
    reach = -offset - upper * cos_q
    upper_sin, upper_cos = upper * sin_q, upper * cos_q
    sx, sy, sz = px + reach * rx, py + reach * ry, pz + upper_sin
    bx, by, bz = -upper_sin * rx, -upper_sin * ry, -upper_cos
    cx, cy, cz = -upper_cos * rx, -upper_cos * ry, upper_sin
    return (sx, sy, sz, bx, by, bz, cx, cy, cz, sx * bx + sy * by + sz * bz,
            sx * cx + sy * cy + sz * cz)


@kernel
def _cross(first, second):
    """Return the cross product of the s vectors (entries 0-2) of two arms."""
    x, y, z = first[0], first[1], first[2]
    u, v, w = second[0], second[1], second[2]
    return y * w - z * v, z * u - x * w, x * v - y * u


@kernel
def _speed_rhs(arm, rate):
    """Right-hand side of ``s . p_dot = (s . b) q_dot`` for one arm."""
    return arm[9] * rate


@kernel
def _accel_rhs(arm, rate, rate_dot, velocity):
    """Right-hand side of ``s . p_ddot = s . (c q_dot^2 + b q_ddot) - |s_dot|^2``."""
    rate_x = velocity[0] - arm[3] * rate
    rate_y = velocity[1] - arm[4] * rate
    rate_z = velocity[2] - arm[5] * rate
    rate_sq = rate_x * rate_x + rate_y * rate_y + rate_z * rate_z
    return arm[10] * rate * rate + arm[9] * rate_dot - rate_sq


@kernel
def _jerk_rhs(arm, rate, rate_dot, rate_ddot, velocity, acceleration):
    """Right-hand side of the jerk row (see :func:`tcp_derivatives`) for one arm."""
    rate_x = velocity[0] - arm[3] * rate
    rate_y = velocity[1] - arm[4] * rate
    rate_z = velocity[2] - arm[5] * rate
    accel_x = acceleration[0] - arm[6] * rate * rate - arm[3] * rate_dot
    accel_y = acceleration[1] - arm[7] * rate * rate - arm[4] * rate_dot
    accel_z = acceleration[2] - arm[8] * rate * rate - arm[5] * rate_dot
    rate_accel = rate_x * accel_x + rate_y * accel_y + rate_z * accel_z
    return (arm[9] * (rate_ddot - rate * rate * rate) + 3.0 * arm[10] * rate * rate_dot
            - 3.0 * rate_accel)


@kernel
def _solve(rhs0, rhs1, rhs2, columns, inverse_det):
    """Return A^-1 rhs (``columns`` of A^-1 det A, ``inverse_det`` = 1 / det A)."""
    first, second, third = columns
    return ((rhs0 * first[0] + rhs1 * second[0] + rhs2 * third[0]) * inverse_det,
            (rhs0 * first[1] + rhs1 * second[1] + rhs2 * third[1]) * inverse_det,
            (rhs0 * first[2] + rhs1 * second[2] + rhs2 * third[2]) * inverse_det)


# Status codes of inverse kinematics of a row (:func:`_ik_trig_point`, :func:`_rate_point`), in
# the order the errors are reported.
_IK_OK, _IK_ABOVE, _IK_OUTSIDE, _IK_LIMIT, _IK_SINGULAR = range(5)
# A row of :func:`_joint_trig_rows` with a non-finite rate (never one that passed _as_rows).
_NOT_FINITE = 5


# The row kernels below take each point's coordinates and return its results as plain floats
# and 3-tuples (one entry per arm): a compiled call taking arrays counts their references up
# and down (atomic NRT_incref/decref), which cost a fifth of _joint_trig_rows' time when each row
# was a call with ten arrays. The arm directions, radial (x, y) and tangential (x, y), come
# as 3-tuples too.
@kernel(inline=True)
def _triple(values):
    """Return the entries of ``values`` (3,) as a 3-tuple."""
    return values[0], values[1], values[2]


@kernel(inline=True)
def _row(values, row):
    """Return row ``row`` of ``values`` (N, 3) as a 3-tuple."""
    return values[row, 0], values[row, 1], values[row, 2]


@kernel(inline=True)
def _write_row(values, row, entries):
    """Write the 3-tuple ``entries`` into row ``row`` of ``values`` (N, 3)."""
    values[row, 0], values[row, 1], values[row, 2] = entries


@kernel(inline=True)
def _ik_trig(x, y, z, rx, ry, tx, ty, offset, upper, fore_sq, upper_sq):
    """Return (in the arm's sphere, cos q, sin q) of one arm of :func:`_ik_trig_point`."""
    u = x * rx + y * ry + -offset
    w = x * tx + y * ty
    g = u * u + w * w + z * z + upper_sq - fore_sq
    discriminant = 4.0 * upper * upper * (u * u + z * z) - g * g
    if discriminant < 0.0:
        return False, 0.0, 0.0
    root = math.sqrt(discriminant)
    scale = 1.0 / (2.0 * upper * (u * u + z * z))
    return True, (u * g - z * root) * scale, -(z * g + u * root) * scale


@kernel
def _ik_rows(points, rx, ry, tx, ty, offset, upper, forearm, joint_min, joint_max, limit_trig,
             q, status, arms):
    """
    :func:`_ik_trig_point` of every row: ``status`` and ``arms`` (N,) its result, q in ``q``.

    q is ``atan2(sin q, cos q)`` of each arm where every arm is in reach (a row beyond a
    joint limit too), else 0.
    """
    radial_x, radial_y, tangent_x, tangent_y = _triple(rx), _triple(ry), _triple(tx), _triple(ty)
    for row in range(points.shape[0]):
        status[row], arms[row], _, cosines, sines = _ik_trig_point(
            points[row, 0], points[row, 1], points[row, 2], radial_x, radial_y, tangent_x,
            tangent_y, offset, upper, forearm, joint_min, joint_max, limit_trig)
        for arm in range(3):
            q[row, arm] = (math.atan2(sines[arm], cosines[arm])
                           if status[row] == _IK_OK or status[row] == _IK_LIMIT else 0.0)


@kernel(inline=True)
def _rate_arm(point, velocity, acceleration, cos_q, sin_q, rx, ry, offset, upper,
              singular_diagonal, given_rate, given):
    """
    Return (regular, s.b, q_dot, q_ddot) of one arm of :func:`_rate_point`.

    ``q_dot`` is ``given_rate`` if ``given``, else computed; ``regular`` is False (and the
    rates 0) where ``|s.b|`` is below ``singular_diagonal``.
    """
    x, y, z = point
    reach = -offset - upper * cos_q
    upper_sin, upper_cos = upper * sin_q, upper * cos_q
    sx, sy, sz = x + reach * rx, y + reach * ry, z + upper_sin
    bx, by, bz = -upper_sin * rx, -upper_sin * ry, -upper_cos
    diagonal = sx * bx + sy * by + sz * bz
    if abs(diagonal) < singular_diagonal:
        return False, diagonal, 0.0, 0.0
    rate = given_rate if given else (sx * velocity[0] + sy * velocity[1]
                                     + sz * velocity[2]) / diagonal
    rate_x = velocity[0] - bx * rate
    rate_y = velocity[1] - by * rate
    rate_z = velocity[2] - bz * rate
    numerator = (sx * acceleration[0] + sy * acceleration[1] + sz * acceleration[2]
                 + (rate_x * rate_x + rate_y * rate_y + rate_z * rate_z)
                 - (sx * (-upper_cos * rx) + sy * (-upper_cos * ry) + sz * upper_sin)
                 * rate * rate)
    return True, diagonal, rate, numerator / diagonal


@kernel(inline=True)
def _rate_point(point, velocity, acceleration, cos_q, sin_q, rx, ry, offset, upper,
                singular_diagonal, given_rates, given):
    """
    Joint rates of one pose (analytic Jacobian); return (singular arm or -1, its s.b, rates).

    Differentiating ``|s_i|^2 = L2^2`` with ``s_i = C_i - B_i`` the forearm vector gives
    the standard Delta form ``A p_dot = B q_dot`` with rows ``A_i = s_i^T`` and
    ``B = diag(s_i . b_i)``, ``b_i = dB_i/dq_i``; once more, with ``c_i = d^2B_i/dq_i^2``,
    ``q_ddot_i = (s_i . p_ddot + |s_dot_i|^2 - (s_i . c_i) q_dot_i^2) / (s_i . b_i)``,
    ``s_dot_i = p_dot - b_i q_dot_i``. ``point``, ``velocity``, ``acceleration``, ``cos_q``,
    ``sin_q`` and the radial directions ``rx``, ``ry`` are 3-tuples; so are the rates
    (q_dot, q_ddot). ``q_dot`` is ``given_rates`` if ``given``, else computed. At a
    singularity (an arm's ``|s_i . b_i|`` below ``singular_diagonal``) the arm with the
    smallest ``|s_i . b_i|`` is returned.
    """
    regular0, diagonal0, rate0, accel0 = _rate_arm(
        point, velocity, acceleration, cos_q[0], sin_q[0], rx[0], ry[0], offset, upper,
        singular_diagonal, given_rates[0], given)
    regular1, diagonal1, rate1, accel1 = _rate_arm(
        point, velocity, acceleration, cos_q[1], sin_q[1], rx[1], ry[1], offset, upper,
        singular_diagonal, given_rates[1], given)
    regular2, diagonal2, rate2, accel2 = _rate_arm(
        point, velocity, acceleration, cos_q[2], sin_q[2], rx[2], ry[2], offset, upper,
        singular_diagonal, given_rates[2], given)
    rates = ((rate0, rate1, rate2), (accel0, accel1, accel2))
    if regular0 and regular1 and regular2:
        return -1, 0.0, rates
    smallest, smallest_arm = np.inf, 0
    for arm, diagonal in enumerate((diagonal0, diagonal1, diagonal2)):
        if abs(diagonal) < abs(smallest):
            smallest, smallest_arm = diagonal, arm
    return smallest_arm, smallest, rates


@kernel
def _rate_rows(points, velocities, accelerations, q, rx, ry, offset, upper, singular_diagonal,
               qdot, qddot, given_qdot):
    """
    Run :func:`_rate_point` on every row; return the first singular (row, arm, s.b) or row -1.

    ``q_dot`` is read from ``qdot`` if ``given_qdot``, else written there.
    """
    radial_x, radial_y = _triple(rx), _triple(ry)
    for row in range(points.shape[0]):
        cos0, sin0 = math.cos(q[row, 0]), math.sin(q[row, 0])
        cos1, sin1 = math.cos(q[row, 1]), math.sin(q[row, 1])
        cos2, sin2 = math.cos(q[row, 2]), math.sin(q[row, 2])
        cos_q, sin_q = (cos0, cos1, cos2), (sin0, sin1, sin2)
        arm, diagonal, rates = _rate_point(
            _row(points, row), _row(velocities, row), _row(accelerations, row), cos_q, sin_q,
            radial_x, radial_y, offset, upper, singular_diagonal, _row(qdot, row), given_qdot)
        if arm >= 0:
            return row, arm, diagonal
        _write_row(qdot, row, rates[0])
        _write_row(qddot, row, rates[1])
    return -1, 0, 0.0


@kernel(inline=True)
def _ik_trig_point(x, y, z, rx, ry, tx, ty, offset, upper, forearm, joint_min, joint_max,
                   limit_trig):
    """
    Elbow-out IK of the point (x, y, z); return (status, failing arm, value, cos q, sin q).

    ``cos q`` and ``sin q`` are 3-tuples (arm 0, 1, 2; zeros where an arm is out of reach),
    without a trigonometric call: with ``rho^2 = u^2 + z^2`` and
    ``sqrt(D^2 + G^2) = 2 L1 rho``, ``cos q = (u G - z sqrt(D)) / (2 L1 rho^2)`` and
    ``sin q = -(z G + u sqrt(D)) / (2 L1 rho^2)``; q is their ``atan2`` (here only for a
    joint limit near it, :func:`_inside_joint_limits`). ``value`` is the failing arm's q
    (``_IK_LIMIT``), else 0.

    The constraint of arm i, written in its vertical plane with ``u`` the radial and ``w`` the
    tangential coordinate of ``C_i - A_i`` and ``z`` the height, is
    ``E cos q + F sin q + G = 0`` with ``E = -2 L1 u``, ``F = 2 L1 z`` and
    ``G = u^2 + w^2 + z^2 + L1^2 - L2^2``. The half-angle substitution turns it into the
    classic quadratic ``(G - E) tau^2 + 2 F tau + (G + E) = 0`` in ``tau = tan(q / 2)``, whose
    discriminant is ``D = E^2 + F^2 - G^2``. Its two roots are written here in the equivalent
    atan2 form ``q = -atan2(z, u) -+ atan2(sqrt(D), G)``, which needs no division by
    ``G - E``; the minus sign is the elbow-out branch (elbow on the outer side of the line
    from the actuator axis to the effector joint). Checked in the order the errors are
    named: above the base (or not finite), outside an arm's sphere, beyond a joint limit.
    """
    zero = (0.0, 0.0, 0.0)
    if not (z < 0.0 and abs(x) + abs(y) + abs(z) < np.inf):
        return _IK_ABOVE, 0, 0.0, zero, zero
    fore_sq = forearm * forearm
    upper_sq = upper * upper
    inside0, cos0, sin0 = _ik_trig(x, y, z, rx[0], ry[0], tx[0], ty[0], offset, upper,
                                   fore_sq, upper_sq)
    if not inside0:
        return _IK_OUTSIDE, 0, 0.0, zero, zero
    inside1, cos1, sin1 = _ik_trig(x, y, z, rx[1], ry[1], tx[1], ty[1], offset, upper,
                                   fore_sq, upper_sq)
    if not inside1:
        return _IK_OUTSIDE, 1, 0.0, zero, zero
    inside2, cos2, sin2 = _ik_trig(x, y, z, rx[2], ry[2], tx[2], ty[2], offset, upper,
                                   fore_sq, upper_sq)
    if not inside2:
        return _IK_OUTSIDE, 2, 0.0, zero, zero
    cos_q, sin_q = (cos0, cos1, cos2), (sin0, sin1, sin2)
    for arm in range(3):
        if not _inside_joint_limits(cos_q[arm], sin_q[arm], joint_min, joint_max, limit_trig):
            return _IK_LIMIT, arm, math.atan2(sin_q[arm], cos_q[arm]), cos_q, sin_q
    return _IK_OK, 0, 0.0, cos_q, sin_q


@kernel
def _joint_trig_rows(points, velocities, accelerations, rx, ry, tx, ty, offset, upper, forearm,
                     joint_min, joint_max, singular_diagonal, limit_trig, cos_q, sin_q, qdot,
                     qddot, peaks):
    """
    Per row, :func:`joint_trig_motion`'s IK (cos q, sin q) and rates; their peaks in ``peaks``.

    ``peaks`` (2,) gets the largest |q_dot| and |q_ddot| (NaN if one is) of all rows.
    Stops at the first row that fails (out of reach, beyond a joint limit, at an IK
    singularity, a non-finite velocity or acceleration) and returns (row, status, arm,
    value) for :func:`_joint_failure`; row -1 when every row succeeds.
    """
    radial_x, radial_y, tangent_x, tangent_y = _triple(rx), _triple(ry), _triple(tx), _triple(ty)
    peak_velocity, peak_accel = 0.0, 0.0
    for row in range(points.shape[0]):
        point = _row(points, row)
        status, arm, value, cosines, sines = _ik_trig_point(
            point[0], point[1], point[2], radial_x, radial_y, tangent_x, tangent_y, offset,
            upper, forearm, joint_min, joint_max, limit_trig)
        if status != _IK_OK:
            return row, status, arm, value
        velocity, acceleration = _row(velocities, row), _row(accelerations, row)
        for axis in range(3):
            if not (math.isfinite(velocity[axis]) and math.isfinite(acceleration[axis])):
                return row, _NOT_FINITE, 0, 0.0
        _write_row(cos_q, row, cosines)
        _write_row(sin_q, row, sines)
        arm, diagonal, rates = _rate_point(
            point, velocity, acceleration, cosines, sines, radial_x, radial_y, offset, upper,
            singular_diagonal, (0.0, 0.0, 0.0), False)
        if arm >= 0:
            return row, _IK_SINGULAR, arm, diagonal
        _write_row(qdot, row, rates[0])
        _write_row(qddot, row, rates[1])
        peak_velocity = _larger_magnitude(peak_velocity, rates[0])
        peak_accel = _larger_magnitude(peak_accel, rates[1])
    peaks[0], peaks[1] = peak_velocity, peak_accel
    return -1, _IK_OK, 0, 0.0


@kernel(inline=True)
def _larger_magnitude(peak, rates):
    """Return the largest of ``peak`` and the magnitudes of ``rates`` (a NaN stays, as in max)."""
    for magnitude in (abs(rates[0]), abs(rates[1]), abs(rates[2])):
        if peak == peak and not magnitude <= peak:
            peak = magnitude
    return peak


@kernel
def _angle_rows(cos_q, sin_q, q):
    """Fill ``q`` (N, 3) with ``atan2(sin_q, cos_q)``: the call :func:`_ik_rows` makes."""
    for row in range(q.shape[0]):
        for arm in range(3):
            q[row, arm] = math.atan2(sin_q[row, arm], cos_q[row, arm])


# An angle whose sines from both joint limits exceed this share of |cos q| + |sin q| is inside
# the limits without its atan2: far beyond any rounding of the cross products (~1e-15).
_LIMIT_TEST_MARGIN = 1e-9


@kernel(inline=True)
def _inside_joint_limits(cos_q, sin_q, joint_min, joint_max, limit_trig):
    """
    Return whether ``q = atan2(sin_q, cos_q)`` is within ``[joint_min, joint_max]``.

    With usable ``limit_trig`` (:func:`_limit_trig`), an angle well inside (both
    ``sin(q - joint_min)`` and ``sin(joint_max - q)``, times ``|(cos q, sin q)|``, above
    ``_LIMIT_TEST_MARGIN``) is inside without its atan2; else q is computed and compared.
    """
    cos_min, sin_min, cos_max, sin_max, usable = limit_trig
    margin = _LIMIT_TEST_MARGIN * (abs(cos_q) + abs(sin_q))
    if (usable and sin_q * cos_min - cos_q * sin_min > margin
            and sin_max * cos_q - cos_max * sin_q > margin):
        return True
    q = math.atan2(sin_q, cos_q)
    return not (q < joint_min or q > joint_max)


@kernel
def _speed_cap_rows(positions, directions, extra, rx, ry, tx, ty, offset, upper, forearm,
                    joint_min, joint_max, singular_diagonal, limit_trig, limit, caps):
    """
    Fill ``caps`` (N,) with :func:`joint_speed_caps`; return whether every point succeeds.

    The points and directions are the columns of ``positions`` and ``directions`` (3, N);
    then the point ``extra`` (a 3-tuple; NaN coordinates: none) must be reachable too. Stops
    at the first point out of reach or beyond a joint limit (:func:`_ik_trig_point`) or at
    an IK singularity (:func:`_rate_point`).
    """
    radial_x, radial_y, tangent_x, tangent_y = _triple(rx), _triple(ry), _triple(tx), _triple(ty)
    zero = (0.0, 0.0, 0.0)
    for row in range(positions.shape[1]):
        x, y, z = positions[0, row], positions[1, row], positions[2, row]
        status, _, _, cosines, sines = _ik_trig_point(
            x, y, z, radial_x, radial_y, tangent_x, tangent_y, offset, upper, forearm,
            joint_min, joint_max, limit_trig)
        if status != _IK_OK:
            return False
        arm, _, rates = _rate_point(
            (x, y, z), (directions[0, row], directions[1, row], directions[2, row]), zero,
            cosines, sines, radial_x, radial_y, offset, upper, singular_diagonal, zero, False)
        if arm >= 0:
            return False
        speed = rates[0]
        caps[row] = limit / max(max(max(abs(speed[0]), abs(speed[1])), abs(speed[2])), 1e-12)
    if extra[0] != extra[0]:
        return True
    return _ik_trig_point(extra[0], extra[1], extra[2], radial_x, radial_y, tangent_x,
                          tangent_y, offset, upper, forearm, joint_min, joint_max,
                          limit_trig)[0] == _IK_OK
