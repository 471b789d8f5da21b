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
CPU time per leg of the time-optimal profile: this checkout against a git revision.

Both versions run in one process, interleaved leg by leg (which goes first alternates), so
that a loaded machine loads both alike. The revision's package is extracted (``git
archive``) into ``--workdir`` and imported under another name (``ellipath_ref``); its
kernels are compiled into numba's cache there on the first run (about a minute of CPU).
The legs are those of ``scripts/scan_study.py`` (seeded random pairs, chained, default
settings); each is planned by ``_optimal_motion`` (the profile's construction, without the
final limit check) ``--rounds`` times per version after a warm-up round, and timed with
``time.process_time``. Reported: the percentiles of each version's per-leg CPU time (the
median of its rounds), of the per-leg ratio, and how many legs' plans differ in any bit.

    PYTHONPATH=. python3 scripts/cpu_compare.py [--rev REV] [--pairs N] [--rounds R]
"""

import argparse
import importlib
import logging
import os
import subprocess
import sys
import tarfile
import time

from ellipath_ros.core import optimal_profile
from ellipath_ros.core.compiled import warm_up
import numpy as np
from scan_study import legs

REFERENCE = 'ellipath_ref'
LOG = logging.getLogger('cpu_compare')


def reference_package(rev, workdir):
    """Return (the revision's ``core`` package, imported as ``ellipath_ref``, its commit)."""
    commit = subprocess.run(['git', 'rev-parse', rev], check=True, capture_output=True,
                            text=True).stdout.strip()
    root = os.path.join(workdir, commit)
    package = os.path.join(root, REFERENCE)
    if not os.path.isdir(package):
        os.makedirs(root, exist_ok=True)
        archive = os.path.join(root, 'source.tar')
        subprocess.run(['git', 'archive', '-o', archive, commit, 'ellipath_ros'], check=True)
        with tarfile.open(archive) as source:
            source.extractall(root, filter='data')
        os.rename(os.path.join(root, 'ellipath_ros'), package)
        for folder, _, names in os.walk(package):
            for name in (name for name in names if name.endswith('.py')):
                with open(os.path.join(folder, name), encoding='utf-8') as stream:
                    text = stream.read()
                with open(os.path.join(folder, name), 'w', encoding='utf-8') as stream:
                    stream.write(text.replace('ellipath_ros', REFERENCE))
    sys.path.insert(0, root)
    importlib.import_module(f'{REFERENCE}.core.optimal_profile')
    return importlib.import_module(f'{REFERENCE}.core'), commit


def reference_path(path, reference):
    """
    Return ``path`` as the reference's PickPlacePath (its motions check the class).

    The same fields, so the same curve objects: what they cache (the curvature grids) serves
    both versions alike.
    """
    copy = object.__new__(reference.geometry.PickPlacePath)
    copy.__dict__.update(vars(path))
    return copy


def bits(motion):
    """Return the exact bytes of a timed motion's pieces, duration and segments."""
    law = motion.law
    return b''.join(np.asarray(array).tobytes() for array in (
        law.times, law.s0, law.v0, law.a0, law.jerk, motion.segment_durations,
        motion.duration))


def measure(reference, count, rounds):
    """Return (CPU s per leg and round of this checkout, of the reference, plans differing)."""
    items = [(paths, cap, config.limits) for paths, cap, config in (
        ((path, reference_path(path, reference)), cap, config)
        for _, path, cap, config in legs(count))]
    versions = (optimal_profile._optimal_motion, reference.optimal_profile._optimal_motion)
    differing = sum(bits(versions[0](paths[0], limits, cap))
                    != bits(versions[1](paths[1], limits, cap))
                    for paths, cap, limits in items)
    cpu = np.empty((2, len(items), rounds))
    for round_index in range(rounds):
        for index, (paths, cap, limits) in enumerate(items):
            order = (0, 1) if (index + round_index) % 2 == 0 else (1, 0)
            for version in order:
                started = time.process_time()
                versions[version](paths[version], limits, cap)
                cpu[version, index, round_index] = time.process_time() - started
    return cpu[0], cpu[1], differing


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--rev', default='HEAD', help='the revision to compare with')
    parser.add_argument('--pairs', type=int, default=200)
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--workdir', default='/tmp/ellipath_cpu_compare',
                        help='where the revision is extracted (and its kernels cached)')
    options = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format='%(message)s')
    reference, commit = reference_package(options.rev, options.workdir)
    warm_up()
    mine, theirs, differing = measure(reference, options.pairs, options.rounds)
    mine, theirs = 1e3 * np.median(mine, axis=1), 1e3 * np.median(theirs, axis=1)
    LOG.info('%d legs, %d rounds each, interleaved; plans differing in any bit: %d',
             mine.size, options.rounds, differing)
    for name, values in (('this checkout', mine), (commit[:7], theirs),
                         ('ratio (this / rev)', mine / theirs)):
        p50, p99 = np.percentile(values, [50.0, 99.0])
        LOG.info('  %-20s p50 %.3f, p99 %.3f, mean %.3f%s', name, p50, p99, values.mean(),
                 '' if name.startswith('ratio') else ' ms per leg')
    LOG.info('  total: %.1f ms vs %.1f ms (%+.1f %%)', mine.sum(), theirs.sum(),
             100.0 * (mine.sum() / theirs.sum() - 1.0))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
