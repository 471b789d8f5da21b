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
The compiled evaluation loops give what their plain-Python execution gives, bit for bit.

Kinematics, JTC's interpolation and its executed peaks, the knot search's deviations and the
path and law evaluation run as numba kernels (``compiled.kernel``: no fastmath). Their
results are claimed equal to the same operations interpreted: a compiler option that
reassociated or fused them (fastmath, contraction into FMA) would break these comparisons.
Each case is run once compiled (this process) and once with ``NUMBA_DISABLE_JIT=1`` (a
subprocess), and the raw bytes are compared.
"""

import os
from pathlib import Path
import subprocess
import sys
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _evaluations():
    """Return the arrays of every compiled evaluation on a small seeded case."""
    from ellipath_ros.core.geometry import plan_path
    from ellipath_ros.core.joint_trajectory import (
        DEFAULT_JOINT_NAMES, executed_table, JointTrajectoryData, MotionSamples,
        quintic_interpolate)
    from ellipath_ros.core.kinematics import (
        DeltaGeometry, forward_kinematics, joint_motion, tcp_derivatives)
    from ellipath_ros.core.knots import minimal_knots
    from ellipath_ros.core.motion import _cartesian, _pieces_law

    rng = np.random.default_rng(11)
    geometry = DeltaGeometry()
    points = np.column_stack((rng.uniform(-0.3, 0.3, 40), rng.uniform(-0.3, 0.3, 40),
                              rng.uniform(-0.95, -0.6, 40)))
    velocities, accelerations = rng.normal(size=(2, 40, 3)) * np.array([1.0, 20.0])[:, None, None]
    q, qdot, qddot = joint_motion(points, velocities, accelerations, geometry)
    results = [q, qdot, qddot, forward_kinematics(q, geometry),
               *tcp_derivatives(q, qdot, qddot, 100.0 * qddot, geometry),
               # Poses that cannot all be assembled: NaN rows, not errors.
               *tcp_derivatives(rng.uniform(-3.0, 3.0, (40, 3)), qdot, qddot, qddot,
                                geometry, strict=False)]
    times = np.concatenate(([0.0], np.cumsum(rng.uniform(0.005, 0.02, 7))))
    knots = JointTrajectoryData(DEFAULT_JOINT_NAMES, times, q[:8], qdot[:8], qddot[:8])
    results += [executed_table(knots, geometry),
                *quintic_interpolate(knots, rng.uniform(-0.01, times[-1] + 0.01, 30))]
    path = plan_path(points[0], points[1], join='g2')
    lengths = rng.uniform(-0.01, path.length + 0.01, 60)
    results += list(path.rows_at_lengths(lengths))
    law = _pieces_law([(0.05, 0.0, 0.0, 0.0, 500.0), (0.1, 0.000625, 0.0625, 25.0, -500.0),
                       (0.05, 0.01, 0.5, -25.0, 0.0)])
    law_times = rng.uniform(-0.01, 0.21, 50)
    s, v, a, j = law.state(law_times)
    results += [s, v, a, j, *_cartesian(path, np.clip(s, 0.0, path.length), v, a, j)]

    # A horizontal circle at 1.5 m/s, sampled every ~0.5 ms, and at 4 times only (the
    # search stops for the motion's states where no sample is near a knot); its knots for a
    # tolerance read from the planned table and for one below it (the motion evaluated at
    # the check points, the search run again for them).
    centre, radius, rate = points[0] - np.array([0.1, 0.0, 0.0]), 0.1, 15.0

    def circle(t):
        angle = rate * t
        cos, sin, zero = np.cos(angle), np.sin(angle), np.zeros(t.size)
        return (centre + radius * np.column_stack((cos, sin, zero)),
                radius * rate * np.column_stack((-sin, cos, zero)),
                radius * rate ** 2 * np.column_stack((-cos, -sin, zero)),
                radius * rate ** 3 * np.column_stack((sin, -cos, zero)))

    motion = SimpleNamespace(duration=0.1, state_at=circle)
    for count in (200, 4):
        grid = np.linspace(0.0, motion.duration, count)
        samples = MotionSamples(motion, geometry, grid, motion.state_at(grid))
        if count == 200:
            results.append(samples.planned(rng.uniform(0.0, motion.duration, 30)))
        for tolerance in (1e-5, 1e-7):
            found, error = minimal_knots(motion, geometry, tolerance=tolerance,
                                         samples=samples)
            results += [found.time_from_start, found.positions, found.velocities,
                        found.accelerations, [error]]
    return results


def _digest(arrays):
    return b''.join(np.ascontiguousarray(value, dtype=float).tobytes() for value in arrays)


def test_compiled_loops_equal_their_interpreted_form():
    compiled = _evaluations()
    env = dict(os.environ, NUMBA_DISABLE_JIT='1',
               PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT),
                                                        os.environ.get('PYTHONPATH')))))
    script = ('import sys; sys.path.insert(0, {tests!r}); '
              'from test_compiled_evaluation import _digest, _evaluations; '
              'sys.stdout.buffer.write(_digest(_evaluations()))').format(
                  tests=str(ROOT / 'test'))
    interpreted = subprocess.run([sys.executable, '-c', script], env=env, cwd=ROOT,
                                 capture_output=True, check=True, timeout=300).stdout
    assert len(interpreted) == len(_digest(compiled))
    # NaN rows compare as bytes too: the same NaN comes from the same operations.
    assert interpreted == _digest(compiled)
    # The case is not vacuous: real motion, finite where assembled, NaN where not.
    assert np.isfinite(compiled[0]).all() and np.isnan(compiled[8]).any()
