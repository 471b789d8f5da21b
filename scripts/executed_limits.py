#!/usr/bin/env python3
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
Check what JTC executes on seeded random reachable pairs, independently of the planner.

For each pair: plan a transfer leg with the default settings (or ``--join paper``), run JTC's
quintic through the published points, forward kinematics every ``--step`` seconds, TCP
derivatives by central differences (``--spread`` samples wide), joint ones from the
polynomials. Prints the worst and p99 executed ratios to the limits, how far the planner's
reported executed peaks are below this check, points per move and planning time.

    python3 scripts/executed_limits.py --pairs 1000
"""

import argparse
import sys
import time

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.planner import plan_transfer, PlannerConfig
import numpy as np

KEYS = ('peak_speed', 'peak_accel', 'peak_jerk', 'joint_peak_velocity', 'joint_peak_accel')


def dense_check(trajectory, geometry, step, spread):
    """Return the executed peaks (``KEYS`` order) found on a grid of ``step`` seconds."""
    times = trajectory.time_from_start
    t = np.arange(times[0], times[-1] + step / 2, step)
    q, qdot, qddot = quintic_interpolate(trajectory, t)
    p = forward_kinematics(q, geometry)
    k, h = spread, spread * step
    velocity = (p[2 * k:] - p[:-2 * k]) / (2 * h)
    acceleration = (p[2 * k:] - 2 * p[k:-k] + p[:-2 * k]) / h ** 2
    jerk = (p[4 * k:] - 2 * p[3 * k:-k] + 2 * p[k:-3 * k] - p[:-4 * k]) / (2 * h ** 3)
    return np.array([np.linalg.norm(velocity, axis=1).max(),
                     np.linalg.norm(acceleration, axis=1).max(),
                     np.linalg.norm(jerk, axis=1).max(), np.abs(qdot).max(),
                     np.abs(qddot).max()])


def _report(args, refused, ratios, under, points, plan_ms, durations):
    """Print the worst and p99 executed ratios so far (and how they were found)."""
    out = sys.stdout
    out.write(f'{len(ratios)} pairs (join {args.join}, seed {args.seed}, {refused} '
              f'unreachable skipped), check every {args.step * 1e6:g} us\n')
    out.write('executed / limit          worst     p99  median\n')
    for index, key in enumerate(KEYS):
        column = ratios[:, index]
        out.write(f'  {key:22s} {column.max():7.4f} {np.percentile(column, 99):7.4f} '
                  f'{np.median(column):7.4f}\n')
    out.write('check above reported peak (worst, per quantity): '
              + ', '.join(f'{key} {value:+.3%}' for key, value in zip(KEYS, under.max(axis=0)))
              + '\n')
    out.write(f'points per move: median {np.median(points):.0f}, mean {np.mean(points):.1f}, '
              f'max {np.max(points)}; duration mean {np.mean(durations) * 1e3:.1f} ms; '
              f'plan median {np.median(plan_ms):.0f} ms, p90 '
              f'{np.percentile(plan_ms, 90):.0f} ms\n')
    out.flush()


def main(argv=None):
    """Run the check (arguments as on the command line) and print the summaries."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--pairs', type=int, default=1000)
    parser.add_argument('--seed', type=int, default=14)
    parser.add_argument('--join', default='g2')
    parser.add_argument('--step', type=float, default=2e-6)
    parser.add_argument('--spread', type=int, default=5)
    parser.add_argument('--report-every', type=int, default=100)
    args = parser.parse_args(argv)
    config = PlannerConfig.from_flat({'join': args.join})
    limits, joints = config.limits, config.joint_limits
    scale = np.array([limits.max_speed, limits.max_accel, limits.max_jerk,
                      joints.max_velocity, joints.max_acceleration])
    rng = np.random.default_rng(args.seed)
    ratios, under, points, plan_ms, durations = [], [], [], [], []
    refused = 0
    while len(ratios) < args.pairs:
        pick = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3),
                         rng.uniform(-0.95, -0.7)])
        place = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3),
                          rng.uniform(-0.95, -0.7)])
        started = time.perf_counter()
        try:
            leg = plan_transfer(pick, place, config)
        except EllipathError:
            refused += 1
            continue
        plan_ms.append(1e3 * (time.perf_counter() - started))
        found = dense_check(leg.joint_trajectory, config.geometry, args.step, args.spread)
        reported = np.array([leg.executed[key] for key in KEYS])
        ratios.append(found / scale)
        under.append(found / reported - 1.0)
        points.append(leg.joint_trajectory.time_from_start.size)
        durations.append(leg.motion.duration)
        if len(ratios) % args.report_every == 0 or len(ratios) == args.pairs:
            _report(args, refused, np.array(ratios), np.array(under), points, plan_ms,
                    durations)
    return 0


if __name__ == '__main__':
    sys.exit(main())
