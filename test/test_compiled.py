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
# plan requests with both joins and both profiles, a belt pick and a request the executed
# workspace check rejects (a keep-out box across its approach leg: the first such rejection
# took 9 s in the node before the warm-up had one); list each kernel of the
# core whose compiled forms changed meanwhile (a kernel first called from Python compiles, or
# loads from the cache, on that call).
SCRIPT = textwrap.dedent("""
    import dataclasses, importlib, json, pkgutil
    import numpy as np
    import ellipath_ros.core
    from ellipath_ros.bench.latency import random_pairs
    from ellipath_ros.core import planner
    from ellipath_ros.core.compiled import warm_up
    from ellipath_ros.core.conveyor import Conveyor, plan_belt_cycle
    from ellipath_ros.core.errors import EllipathError

    # Every module of the core: the kernels of the scan, the evaluation and the profiles.
    modules = [importlib.import_module(f'ellipath_ros.core.{found.name}')
               for found in pkgutil.iter_modules(ellipath_ros.core.__path__)]

    def forms():
        return {f'{module.__name__}.{name}': len(value.overloads)
                for module in modules
                for name, value in vars(module).items() if hasattr(value, 'overloads')}

    first, again = warm_up(), warm_up()
    before = forms()
    plans = 0
    for settings in ({'join': 'g2'}, {'join': 'paper'},
                     {'join': 'paper', 'profile': 'curvature'}):
        config = dataclasses.replace(planner.PlannerConfig(), **settings)
        start = np.array([0.0, 0.0, -0.8])
        for pick, place in random_pairs(40):
            try:
                start = planner.plan_cycle(start, pick, place, config).end_position
                plans += 1
            except EllipathError:
                pass
    belt = Conveyor(velocity=np.array([0.3, 0.0, 0.0]), window_upstream=-0.3,
                    window_downstream=0.3)
    plan_belt_cycle(np.array([0.12, 0.18, -0.78]), np.array([-0.2, 0.05, -0.85]),
                    np.array([0.15, 0.2, -0.8]), planner.PlannerConfig(), belt,
                    pick_dwell=0.05, latch_time=0.0, start_time=0.02)
    box = (-0.26, -0.3, -1.0, -0.21, 0.3, -0.84)
    crossed = dataclasses.replace(planner.PlannerConfig(), workspace=dataclasses.replace(
        planner.PlannerConfig().workspace, keep_out_boxes=(box,)))
    try:
        planner.plan_cycle(np.array([0.14, 0.08, -0.8]), np.array([-0.3, 0.0, -0.9]),
                           np.array([0.18, -0.08, -0.83]), crossed)
        rejected = ''
    except EllipathError as error:
        rejected = error.kind
    after = forms()
    print(json.dumps({'rejected': rejected, 'first': first, 'again': again, 'plans': plans,
                      'kernels': len(before),
                      'changed': sorted(name for name in after if after[name] != before[name])}))
""")


def test_after_the_warm_up_requests_compile_and_load_no_kernel():
    result = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True,
                            timeout=110, check=True)
    report = json.loads(result.stdout.splitlines()[-1])
    assert report['first'] > 0.0 and report['again'] == 0.0
    assert report['plans'] >= 30 and report['kernels'] >= 60
    assert report['rejected'] == 'workspace'
    assert report['changed'] == []
