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
The node's memory over long runs: the soak's verdict, the node's malloc policy, a short soak.

The long runs (30 minutes of the node, 100,000 plans) are scripts, see docs/reliability.md;
the short soak here (15 s) only checks that the script's report is complete and honest.
"""

import json
import os
import signal
import subprocess
import sys

from ellipath_ros.malloc_policy import MALLOC_ARENA_MAX
from ellipath_ros.malloc_policy import MALLOC_MMAP_THRESHOLD
from ellipath_ros.node import NUMPY_CACHE_BYTES
from ellipath_ros.node import NUMPY_CACHE_DEPTH
import pytest

ROS_DOMAIN_OFFSET = 7  # see conftest.py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'scripts'))
import soak  # noqa: E402, I100 (scripts/ is not a package)

BUFFERS = {'statuses_buffer': ('statuses', 100), 'trajectories_buffer': ('trajectories', 10)}


def samples(rss_of_time, statuses_per_s=4.0, trajectories_per_s=2.0, seconds=600, every=10):
    """Return memory samples of a run whose VmRSS is ``rss_of_time(t)`` [KiB]."""
    result = []
    for t in range(every, seconds + 1, every):
        rss = rss_of_time(t)
        result.append({'t': float(t), 'offered': t, 'statuses': int(statuses_per_s * t),
                       'trajectories': int(trajectories_per_s * t), 'rss': rss,
                       'anon': rss - 60_000, 'file': 58_000, 'shmem': 2_000})
    return result


def test_the_warm_up_ends_when_the_last_buffer_is_full():
    # 100 statuses at 4/s: t = 25 s, first sampled at 30 s; 10 trajectories at 2/s: t = 5 s.
    full, end = soak.warm_up(samples(lambda t: 90_000), buffers=BUFFERS)
    assert full == {'statuses_buffer': 30.0, 'trajectories_buffer': 10.0}
    assert end == 30.0
    full, end = soak.warm_up(samples(lambda t: 90_000, statuses_per_s=0.1), buffers=BUFFERS)
    assert full['statuses_buffer'] is None and end is None


def test_growth_during_the_warm_up_is_not_counted_and_growth_after_it_is():
    # 5 MiB during the first 30 s (until the statuses buffer is full), then flat.
    warm = soak.memory_verdict(samples(lambda t: 90_000 + 5_000 * min(t, 30) // 30),
                               buffers=BUFFERS)
    assert warm['warm_up_end_s'] == 30.0 and warm['verdict'] == 'flat'
    assert warm['growth']['rss']['last_less_first_kib'] == 0
    # 60 KiB per minute throughout, as the node of the last round: 570 KiB after 30 s.
    growing = soak.memory_verdict(samples(lambda t: 90_000 + t), buffers=BUFFERS)
    assert growing['verdict'] == 'growing'
    assert growing['growth']['rss']['fitted_rise_kib'] == pytest.approx(570.0)
    assert growing['growth']['anon']['per_10_min_kib'] == pytest.approx(600.0)
    # A buffer that never fills: no verdict, whatever the memory did.
    never = soak.memory_verdict(samples(lambda t: 90_000, statuses_per_s=0.1),
                                buffers=BUFFERS)
    assert never['verdict'] == 'no warm-up' and 'growth' not in never


def test_the_warm_up_waits_for_the_planners_own_fill():
    # At 2 trajectories/s the node's default buffers (1,000 statuses at 4/s: 250 s; 10
    # trajectories: 5 s) are full long before the 1,000th plan (500 s): a rise until then,
    # as the planner fills its caches, is not growth; one after it is.
    filling = soak.memory_verdict(samples(lambda t: 90_000 + 2 * min(t, 500), seconds=1200))
    assert filling['buffers']['planner_fill']['full_at_s'] == 500.0
    assert filling['warm_up_end_s'] == 500.0 and filling['verdict'] == 'flat'
    late = soak.memory_verdict(samples(lambda t: 90_000 + 2 * min(t, 800), seconds=1200))
    assert late['verdict'] == 'growing'


def test_the_verdict_fits_a_line_through_noisy_samples():
    # +-400 KiB of alternating noise (large arrays mapped at some samples), no trend.
    noisy = soak.memory_verdict(samples(lambda t: 90_000 + (400 if t % 20 else -400)),
                                buffers=BUFFERS)
    assert noisy['verdict'] == 'flat'
    assert abs(noisy['growth']['rss']['fitted_rise_kib']) < 100.0


# glibc through ctypes, the start of each probe below (each runs in a process of its own): the
# memory in use (libc.mallinfo2().uordblks) and the number of arenas (heaps of malloc_info).
GLIBC_PROBE = r"""
import ctypes, os, re, tempfile
libc = ctypes.CDLL(None)
libc.fopen.restype = ctypes.c_void_p
libc.fopen.argtypes = (ctypes.c_char_p, ctypes.c_char_p)
libc.malloc_info.argtypes = (ctypes.c_int, ctypes.c_void_p)
libc.fclose.argtypes = (ctypes.c_void_p,)
class Mallinfo(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        'arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks',
        'fordblks', 'keepcost')]
