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
The paper's figures (2, 3, 5, 6, 7, 8) and a profile comparison, as PNG files.

Optional: needs matplotlib (``pip install .[plot]``), imported lazily inside
the functions and drawn with the Agg canvas only (no pyplot, no global backend
change). Neither the planning core nor the node imports this module.

Coordinates of the path figures are the paper frame (``core/geometry.py``): horizontal
along u from pick towards place, vertical z, origin at the midpoint of T1 and
T2. Angles are shown in degrees (axis labels say so); everything else is SI.
"""

from dataclasses import replace
import math
import os

from ellipath_ros.core.curvature_profile import curvature_nodes
from ellipath_ros.core.errors import DegenerateGeometryError
from ellipath_ros.core.geometry import (
    arc_for_policy, ArcPolicy, conjugate_k_from_phi, EllipticArc, paper_phi,
    radius_of_curvature_derivatives)
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.planner import plan_transfer, PlannerConfig
from ellipath_ros.paper.comparison import figure8_paths
from ellipath_ros.paper.equations import paper_axes
import numpy as np

# Resolution of the written PNGs [dots per inch]: readable, and small enough (about 30-100 kB)
# to keep the figures of docs/figures in the repository.
_DPI = 90
# Figure 3 of the paper: radius of curvature of the ellipse a = 0.3 m, b = 0.05 m.
_PAPER_FIG3_AXES = (0.3, 0.05)
# Figure 2 of the paper: phi from the critical angle up to this [deg], in 1 deg steps.
_PAPER_FIG2_LAST_DEG = 60
# Time samples of the curves over one motion: on motions up to 2.5 s still six per 10 ms
# jerk phase (50 m/s**2 reached at 5000 m/s**3), so the acceleration ramps are drawn, not cut.
_TIME_SAMPLES = 1500

_PLOT_EXTRA_HINT = 'install the plot extra: pip install .[plot]'
_JOINT_STYLES = (('tab:red', '-'), ('tab:green', '-.'), ('tab:blue', '--'))


def _matplotlib():
    """Return matplotlib's Figure and Agg canvas classes; raise ImportError if it is missing."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as error:
        raise ImportError(f'plotting needs matplotlib: {_PLOT_EXTRA_HINT}') from error
    return Figure, FigureCanvasAgg


def _new_figure(rows=1, columns=1, size=(7.0, 4.5), **subplot_kw):
    """Return (figure, axes (rows, columns)) drawn on the Agg canvas."""
    Figure, FigureCanvasAgg = _matplotlib()
    figure = Figure(figsize=size, layout='constrained')
    FigureCanvasAgg(figure)
    return figure, figure.subplots(rows, columns, squeeze=False, **subplot_kw)


def _save(figure, out_dir, name):
    """Write ``figure`` as ``out_dir/name`` and return the path."""
    path = os.path.join(out_dir, name)
    figure.savefig(path, dpi=_DPI)
    return path


