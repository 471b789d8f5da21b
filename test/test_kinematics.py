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

"""Tests of the rotary Delta kinematics: closed forms, branches, errors and rates."""

import dataclasses
import math

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import UnreachableError
from ellipath_ros.core.kinematics import _inside_joint_limits
from ellipath_ros.core.kinematics import _limit_trig
from ellipath_ros.core.kinematics import check_reachable
from ellipath_ros.core.kinematics import DeltaGeometry
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.kinematics import joint_accelerations
from ellipath_ros.core.kinematics import joint_angles
from ellipath_ros.core.kinematics import joint_motion
from ellipath_ros.core.kinematics import joint_speed_caps
from ellipath_ros.core.kinematics import joint_trig_motion
from ellipath_ros.core.kinematics import joint_velocities
from ellipath_ros.core.kinematics import JointLimits
from ellipath_ros.core.kinematics import reachable
from ellipath_ros.core.kinematics import tcp_derivatives
import numpy as np
import pytest

GEOMETRY = DeltaGeometry()
GOOD = [[0.0, 0.0, -0.8], [0.1, -0.05, -0.7], [-0.2, 0.1, -0.9]]


def workspace_points(seed, count):
    """Random points in the cylinder r <= 0.35 m, z in [-1.0, -0.55] m."""
    rng = np.random.default_rng(seed)
    radius = 0.35 * np.sqrt(rng.uniform(0.0, 1.0, count))
    angle = rng.uniform(0.0, 2.0 * np.pi, count)
    z = rng.uniform(-1.0, -0.55, count)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle), z], axis=1)


class Helix:
    """A smooth analytic TCP motion: a circle in x-y with a sinusoidal height."""

    centre = np.array([0.05, -0.03, -0.8])
    radius, omega, height, nu = 0.2, 9.0, 0.1, 13.0

    def state_at(self, t):
        """Position, velocity and acceleration at times t (N,)."""
        t = np.asarray(t, dtype=float)
        w, n = self.omega, self.nu
        c, s, cz, sz = np.cos(w * t), np.sin(w * t), np.cos(n * t), np.sin(n * t)
        zero = np.zeros_like(t)
        position = self.centre + np.stack(
            [self.radius * c, self.radius * s, self.height * sz], axis=1)
        velocity = np.stack(
            [-self.radius * w * s, self.radius * w * c, self.height * n * cz], axis=1)
        acceleration = np.stack(
            [-self.radius * w * w * c, -self.radius * w * w * s, zero - self.height * n * n * sz],
            axis=1)
        return position, velocity, acceleration


