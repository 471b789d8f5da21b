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

"""The start-up warm-up: after it, requests compile and load no kernel."""

import json
import subprocess
import sys
import textwrap

# Run in a fresh interpreter (this one may have called the kernels already): warm up, then
# plan requests with both joins; list each kernel whose compiled forms changed meanwhile (a
# kernel first called from Python compiles, or loads from the cache, on that call).
SCRIPT = textwrap.dedent("""
    import dataclasses, json
    import numpy as np
    from ellipath_ros.bench.latency import random_pairs
    from ellipath_ros.core import arc_scan, optimal_profile, planner
    from ellipath_ros.core.compiled import warm_up
    from ellipath_ros.core.errors import EllipathError

    def forms():
        return {f'{module.__name__}.{name}': len(value.overloads)
                for module in (arc_scan, optimal_profile)
                for name, value in vars(module).items() if hasattr(value, 'overloads')}

    first, again = warm_up(), warm_up()
    before = forms()
    plans = 0
    for join in ('g2', 'paper'):
        config = dataclasses.replace(planner.PlannerConfig(), join=join)
        start = np.array([0.0, 0.0, -0.8])
        for pick, place in random_pairs(12):
            try:
                start = planner.plan_cycle(start, pick, place, config).end_position
                plans += 1
            except EllipathError:
                pass
    after = forms()
    print(json.dumps({'first': first, 'again': again, 'plans': plans, 'kernels': len(before),
                      'changed': sorted(name for name in after if after[name] != before[name])}))
""")


def test_after_the_warm_up_requests_compile_and_load_no_kernel():
    result = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True,
                            timeout=110, check=True)
    report = json.loads(result.stdout.splitlines()[-1])
    assert report['first'] > 0.0 and report['again'] == 0.0
    assert report['plans'] >= 20 and report['kernels'] >= 20
    assert report['changed'] == []