def _figure2(arc, policy, out_dir):
    """Draw the arc length against phi (paper's Figure 2) and against k, for this l, h."""
    half_width, h = arc.l, arc.h
    figure, axes = _new_figure(1, 2, size=(10.0, 4.2))
    left, right = axes[0]
    try:
        first_deg = round(abs(math.degrees(paper_phi(half_width, h))))
    except DegenerateGeometryError:
        first_deg = 90
    critical_deg = math.degrees(math.atan2(abs(h), half_width))
    if h == 0.0 or first_deg >= 90:
        reason = ('h = 0: the tangent ellipses have phi = 0 or 90 deg only'
                  if h == 0.0 else 'no whole degree between the critical angle and 90 deg')
        left.text(0.5, 0.5, reason, ha='center', va='center', transform=left.transAxes)
    else:
        phis_deg = np.arange(first_deg, max(_PAPER_FIG2_LAST_DEG, first_deg) + 1)
        phis = np.radians(phis_deg)
        exact = [EllipticArc(half_width, abs(h), conjugate_k_from_phi(
            half_width, abs(h), phi)).length for phi in phis]
        axes_ab = np.array([paper_axes(half_width, abs(h), phi) for phi in phis])
        approx = 0.5 * (0.5 * math.pi * axes_ab.sum(axis=1)
                        + math.pi / math.sqrt(2.0) * np.hypot(axes_ab[:, 0], axes_ab[:, 1]))
        left.plot(phis_deg, approx, 'o-', ms=3, label='approximate, eq. (27)')
        left.plot(phis_deg, exact, 's-', ms=3, label='exact')
        left.plot(phis_deg[0], approx[0], 'r*', ms=14,
                  label=f'phi* = {first_deg} deg (critical {critical_deg:.3f} deg)')
        left.legend()
    mirrored = ' (mirrored, h < 0)' if h < 0.0 else ''
    left.set(xlabel='major-axis angle |phi| [deg]', ylabel='arc length L [m]',
             title=f'Fig. 2: L(phi), l = {half_width:g} m, h = {h:g} m{mirrored}')
    left.grid(True, alpha=0.3)
    scale = math.hypot(half_width, h)
    ks = np.geomspace(0.02 * scale, 2.0 * scale, 120)
    right.plot(ks, [EllipticArc(half_width, h, k).length for k in ks], label='exact length')
    right.axhline(2.0 * scale, color='grey', ls='--', label='chord 2 |T1 T2| (k -> 0)')
    marked = [('paper rule', 'r*', ArcPolicy())]
    if policy.kind != 'paper':
        marked.append((policy.kind, 'kD', policy))
    for name, style, chosen in marked:
        try:
            candidate = arc_for_policy(half_width, h, chosen)
        except DegenerateGeometryError:
            continue
        right.plot(candidate.k, candidate.length, style, ms=10,
                   label=f'{name}: k = {candidate.k:.4f} m, L = {candidate.length:.5f} m')
    right.set(xscale='log', xlabel='vertical conjugate semi-diameter k [m]',
              ylabel='arc length L [m]', title='the same family by k (length grows with k)')
    right.grid(True, which='both', alpha=0.3)
    right.legend(fontsize='small')
    return _save(figure, out_dir, 'fig2_length_vs_phi.png')


def _figure3(arc, out_dir):
    """Draw rho and its derivatives for the paper's ellipse and for this arc (Figure 3)."""
    figure, axes = _new_figure(3, 2, size=(10.0, 7.0), sharex='col')
    paper_a, paper_b = _PAPER_FIG3_AXES
    cases = ((paper_a, paper_b, np.linspace(0.0, 2.0 * math.pi, 721),
              f'paper: a = {paper_a:g} m, b = {paper_b:g} m'),
             (arc.a, arc.b, np.linspace(arc.theta_T2, arc.theta_T1, 361),
              f'this arc: a = {arc.a:.5f} m, b = {arc.b:.5f} m'))
    labels = ('rho [m]', "rho' [m/rad]", "rho'' [m/rad^2]")
    for column, (a, b, theta, title) in enumerate(cases):
        values = radius_of_curvature_derivatives(a, b, theta)
        for row, (value, label) in enumerate(zip(values, labels)):
            axis = axes[row, column]
            axis.plot(np.degrees(theta), value, color=('tab:red', 'tab:green', 'tab:blue')[row])
            axis.set_ylabel(label)
            axis.grid(True, alpha=0.3)
        axes[0, column].set_title(f'Fig. 3: {title}')
        axes[-1, column].set_xlabel('ellipse parameter theta [deg]')
    return _save(figure, out_dir, 'fig3_radius_of_curvature.png')


def _path_state_at(motion, s_query):
    """Return the times [s] at which the motion reaches path lengths ``s_query`` [m]."""
    t = np.linspace(0.0, motion.duration, 4 * _TIME_SAMPLES)
    s = np.maximum.accumulate(motion.path_state(t)[0])
    return np.interp(s_query, s, t)