def test_default_geometry_and_limits_match_the_design():
    assert (GEOMETRY.base_radius, GEOMETRY.effector_radius, GEOMETRY.upper_arm,
            GEOMETRY.forearm) == (0.200, 0.045, 0.350, 0.800)
    assert GEOMETRY.joint_min < 0.0 < GEOMETRY.joint_max
    limits = JointLimits()
    assert (limits.max_velocity, limits.max_acceleration) == (10.0, 200.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        GEOMETRY.forearm = 1.0


@pytest.mark.parametrize('changes, field', [
    ({'base_radius': 0.0}, 'base_radius'),
    ({'effector_radius': -0.01}, 'effector_radius'),
    ({'upper_arm': float('nan')}, 'upper_arm'),
    ({'forearm': 0.1}, 'forearm'),
    ({'joint_min': 1.0, 'joint_max': 0.5}, 'joint_max'),
    ({'joint_max': 4.0}, 'joint_max'),
    ({'joint_min': 'low'}, 'joint_min'),
])
def test_geometry_rejects_bad_values(changes, field):
    with pytest.raises(InvalidInputError, match=rf'^{field}: expected .*, got'):
        DeltaGeometry(**changes)


@pytest.mark.parametrize('changes, field', [
    ({'max_velocity': 0.0}, 'max_joint_velocity'),
    ({'max_acceleration': -1.0}, 'max_joint_accel'),
    ({'max_velocity': float('inf')}, 'max_joint_velocity'),
])
def test_joint_limits_reject_bad_values(changes, field):
    with pytest.raises(InvalidInputError, match=rf'^{field}: expected .*, got'):
        JointLimits(**changes)


def test_forward_of_inverse_round_trips():
    points = workspace_points(seed=7, count=2000)
    q = inverse_kinematics(points, GEOMETRY)
    assert q.shape == (2000, 3)
    np.testing.assert_allclose(forward_kinematics(q, GEOMETRY), points, rtol=0.0, atol=1e-9)


def test_inverse_of_forward_round_trips():
    # Inside this box every pose is in the elbow-out working mode that IK returns.
    q = np.random.default_rng(11).uniform(0.1, 1.2, size=(2000, 3))
    points = forward_kinematics(q, GEOMETRY)
    assert (points[:, 2] < 0.0).all()
    np.testing.assert_allclose(inverse_kinematics(points, GEOMETRY), q, rtol=0.0, atol=1e-9)


def test_single_point_keeps_its_shape():
    q = inverse_kinematics(GOOD[1], GEOMETRY)
    assert q.shape == (3,)
    assert forward_kinematics(q, GEOMETRY).shape == (3,)
    with pytest.raises(InvalidInputError, match=r'shape'):
        inverse_kinematics(np.zeros((4, 2)), GEOMETRY)


@pytest.mark.parametrize('z', [-0.8, -0.6, -1.0])
def test_on_axis_pose_matches_hand_derived_angle(z):
    # In the plane of any arm: elbow (R + L1 cos q, -L1 sin q), effector joint (r, z).
    # |joint - elbow| = L2 gives d cos q + z sin q = k / (2 L1) with d = R - r and
    # k = L2^2 - L1^2 - d^2 - z^2, i.e. rho cos(q - phi) = k / (2 L1) with
    # rho = hypot(d, z), phi = atan2(z, d); the elbow-out root is phi + acos(...).
    big_r, small_r, upper, fore = 0.200, 0.045, 0.350, 0.800
    d = big_r - small_r
    k = fore ** 2 - upper ** 2 - d ** 2 - z ** 2
    expected = math.atan2(z, d) + math.acos(k / (2.0 * upper * math.hypot(d, z)))
    q = inverse_kinematics([0.0, 0.0, z], GEOMETRY)
    assert q[0] == q[1] == q[2]
    assert abs(q[0] - expected) < 1e-12
    np.testing.assert_allclose(forward_kinematics(q, GEOMETRY), [0.0, 0.0, z], atol=1e-12)


@pytest.mark.parametrize('angle', [0.3, 1.2, 3.0])
def test_forward_returns_the_lower_of_the_two_solutions(angle):
    # Equal angles: the three sphere centres lie on a horizontal circle of radius
    # |R - r + L1 cos q| at height -L1 sin q; the effector is L2 away from all of them, on the
    # axis, above or below. For q = 3 the centres are past the axis (negative radius).
    radius = 0.200 - 0.045 + 0.350 * math.cos(angle)
    lower = -0.350 * math.sin(angle) - math.sqrt(0.800 ** 2 - radius ** 2)
    np.testing.assert_allclose(forward_kinematics([angle] * 3, GEOMETRY), [0.0, 0.0, lower],
                               rtol=0.0, atol=1e-12)


@pytest.mark.parametrize('q', [[0.2, 0.9, 1.4], [-0.5, 0.4, 1.9], [2.9, 1.0, 1.0]])
def test_forward_solves_the_loop_closure_below_the_mirror_solution(q):
    # Any pose, even one where the sphere centres run clockwise: the result is L2 from every
    # centre, and its mirror image in the centres' plane (the other solution) is higher.
    point = forward_kinematics(q, GEOMETRY)
    centres = []
    for arm, angle in enumerate(q):
        azimuth = 2.0 * math.pi * arm / 3.0
        radial = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
        elbow = (0.200 + 0.350 * math.cos(angle)) * radial - [0.0, 0.0, 0.350 * math.sin(angle)]
        centres.append(elbow - 0.045 * radial)
    distances = np.linalg.norm(point - np.array(centres), axis=1)
    np.testing.assert_allclose(distances, 0.800, rtol=0.0, atol=1e-12)
    normal = np.cross(centres[1] - centres[0], centres[2] - centres[0])
    normal /= np.linalg.norm(normal)
    mirror = point - 2.0 * np.dot(point - centres[0], normal) * normal
    assert point[2] < mirror[2] - 1e-3


def test_inverse_picks_the_elbow_out_root_of_the_half_angle_quadratic():
    points = workspace_points(seed=3, count=200)
    big_r, small_r, upper, fore = 0.200, 0.045, 0.350, 0.800
    q = inverse_kinematics(points, GEOMETRY)
    for arm in range(3):
        angle = 2.0 * math.pi * arm / 3.0
        radial = np.array([math.cos(angle), math.sin(angle), 0.0])
        tangent = np.array([-math.sin(angle), math.cos(angle), 0.0])
        rel = points + (small_r - big_r) * radial
        u, w, z = rel @ radial, rel @ tangent, points[:, 2]
        e, f = -2.0 * upper * u, 2.0 * upper * z
        g = u * u + w * w + z * z + upper ** 2 - fore ** 2
        # (g - e) tau^2 + 2 f tau + (g + e) = 0 with tau = tan(q / 2).
        root = np.sqrt(e * e + f * f - g * g)
        roots = 2.0 * np.arctan(np.stack([(-f + root) / (g - e), (-f - root) / (g - e)]))
        outer = np.argmax(np.cos(roots), axis=0)  # larger elbow radius R + L1 cos q
        np.testing.assert_allclose(q[:, arm], roots[outer, np.arange(points.shape[0])],
                                   atol=1e-9)


@pytest.mark.parametrize('bad, error, reason', [
    ([2.0, 0.0, -0.8], UnreachableError, r'outside the sphere of arm 0: too far'),
    ([0.0, 0.0, -0.1], UnreachableError, r'outside the sphere of arm 0: too close'),
    ([0.0, 0.0, 0.1], UnreachableError, r'above the base plane'),
    ([0.1, 0.0, 0.0], UnreachableError, r'above the base plane'),
    ([0.4, 0.0, -0.5], UnreachableError, r'joint limit: arm 0 needs q=-1\.01'),
    ([float('nan'), 0.0, -0.8], InvalidInputError, r'got \(nan, 0, -0\.8\)'),
])
def test_unreachable_points_are_named_by_index(bad, error, reason):
    points = GOOD + [bad] + GOOD
    with pytest.raises(error, match=rf'^points\[3\]: expected .*{reason}') as caught:
        inverse_kinematics(points, GEOMETRY)
    if error is UnreachableError:
        assert caught.value.index == 3
        with pytest.raises(UnreachableError, match=r'^way\[3\]'):
            check_reachable(points, GEOMETRY, name='way')
    expected = np.ones(len(points), dtype=bool)
    expected[3] = False
    np.testing.assert_array_equal(reachable(points, GEOMETRY), expected)


def test_joint_limit_of_a_narrower_geometry():
    narrow = DeltaGeometry(joint_max=0.3)
    with pytest.raises(UnreachableError, match=r'^points\[0\].*arm 0 needs q=0\.451.*'
                                               r'outside \[-0\.85, 0\.3\] rad'):
        inverse_kinematics([GOOD[0]], narrow)
    assert not reachable(GOOD[0], narrow)
    assert reachable(GOOD[0], GEOMETRY)


def test_forward_rejects_joint_angles_that_cannot_assemble():
    q = [[0.3, 0.3, 0.3], [0.0, 0.0, 3.0]]
    with pytest.raises(UnreachableError, match=r'^q\[1\]: .*cannot meet') as caught:
        forward_kinematics(q, GEOMETRY)
    assert caught.value.index == 1
    loose = forward_kinematics(q, GEOMETRY, strict=False)
    assert np.isfinite(loose[0]).all() and np.isnan(loose[1]).all()


def test_rates_match_finite_differences_of_inverse_kinematics():
    motion = Helix()
    times = np.linspace(0.0, 0.7, 41)
    step = 1e-5
    position, velocity, acceleration = motion.state_at(times)
    q = inverse_kinematics(position, GEOMETRY)
    qdot = joint_velocities(position, q, velocity, GEOMETRY)
    qddot = joint_accelerations(position, q, velocity, acceleration, qdot, GEOMETRY)
    before = inverse_kinematics(motion.state_at(times - step)[0], GEOMETRY)
    after = inverse_kinematics(motion.state_at(times + step)[0], GEOMETRY)
    qdot_fd = (after - before) / (2.0 * step)
    qddot_fd = (after - 2.0 * q + before) / step ** 2
    assert np.abs(qdot).max() > 1.0 and np.abs(qddot).max() > 10.0  # a real test
    assert np.abs(qdot - qdot_fd).max() <= 1e-5 * np.abs(qdot).max()
    assert np.abs(qddot - qddot_fd).max() <= 1e-5 * np.abs(qddot).max()


def test_rates_of_a_single_sample_keep_its_shape():
    position, velocity, acceleration = (array[0] for array in Helix().state_at([0.1]))
    q = inverse_kinematics(position, GEOMETRY)
    qdot = joint_velocities(position, q, velocity, GEOMETRY)
    assert qdot.shape == (3,)
    assert joint_accelerations(position, q, velocity, acceleration, qdot, GEOMETRY).shape == (3,)
    with pytest.raises(InvalidInputError, match=r'^velocities: expected shape \(1, 3\)'):
        joint_velocities([position], [q], [velocity, velocity], GEOMETRY)


def test_stretched_arm_is_a_singularity():
    # On the axis with every arm stretched: upper arm and forearm aligned, s . b = 0.
    d, reach = 0.155, 0.350 + 0.800
    z = -math.sqrt(reach ** 2 - d ** 2)
    angle = math.atan2(-z, -d)
    points = np.array([GOOD[0], [0.0, 0.0, z]])
    q = np.array([inverse_kinematics(GOOD[0], GEOMETRY), [angle] * 3])
    with pytest.raises(UnreachableError, match=r'^points\[1\]: .*singularit') as caught:
        joint_velocities(points, q, np.ones((2, 3)), GEOMETRY)
    assert caught.value.index == 1
    with pytest.raises(UnreachableError, match=r'^points\[1\]'):
        joint_accelerations(points, q, np.ones((2, 3)), np.ones((2, 3)), np.ones((2, 3)),
                            GEOMETRY)


def test_tcp_derivatives_match_differences_of_forward_kinematics():
    """Exact TCP velocity, acceleration and jerk of a joint motion, against FK differences."""
    rng = np.random.default_rng(7)
    q0 = inverse_kinematics(np.array([0.1, -0.05, -0.85]), GEOMETRY)
    # A quartic joint motion with rates of a fast pick: q_dot ~ 5 rad/s, q_ddot ~ 100 rad/s^2.
    rates = rng.normal(size=(4, 3)) * np.array([5.0, 100.0, 3e3, 3e4])[:, np.newaxis]

    def joints(t, order=0):
        powers = [t ** k / math.factorial(k) for k in range(5)]
        value = q0 if order == 0 else 0.0
        return value + sum(rates[k - 1] * powers[k - order] for k in range(max(order, 1), 5))

    times = np.array([0.0, 0.013, 0.04])
    p, v, a, j = tcp_derivatives(*(np.array([joints(t, order) for t in times])
                                   for order in range(4)), GEOMETRY)
    h = 5e-5
    for index, t in enumerate(times):
        at = [forward_kinematics(joints(t + k * h), GEOMETRY) for k in (-2, -1, 0, 1, 2)]
        differences = ((at[3] - at[1]) / (2 * h), (at[3] - 2 * at[2] + at[1]) / h ** 2,
                       (at[4] - 2 * at[3] + 2 * at[1] - at[0]) / (2 * h ** 3))
        np.testing.assert_allclose(p[index], at[2], atol=1e-12)
        for exact, difference in zip((v[index], a[index], j[index]), differences):
            # The differences are good to ~1e-4 of the value at this step.
            assert np.abs(exact - difference).max() <= 1e-3 * np.abs(difference).max()


def test_joint_motion_is_inverse_kinematics_and_its_rates():
    points = np.array(GOOD)
    velocities = np.array([[0.5, -1.0, 0.2], [2.0, 0.0, -1.0], [0.0, 1.5, 1.5]])
    accelerations = np.array([[10.0, 0.0, -30.0], [-5.0, 20.0, 0.0], [40.0, -10.0, 5.0]])
    q, qdot, qddot = joint_motion(points, velocities, accelerations, GEOMETRY)
    np.testing.assert_array_equal(q, inverse_kinematics(points, GEOMETRY))
    np.testing.assert_allclose(qdot, joint_velocities(points, q, velocities, GEOMETRY))
    np.testing.assert_allclose(qddot, joint_accelerations(points, q, velocities, accelerations,
                                                          qdot, GEOMETRY))
    with pytest.raises(UnreachableError, match=r'^points\[1\]'):
        joint_motion([[0.0, 0.0, -0.8], [0.0, 0.0, 0.1]], velocities[:2], accelerations[:2],
                     GEOMETRY)


def test_joint_speed_caps_are_the_limit_over_the_largest_rate_or_none_at_any_failure():
    points = np.array(GOOD)
    directions = np.array([[0.5, -1.0, 0.2], [2.0, 0.0, -1.0], [0.0, 0.0, 0.0]])
    caps = joint_speed_caps(points, directions, GEOMETRY, 8.0)
    _, qdot, _ = joint_motion(points, directions, np.zeros((3, 3)), GEOMETRY)
    # joint_motion's rates, bit for bit; no rate counts as 1e-12.
    largest = np.maximum(np.abs(qdot).max(axis=1), 1e-12)
    np.testing.assert_array_equal(caps, 8.0 / largest)
    assert caps[2] == 8.0 / 1e-12
    # Out of reach (above the base, beyond an arm's sphere), the stretched-arm singularity,
    # beyond a joint limit: no caps, no error.
    d, reach = 0.155, 0.350 + 0.800
    stretched = [0.0, 0.0, -math.sqrt(reach ** 2 - d ** 2)]
    for bad, why in (([0.0, 0.0, 0.1], 'above'), ([0.0, 0.0, -1.5], 'too far'),
                     (stretched, 'singularities'), ([0.5, 0.0, -0.5], 'joint limit')):
        with pytest.raises(UnreachableError, match=why):
            joint_motion([bad], np.ones((1, 3)), np.zeros((1, 3)), GEOMETRY)
        assert joint_speed_caps(np.vstack((points, bad)), np.ones((4, 3)), GEOMETRY,
                                8.0) is None


@pytest.mark.parametrize('low, high', [(-0.85, 1.95), (-3.0, 1.0), (0.3, 0.6)])
def test_joint_speed_caps_judge_joint_limits_as_inverse_kinematics(low, high):
    # Points on a fine grid through both limits of arm 0 (the default limits, limits the
    # cross-product test cannot serve, close limits), in the order of their angles.
    geometry = dataclasses.replace(GEOMETRY, joint_min=low, joint_max=high)
    x = np.linspace(-0.6, 0.6, 241)
    points = np.array([[value, 0.0, height] for value in x
                       for height in np.linspace(-1.1, -0.3, 81)])
    inside = reachable(points, geometry)
    assert inside.any() and not inside.all()
    for point, expected in zip(points, inside):
        caps = joint_speed_caps(point[np.newaxis], np.zeros((1, 3)), geometry, 1.0)
        assert (caps is not None) == expected


@pytest.mark.parametrize('low, high', [(-0.85, 1.95), (-3.0, 1.0), (0.3, 0.6)])
def test_joint_trig_motion_gives_the_angles_and_errors_of_inverse_kinematics(low, high):
    # On a grid through both limits of arm 0, where joint_trig_motion judges the limits
    # without the angles: the angles from its cos q and sin q bit for bit, or the same error.
    geometry = dataclasses.replace(GEOMETRY, joint_min=low, joint_max=high)
    points = np.array([[value, 0.0, height] for value in np.linspace(-0.6, 0.6, 61)
                       for height in np.linspace(-1.1, -0.3, 21)])
    rates = (np.ones((1, 3)), np.zeros((1, 3)))
    failures = 0
    for point in points:
        try:
            expected = inverse_kinematics(point[np.newaxis], geometry)
        except UnreachableError as error:
            failures += 1
            with pytest.raises(UnreachableError) as caught:
                joint_trig_motion(point[np.newaxis], *rates, geometry)
            assert str(caught.value) == str(error)
            continue
        cos_q, sin_q, _, _ = joint_trig_motion(point[np.newaxis], *rates, geometry)
        np.testing.assert_array_equal(joint_angles(cos_q, sin_q), expected)
    assert 0 < failures < len(points)


@pytest.mark.parametrize('low, high', [(-0.85, 1.95), (-3.0, 1.0), (-1.0, math.pi)])
def test_joint_limits_judged_from_cos_and_sin_as_from_the_angle(low, high):
    limit_trig = _limit_trig(dataclasses.replace(GEOMETRY, joint_min=low, joint_max=high))
    # Angles at, and a few rounding steps to a millionth of a radian either side of, each
    # limit, and across the circle; cos and sin not quite of unit length, as IK gives them.
    offsets = np.concatenate((-np.logspace(-16, -6, 41), [0.0], np.logspace(-16, -6, 41)))
    angles = np.concatenate((low + offsets, high + offsets, np.linspace(-np.pi, np.pi, 721)))
    for angle in angles:
        for length in (1.0 - 1e-15, 1.0, 1.0 + 1e-15):
            cos_q, sin_q = length * math.cos(angle), length * math.sin(angle)
            q = math.atan2(sin_q, cos_q)
            expected = not (q < low or q > high)
            assert _inside_joint_limits(cos_q, sin_q, low, high, limit_trig) == expected