libc.mallinfo2.restype = Mallinfo
def arenas():
    path = os.path.join(tempfile.mkdtemp(), 'info.xml')
    stream = libc.fopen(path.encode(), b'w')
    libc.malloc_info(0, stream)
    libc.fclose(stream)
    return len(re.findall('<heap nr=', open(path).read()))
"""


# Run in a process of its own: threads that each allocate, then the number of glibc arenas
# (heaps of malloc_info), and whether a block above the threshold is mapped again after a
# larger one was freed (glibc's default raises its mmap threshold to the largest block freed).
ALLOCATOR_PROBE = GLIBC_PROBE + r"""
import threading
import ellipath_ros.node  # its imports (rclpy) make arenas before the policy is set
from ellipath_ros.malloc_policy import MALLOC_MMAP_THRESHOLD, set_malloc_policy
libc.malloc.restype = ctypes.c_void_p
libc.free.argtypes = (ctypes.c_void_p,)
# The imports have started threads of their own (and arenas) before main() can set it.
arenas_before = arenas()
policy = set_malloc_policy(os.environ)
barrier = threading.Barrier(6)
def allocate():
    block = libc.malloc(4096)
    barrier.wait()  # all alive at once, so that none reuses the arena of one that ended
    libc.free(block)
threads = [threading.Thread(target=allocate) for _ in range(6)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
new_arenas = arenas() - arenas_before
large = libc.malloc(4 * MALLOC_MMAP_THRESHOLD)
libc.free(large)
mapped_before = libc.mallinfo2().hblkhd
block = libc.malloc(2 * MALLOC_MMAP_THRESHOLD)
mapped = libc.mallinfo2().hblkhd > mapped_before
libc.free(block)
print(policy, arenas_before, new_arenas, mapped)
"""


def allocator_probe(**environment):
    """
    Run ALLOCATOR_PROBE; return (policy set, arenas, new arenas, a large block mapped).

    arenas: glibc's arenas before the policy was set; new arenas: those made after it by six
    threads that each allocate; a large block mapped: one above MALLOC_MMAP_THRESHOLD, after
    a larger one was freed.
    """
    env = {name: value for name, value in os.environ.items()
           if name not in ('MALLOC_ARENA_MAX', 'MALLOC_MMAP_THRESHOLD_', 'GLIBC_TUNABLES')}
    env.update(environment)
    output = subprocess.run([sys.executable, '-c', ALLOCATOR_PROBE], env=env, check=True,
                            capture_output=True, text=True, timeout=60).stdout.split()
    return output[0] == 'True', int(output[1]), int(output[2]), output[3] == 'True'


def test_the_node_limits_glibcs_arenas_and_fixes_its_mmap_threshold():
    if not os.confstr('CS_GNU_LIBC_VERSION'):
        pytest.skip('glibc only: other allocators have no arenas to limit')
    policy, arenas, new_arenas, mapped = allocator_probe()
    assert policy
    # No new arena once there are MALLOC_ARENA_MAX (those made during the imports stay).
    assert new_arenas <= max(0, MALLOC_ARENA_MAX - arenas), (arenas, new_arenas)
    assert mapped, f'a block of {2 * MALLOC_MMAP_THRESHOLD} B came from an arena'
    # The caller's own policy prevails; glibc's default then shows what the policy changes.
    policy, arenas, new_arenas, mapped = allocator_probe(MALLOC_ARENA_MAX='16')
    assert not policy
    assert new_arenas >= 6 - 1, (arenas, new_arenas)
    assert not mapped, 'glibc raised its threshold after the larger block was freed'


# Run in a process of its own: glibc's memory in use [bytes] grown by arrays of every size that
# NumPy's small-block cache holds, made and freed NUMPY_CACHE_DEPTH at a time, with or without
# fill_numpy_cache() first.
NUMPY_CACHE_PROBE = GLIBC_PROBE + r"""
import sys
import numpy as np
from ellipath_ros.node import fill_numpy_cache, NUMPY_CACHE_BYTES, NUMPY_CACHE_DEPTH
if sys.argv[1] == 'fill':
    fill_numpy_cache()
before = libc.mallinfo2().uordblks
for size in range(1, NUMPY_CACHE_BYTES):
    held = [np.empty(size, dtype=np.uint8) for _ in range(NUMPY_CACHE_DEPTH)]
    del held
print(libc.mallinfo2().uordblks - before)
"""


def numpy_cache_growth(fill):
    """Run NUMPY_CACHE_PROBE; return the growth of the memory in use [bytes]."""
    output = subprocess.run([sys.executable, '-c', NUMPY_CACHE_PROBE, 'fill' if fill else 'no'],
                            check=True, capture_output=True, text=True, timeout=60).stdout
    return int(output)


def test_the_node_fills_numpys_small_block_cache_before_planning():
    if not os.confstr('CS_GNU_LIBC_VERSION'):
        pytest.skip('glibc only: mallinfo2 gives the memory in use')
    # Without the fill, each new size stays cached after its arrays are freed: the memory in
    # use grows by what the cache holds (7 blocks of each size below 1 KiB: about 3.6 MB).
    cache_bytes = NUMPY_CACHE_DEPTH * NUMPY_CACHE_BYTES * (NUMPY_CACHE_BYTES - 1) // 2
    assert numpy_cache_growth(fill=False) > cache_bytes // 2
    # Filled first, the same arrays reuse the cached blocks: no growth beyond noise.
    assert numpy_cache_growth(fill=True) < cache_bytes // 50


# Run in a process of its own: the ellipath_node command's start (node_entry.main) up to
# node.main, which prints glibc's arenas instead of running the node.
ENTRY_PROBE = GLIBC_PROBE + r"""
import builtins, sys
import ellipath_ros.node_entry as entry
def node_main(args, early_signals=()):
    print(arenas(), 'rclpy' in sys.modules)
real_import = builtins.__import__
def importing(name, *args, **kwargs):
    module = real_import(name, *args, **kwargs)
    if name == 'ellipath_ros' and 'node' in (args[2] if len(args) > 2 and args[2] else ()):
        module.node.main = node_main
    return module
builtins.__import__ = importing
entry.main([])
"""


def test_the_node_command_sets_the_policy_before_rclpys_threads_allocate():
    if not os.confstr('CS_GNU_LIBC_VERSION'):
        pytest.skip('glibc only: other allocators have no arenas to limit')
    env = {name: value for name, value in os.environ.items()
           if name not in ('MALLOC_ARENA_MAX', 'MALLOC_MMAP_THRESHOLD_', 'GLIBC_TUNABLES')}
    output = subprocess.run([sys.executable, '-c', ENTRY_PROBE], env=env, check=True,
                            capture_output=True, text=True, timeout=60).stdout.split()
    # Importing the node (rclpy) made no arena beyond MALLOC_ARENA_MAX: the planning thread
    # allocates in the arena that malloc_trim gives back in full.
    assert output == [str(MALLOC_ARENA_MAX), 'True']


@pytest.fixture(scope='module')
def short_soak(ros_domain_id, monkeypatch_module):
    """Run the node for 15 s at 2 pairs/s, sampled every 2 s."""
    monkeypatch_module.setenv('ROS_DOMAIN_ID', str(ros_domain_id))
    return soak.soak_node(minutes=0.25, rate=2.0, seed=5, every=2.0)


def test_a_short_soak_accounts_for_every_pair_and_claims_no_verdict(short_soak):
    assert short_soak['ok'], short_soak['node_log']
    assert short_soak['node']['pairs_released'] == short_soak['sender']['pairs_sent']
    memory = short_soak['memory']
    per_minute = memory['per_minute_kib']
    assert set(per_minute) == set(soak.MEMORY_KEYS)
    assert all(value > 0 for value in per_minute['rss'])
    # About 30 statuses: the /diagnostics history is far from full, so nothing is claimed.
    assert memory['buffers']['diagnostics_history']['full_at_s'] is None
    assert memory['verdict'] == 'no warm-up'


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_one_signal_stops_the_plans_soak_and_prints_the_summary(signum):
    # Started with SIGINT ignored, as by `nohup ... &` from a script (one SIGINT did not stop
    # a 100,000-plan soak started so): the soak installs its own handlers.
    process = subprocess.Popen(
        [sys.executable, os.path.join(ROOT, 'scripts', 'soak.py'), 'plans', '--plans',
         '100000', '--every', '1'],
        env=dict(os.environ, PYTHONPATH=ROOT), stdout=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        first = json.loads(process.stdout.readline())  # planning has begun
        process.send_signal(signum)
        output, _ = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 0
    summary = json.loads(output.splitlines()[-1])['summary']
    assert summary['stopped'] is True
    assert first['plans'] <= summary['plans_done'] < 100_000