def _figure5(plan, r, out_dir):
    """Draw, per node of the curvature profile, rho, s, and its three time derivatives."""
    arc = plan.path.arc
    theta = curvature_nodes(arc, r)
    s_arc = arc.s_from_t(arc.t_from_theta(theta))
    times = _path_state_at(plan.motion, plan.path.segment_ends[1] + s_arc)
    _, velocity, acceleration, jerk = plan.motion.path_state(times)
    index = np.arange(1, theta.size + 1)
    rows = ((arc.radius_of_curvature(theta), '(a) Curv. rho [m]'),
            (s_arc, '(b) Disp. s [m]'),
            (velocity, '(c) Vel. [m/s]'),
            (acceleration, '(d) Acc. [m/s^2]'),
            (jerk, '(e) Jerk [m/s^3]'))
    figure, axes = _new_figure(5, 1, size=(7.0, 9.0), sharex='col')
    for axis, (value, label) in zip(axes[:, 0], rows):
        axis.plot(index, value, '.-', ms=4)
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[0, 0].set_title(f'Fig. 5: curvature profile, r = {r:g} rad/m, {theta.size} nodes\n'
                         '(speed, acceleration, jerk along the path at the nodes)')
    axes[-1, 0].set_xlabel('node i')
    return _save(figure, out_dir, 'fig5_curvature_profile.png')


def _figure6(plan, r, out_dir):
    """Draw the path in the paper frame with the nodes, start/end markers and the apex."""
    path, arc = plan.path, plan.path.arc
    theta = curvature_nodes(arc, r)
    nodes = arc.point(arc.t_from_theta(theta))
    curve = arc.point(np.linspace(math.pi, 0.0, 400))
    c1, c2 = path.segment_lengths[0], path.segment_lengths[2]
    figure, axes = _new_figure(size=(8.0, 4.0))
    axis = axes[0, 0]
    axis.plot([-arc.l, -arc.l], [-arc.h - c1, -arc.h], color='grey', ls='--',
              label='vertical segments')
    axis.plot([arc.l, arc.l], [arc.h, arc.h - c2], color='grey', ls='--')
    axis.plot(curve[:, 0], curve[:, 1], 'r-', label='elliptic arc')
    axis.plot(nodes[:, 0], nodes[:, 1], 'b.', ms=5, label=f'{theta.size} nodes (r = {r:g})')
    axis.plot(*curve[0], 'o', mfc='none', mec='red', ms=11, mew=2, label='start T1')
    axis.plot(*curve[-1], 'o', mfc='none', mec='green', ms=11, mew=2, label='end T2')
    apex = arc.apex
    axis.plot(*apex, 'k^', ms=9,
              label=f'apex ({apex[0]:.5f}, {apex[1]:.5f}) m, H = {arc.apex_height:.5f} m')
    axis.set_aspect('equal', adjustable='datalim')
    axis.set(xlabel='u (horizontal, pick -> place) [m]', ylabel='z [m]',
             title=f'Fig. 6: path and nodes, phi = {math.degrees(arc.phi):.3f} deg, '
                   f'a = {arc.a:.5f} m, b = {arc.b:.5f} m')
    axis.grid(True, alpha=0.3)
    figure.legend(fontsize='small', loc='outside lower center', ncols=2)
    return _save(figure, out_dir, 'fig6_path_nodes.png')


def _segment_times(plan):
    """Return the times [s] at which the motion passes T1 and T2."""
    return _path_state_at(plan.motion, plan.path.segment_ends[1:3])


