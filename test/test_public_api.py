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
"""The public API: every name in ``__all__`` imports, and the core stays ROS- and plot-free."""

import importlib
import os
import pathlib
import subprocess
import sys

import pytest


@pytest.mark.parametrize('package', ['ellipath_ros.core', 'ellipath_ros.paper'])
def test_every_public_name_imports(package):
    module = importlib.import_module(package)
    assert module.__all__, package
    assert len(set(module.__all__)) == len(module.__all__)
    for name in module.__all__:
        assert getattr(module, name) is not None, name
    namespace = {}
    exec(f'from {package} import *', namespace)  # noqa: S102 (the star import is the test)
    assert set(module.__all__) <= set(namespace)


def test_core_entry_points_plan_a_cycle():
    from ellipath_ros.core import plan_cycle, PlannerConfig, validate_jtc
    cycle = plan_cycle((0.0, 0.0, -0.8), (0.0, 0.0, -0.8), (0.3, 0.0, -0.75), PlannerConfig())
    assert cycle.legs and cycle.legs[-1].motion.duration > 0.0
    validate_jtc(cycle.joint_trajectory)


def test_core_and_paper_import_neither_ros_nor_matplotlib():
    code = ('import sys, ellipath_ros.core, ellipath_ros.paper; '
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('rclpy', 'matplotlib') or m.endswith('_msgs')))")
    # This worktree's code, not an installed copy.
    root = str(pathlib.Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=root)
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=root, env=env).stdout
    assert out.strip() == '[]'
