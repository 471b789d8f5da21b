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
"""The figures: every PNG is written and valid (needs the optional plot extra)."""

import os
import struct
import sys

from ellipath_ros.core.errors import DegenerateGeometryError
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.paper.plotting import radius_of_curvature_derivatives, write_figures
import numpy as np
import pytest

# matplotlib is the optional plot extra (ellipath_ros.paper.plotting imports it lazily).
pytest.importorskip('matplotlib')

# The paper's example: l = 0.15 m, h = 0.025 m with 25 mm clearances.
PAPER_PICK = (0.0, 0.0, -0.8)
PAPER_PLACE = (0.3, 0.0, -0.75)
EXPECTED = {'fig2_length_vs_phi.png', 'fig3_radius_of_curvature.png',
            'fig5_curvature_profile.png', 'fig6_path_nodes.png', 'fig7_joint_angles.png',
            'fig8_path_comparison.png', 'profiles_comparison.png', 'workspace.png'}
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


def png_size(path):
    """Return (width, height) from the IHDR chunk, checking the PNG signature and the end."""
    with open(path, 'rb') as stream:
        data = stream.read()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b'IHDR'
    assert data[-8:-4] == b'IEND'
    return struct.unpack('>II', data[16:24])


def test_paper_example_writes_every_figure(tmp_path):
    out_dir = tmp_path / 'figures'
    written = write_figures(PAPER_PICK, PAPER_PLACE, out_dir)
    assert {os.path.basename(path) for path in written} == EXPECTED
    assert len(written) == len(EXPECTED)
    for path in written:
        assert os.path.dirname(path) == str(out_dir)
        assert os.path.getsize(path) > 10_000
        width, height = png_size(path)
        assert width >= 400 and height >= 300


def test_other_arc_policy_and_descending_move(tmp_path):
    config = PlannerConfig.from_flat({'arc_policy': 'apex_clearance', 'apex_clearance': 0.03})
    written = write_figures((0.1, 0.05, -0.75), (-0.15, -0.05, -0.8), tmp_path, config)
    assert {os.path.basename(path) for path in written} == EXPECTED


def test_the_workspace_figure_draws_the_configured_keep_out_boxes(tmp_path):
    # The same move, without and with a keep-out box away from its path: only the box differs.
    pick, place = (0.1, 0.05, -0.75), (-0.15, -0.05, -0.8)
    plain = write_figures(pick, place, tmp_path / 'plain')[-1]
    config = PlannerConfig.from_flat({'keep_out_boxes': [0.2, 0.2, -1.0, 0.3, 0.3, -0.7]})
    boxed = write_figures(pick, place, tmp_path / 'boxed', config)[-1]
    assert os.path.basename(plain) == os.path.basename(boxed) == 'workspace.png'
    with open(plain, 'rb') as first, open(boxed, 'rb') as second:
        assert first.read() != second.read()


def test_a_pure_vertical_move_has_no_figures(tmp_path):
    with pytest.raises(DegenerateGeometryError):
        write_figures((0.0, 0.0, -0.8), (0.0, 0.0, -0.7), tmp_path)


def test_missing_matplotlib_names_the_plot_extra(tmp_path, monkeypatch):
    for name in ('matplotlib', 'matplotlib.figure', 'matplotlib.backends.backend_agg'):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ImportError, match=r'pip install \.\[plot\]'):
        write_figures(PAPER_PICK, PAPER_PLACE, tmp_path)
    assert not os.listdir(tmp_path)


def test_radius_of_curvature_derivatives_match_finite_differences():
    theta = np.linspace(-3.0, 3.0, 61)
    step = 1e-5
    rho, rho_1, rho_2 = radius_of_curvature_derivatives(0.3, 0.05, theta)
    plus = radius_of_curvature_derivatives(0.3, 0.05, theta + step)[0]
    minus = radius_of_curvature_derivatives(0.3, 0.05, theta - step)[0]
    np.testing.assert_allclose(rho_1, (plus - minus) / (2 * step), atol=1e-7)
    np.testing.assert_allclose(rho_2, (plus - 2 * rho + minus) / step ** 2, atol=1e-3)
    # Extremes of rho: b**2 / a at theta = 0 and a**2 / b at theta = pi / 2 (eq. 34).
    ends = radius_of_curvature_derivatives(0.3, 0.05, np.array([0.0, np.pi / 2]))[0]
    np.testing.assert_allclose(ends, [0.05 ** 2 / 0.3, 0.3 ** 2 / 0.05], rtol=1e-12)