def _figure7(plan, config, out_dir):
    """Draw the joint angles of the three actuators over time (IK of the motion)."""
    motion = plan.motion
    t = np.linspace(0.0, motion.duration, _TIME_SAMPLES)
    q = inverse_kinematics(motion.state_at(t)[0], config.geometry, name='motion point')
    knots = plan.joint_trajectory
    figure, axes = _new_figure(size=(8.0, 4.5))
    axis = axes[0, 0]
    for column, (color, style) in enumerate(_JOINT_STYLES):
        name = config.joint_names[column]
        axis.plot(t, np.degrees(q[:, column]), color=color, ls=style, label=name)
        axis.plot(knots.time_from_start, np.degrees(knots.positions[:, column]), '.',
                  color=color, ms=4)
    for time in _segment_times(plan):
        axis.axvline(time, color='grey', lw=0.8, ls=':')
    axis.set(xlabel='time [s]', ylabel='joint angle q [deg]',
             title=f'Fig. 7: joint angles, {motion.profile} profile, {motion.duration:.3f} s\n'
                   f'(dots: the {knots.time_from_start.size} JTC points; dotted: T1, T2)')
    axis.grid(True, alpha=0.3)
    axis.legend(loc='best')
    return _save(figure, out_dir, 'fig7_joint_angles.png')


def _figure8(arc, policy, out_dir):
    """Draw the proposed arc against the symmetric ellipse and the Lamé paths."""
    paths = figure8_paths(arc.l, arc.h, policy)
    figure, axes = _new_figure(size=(8.0, 4.0))
    axis = axes[0, 0]
    for path, color in zip(paths, ('red', 'green', 'blue', 'black')):
        axis.plot(path.points[:, 0], path.points[:, 1], color=color,
                  label=f'{path.label}: L = {path.length:.5f} m, H = {path.apex_height:.4f} m')
    axis.plot([-arc.l, arc.l], [-arc.h, arc.h], 'ko', ms=5)
    axis.set_aspect('equal', adjustable='datalim')
    axis.set(xlabel='u (horizontal, pick -> place) [m]', ylabel='z [m]',
             title='Fig. 8: path comparison, T1 to T2 (L: length, H: apex above lower T)')
    axis.grid(True, alpha=0.3)
    figure.legend(fontsize='small', loc='outside lower center')
    return _save(figure, out_dir, 'fig8_path_comparison.png')


def _figure_profiles(plans, config, out_dir):
    """Draw the speed, acceleration norm and jerk norm of both profiles on the same path."""
    figure, axes = _new_figure(3, 1, size=(8.0, 7.5), sharex='col')
    limits = config.limits
    bounds = (limits.max_speed, limits.max_accel, limits.max_jerk)
    labels = ('speed |v| [m/s]', 'acceleration |a| [m/s^2]', 'jerk |j| [m/s^3]')
    for plan, color in zip(plans, ('tab:blue', 'tab:orange')):
        motion = plan.motion
        t = np.linspace(0.0, motion.duration, _TIME_SAMPLES)
        norms = [np.linalg.norm(value, axis=1) for value in motion.state_at(t)[1:]]
        for row, value in enumerate(norms):
            axes[row, 0].plot(t, value, color=color,
                              label=f'{motion.profile}: {motion.duration:.3f} s')
        for time in _segment_times(plan):
            for axis in axes[:, 0]:
                axis.axvline(time, color=color, lw=0.6, ls=':')
    for axis, bound, label in zip(axes[:, 0], bounds, labels):
        axis.axhline(bound, color='grey', ls='--', lw=0.8)
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    ratio = plans[1].motion.duration / plans[0].motion.duration
    axes[0, 0].set_title(f'time_optimal vs curvature profile on the same path: '
                         f'{ratio:.1f}x slower\n(dashed: limits; dotted: T1, T2)')
    axes[0, 0].legend()
    axes[-1, 0].set_xlabel('time [s]')
    return _save(figure, out_dir, 'profiles_comparison.png')


def _figure_workspace(plan, workspace, out_dir):
    """
    Draw the safe workspace and the planned TCP path in it, from above and from the side.

    The cylinder (radius about the base axis, z range) and every keep-out box, as the planner
    checks them (``config.workspace``); the path is the planned one, pick to place.
    """
    from matplotlib.patches import Circle, Rectangle

    path = plan.path.at_lengths(np.linspace(0.0, plan.path.length, 400)).position * 1e3
    radius, z_min, z_max = (value * 1e3 for value in
                            (workspace.radius, workspace.z_min, workspace.z_max))
    boxes = np.asarray(workspace.keep_out_boxes, dtype=float).reshape(-1, 6) * 1e3
    figure, axes = _new_figure(1, 2, size=(10.0, 4.5))
    top, side = axes[0]
    top.add_patch(Circle((0.0, 0.0), radius, fill=False, color='black',
                         label=f'cylinder r = {radius:g} mm'))
    side.add_patch(Rectangle((-radius, z_min), 2 * radius, z_max - z_min, fill=False,
                             color='black', label=f'z from {z_min:g} to {z_max:g} mm'))
    for index, box in enumerate(boxes):
        style = {'color': 'tab:red', 'alpha': 0.3,
                 'label': 'keep-out boxes' if index == 0 else None}
        top.add_patch(Rectangle(box[[0, 1]], *(box[[3, 4]] - box[[0, 1]]), **style))
        side.add_patch(Rectangle(box[[0, 2]], *(box[[3, 5]] - box[[0, 2]]), **style))
    for axis, (first, second), labels in ((top, (0, 1), ('x [mm]', 'y [mm]')),
                                          (side, (0, 2), ('x [mm]', 'z [mm]'))):
        axis.plot(path[:, first], path[:, second], 'b-', label='planned TCP path')
        axis.plot(*path[0, [first, second]], 'o', mfc='none', mec='red', ms=9, label='pick')
        axis.plot(*path[-1, [first, second]], 'o', mfc='none', mec='green', ms=9,
                  label='place')
        axis.set(xlabel=labels[0], ylabel=labels[1])
        axis.set_aspect('equal', adjustable='datalim')
        axis.autoscale_view()
        axis.grid(True, alpha=0.3)
    top.set_title('from above')
    side.set_title('from the side (x, z)')
    side.legend(fontsize='small', loc='best')
    figure.suptitle(f'safe workspace: {workspace.describe()}; the planned path')
    return _save(figure, out_dir, 'workspace.png')


def write_figures(pick, place, out_dir, config=None):
    """
    Write the figures for one pick and place as PNG files into ``out_dir``.

    Figures 2 (for the path's l, h), 3 (the paper's a = 0.3, b = 0.05 and this
    arc), 5, 6 and 7 (the paper's curvature profile with ``config.curvature_r``),
    8 (comparison paths for this l, h), the time-optimal vs curvature
    profile comparison, and the safe workspace (``config.workspace``: cylinder, z range,
    keep-out boxes) with the planned path, from above and from the side.

    Parameters
    ----------
    pick, place : array_like
        Pick and place TCP positions in the base frame [m], shape (3,).
    out_dir : str or os.PathLike
        Output directory, created if missing.
    config : PlannerConfig, optional
        Planner settings (arc policy, limits, geometry, r); defaults when omitted.
        Its ``profile`` is ignored: both profiles are planned.

    Returns
    -------
    list of str
        Paths of the written PNG files.

    Raises
    ------
    ImportError
        If matplotlib is missing (install the plot extra: pip install .[plot]).
    EllipathError
        If the move cannot be planned, or has no arc (a pure vertical move).

    """
    config = config or PlannerConfig()
    _matplotlib()
    # The paper's figures show the paper's path (its node rule lives on the ellipse).
    curvature = plan_transfer(pick, place, replace(config, profile='curvature', join='paper'))
    arc = curvature.path.arc
    if arc is None:
        raise DegenerateGeometryError(
            'figures: expected pick and place apart horizontally, got a pure vertical move '
            '(no elliptic arc to draw)')
    optimal = plan_transfer(pick, place, replace(config, profile='time_optimal'))
    os.makedirs(out_dir, exist_ok=True)
    r = config.curvature_r
    return [_figure2(arc, config.arc, out_dir), _figure3(arc, out_dir),
            _figure5(curvature, r, out_dir), _figure6(curvature, r, out_dir),
            _figure7(curvature, config, out_dir), _figure8(arc, config.arc, out_dir),
            _figure_profiles((optimal, curvature), config, out_dir),
            _figure_workspace(optimal, config.workspace, out_dir)]
