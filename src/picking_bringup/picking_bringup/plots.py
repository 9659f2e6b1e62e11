"""Plots a person reads instead of tables: time profiles, 3D paths, error curves.

matplotlib is imported lazily with the Agg backend, so the core never needs a
display and importing this module is cheap.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def legend_below(fig, ax, ncol=4):
    """``ax``'s legend below the figure's plots, not over their curves (seven joint names fill
    an axis' width), then the layout leaving it room (0.22 in a row of names)."""
    unique = dict(zip(*reversed(ax.get_legend_handles_labels())))     # one entry per label
    labels, handles = list(unique), list(unique.values())
    fig.legend(handles, labels, loc='lower center', fontsize='small', ncol=min(len(labels), ncol), frameon=False)
    rows = -(-len(labels) // ncol)
    fig.tight_layout(rect=(0.0, 0.22 * rows / fig.get_figheight(), 1.0, 1.0))


def plot_profiles(path, t, q, qd, qdd, title, unit='rad', labels=None, marks=(), mark_labels=(), extra=None):
    """Position, velocity and acceleration over time, one line per joint (Figs. 5, 9-11, 14).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    t : ndarray, shape (N,)
        s.
    q, qd, qdd : ndarray, shape (N, n)
    unit : str
        Position unit for the axis labels (``rad``, ``deg``, ``m``).
    marks : sequence of float
        Times to mark with vertical lines (segment starts, via points).
    mark_labels : sequence of str
        A name for each mark (the segment that starts there): its number written over its span, the names in a key.
    extra : (label, values (N,), unit), optional
        One more quantity on an axis of its own below (the gripper's opening, in m).
    """
    plt = _pyplot()
    n = q.shape[1]
    labels = labels or [f'joint {j + 1}' for j in range(n)]
    fig, axes = plt.subplots(3 + (extra is not None), 1, sharex=True, figsize=(8, 7.5 + 2.0 * (extra is not None)))
    units = (f' [{unit}]', f' [{unit}/s]', f' [{unit}/s²]') if unit else ('', ' [1/s]', ' [1/s²]')
    for ax, data, name in zip(axes, (q, qd, qdd), (f'{what}{u}' for what, u in zip(
            ('position', 'velocity', 'acceleration'), units))):
        for j in range(n):
            ax.plot(t, data[:, j], label=labels[j])
        for m in marks:
            ax.axvline(m, color='0.8', lw=0.8, zorder=0)
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
    if extra is not None:
        label, values, extra_unit = extra
        axes[3].plot(t, values, color='0.3', label=label)
        for m in marks:
            axes[3].axvline(m, color='0.8', lw=0.8, zorder=0)
        axes[3].set_ylabel(f'{label} [{extra_unit}]')
        axes[3].grid(True, alpha=0.3)
    # Each segment's number over its span (short ones have no room for a name), the names in a key above.
    spans = list(marks) + [t[-1]]
    for i in range(len(mark_labels)):
        axes[0].annotate(str(i + 1), ((spans[i] + spans[i + 1]) / 2, 1.01), xycoords=('data', 'axes fraction'),
                         fontsize='small', ha='center', va='bottom', color='0.3')
    if mark_labels:
        import textwrap
        key = textwrap.fill('   '.join(f'{i + 1} {name}' for i, name in enumerate(mark_labels)), 110)
        fig.suptitle(title)
        axes[0].set_title(key, fontsize='small', color='0.3', pad=16)
    else:
        axes[0].set_title(title)
    axes[-1].set_xlabel('time [s]')
    if n > 1:
        legend_below(fig, axes[0])
    else:
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_path_3d(path, curves, points=None, title='', point_labels=None, unit=''):
    """A 3D tool path (Fig. 13): ``curves`` maps a label to an (N, 3) polyline; the first is drawn wide and
    light beneath the others (a plan under what was measured along it). ``unit`` labels the axes."""
    plt = _pyplot()
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection='3d')
    for k, (label, xyz) in enumerate(curves.items()):
        style = dict(lw=4, alpha=0.35) if k == 0 and len(curves) > 1 else dict(lw=1.2)
        ax.plot(xyz[:, 0], xyz[:, 1], xyz[:, 2], label=label, **style)
    if points is not None:
        ax.scatter(points[:, 0], points[:, 1], points[:, 2], color='C3', s=14, label='P1, insertion points, P3')
    for label, xyz in (point_labels or {}).items():
        ax.scatter(*xyz, color='k', s=25)
        ax.text(*xyz, f' {label}')
    u = f' [{unit}]' if unit else ''
    ax.set_xlabel(f'x{u}'), ax.set_ylabel(f'y{u}'), ax.set_zlabel(f'z{u}')
    _equal_axes(ax, np.vstack(list(curves.values())))
    return _save_3d(plt, fig, ax, path, title)


def _save_3d(plt, fig, ax, path, title):
    """A 3D figure's title and legend, written to ``path`` and closed."""
    ax.set_title(title)
    ax.legend(loc='upper left', fontsize='small')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _equal_axes(ax, xyz):
    centre = 0.5 * (xyz.max(axis=0) + xyz.min(axis=0))
    half = 0.5 * max(float(np.ptp(xyz, axis=0).max()), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)


def plot_loglog(path, x, y, xlabel, ylabel, title):
    """One curve on log-log axes (the Sec. 3.2 error against the number of points)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.loglog(x, y, marker='o', ms=3)
    ax.set_xlabel(xlabel), ax.set_ylabel(ylabel), ax.set_title(title)
    ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_workspace(path, tool, arm):
    """Tool positions reached within the joint limits: side (r, z) and top (x, y) views."""
    plt = _pyplot()
    fig, (side, top) = plt.subplots(1, 2, figsize=(11, 5))
    r = np.hypot(tool[:, 0], tool[:, 1]) * np.sign(tool[:, 0] + 1e-12)
    side.scatter(r, tool[:, 2], s=1, alpha=0.25)
    side.set_xlabel('signed radial distance from the waist axis [m]')
    side.set_ylabel('z [m]')
    side.set_title(f'{arm.name}: side view')
    top.scatter(tool[:, 0], tool[:, 1], s=1, alpha=0.25)
    top.set_xlabel('x [m]'), top.set_ylabel('y [m]'), top.set_title('top view')
    for ax in (side, top):
        ax.set_aspect('equal')
        ax.grid(True, alpha=0.3)
    fig.suptitle(f'Reachable tool positions within the joint limits ({len(tool):,} random configurations)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_corners(path, corners, tracks, title, window=0.05, caption=None):
    """The tool near each corner of a path, side on: one panel per ``(name, point, direction)`` of
    ``corners`` (the line's unit direction toward the point), with every track of ``tracks`` (label ->
    name -> (N, 3) tool positions) within ``window`` m of the point, drawn as the distance along the
    line past the corner against the distance from the line (mm)."""
    plt = _pyplot()
    cols = min(len(corners), 2)
    rows = -(-len(corners) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.0 * cols, 3.6 * rows), squeeze=False)
    for ax, (name, point, direction) in zip(axes.flat, corners):
        for label, paths in tracks.items():
            rel = paths[name] - point
            near = np.linalg.norm(rel, axis=1) <= window
            along = rel @ direction
            off = np.linalg.norm(rel - along[:, None] * direction, axis=1)
            ax.plot(1e3 * along[near], 1e3 * off[near], label=label)
        ax.scatter([0.0], [0.0], color='k', s=20, zorder=3)
        ax.annotate(f' {name}', (0.0, 0.0))
        ax.set_xlabel('along the line past the corner [mm]')
        ax.set_ylabel('off the line [mm]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
    for ax in axes.flat[len(corners):]:
        ax.set_visible(False)
    fig.suptitle(title)
    legend_below(fig, axes.flat[0], ncol=len(tracks))
    if caption:
        fig.text(0.5, 0.005, caption, ha='center', va='bottom', fontsize='x-small', wrap=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


#: The two views of a tree: (column of the horizontal axis, of the vertical axis, their labels, the title).
TREE_VIEWS = ((1, 2, 'y [m]', 'z [m]', 'front view (y, z)'), (1, 0, 'y [m]', 'x [m]', 'top view (y, x)'))


def _tree_figure(path, draw, title, front, figsize):
    """A tree from the front (y-z) and from above (y-x): ``draw(ax, i, j)`` draws one view with
    columns i, j of the points; ``front`` titles the front view."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=figsize)
    for ax, (i, j, xl, yl, name) in zip(axes, TREE_VIEWS):
        draw(ax, i, j)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        ax.set_title(name)
    axes[0].set_title(front)
    fig.suptitle(title)
    legend_below(fig, axes[0])
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_platform(path, apples, by_arm, skipped, tools, bases, drawn, title):
    """A tree harvested by several arms, from the front (y-z) and from above (y-x), platform frame:
    each arm's apples (numbered in its picking order, the number on the apple) and tool path (thin) in its colour,
    the arms' bases, and the arms' links (thick; ``drawn``: ``(arm, points)``) at a few grasps."""
    p = np.array([T[:3, 3] for T in apples])
    colours = dict(zip(by_arm, ('tab:red', 'tab:blue', 'tab:green', 'tab:purple')))
    b = np.array(bases)

    def draw(ax, i, j):
        for ns, picked in by_arm.items():
            c = colours[ns]
            if len(tools.get(ns, ())):
                ax.plot(tools[ns][:, i], tools[ns][:, j], color=c, lw=0.5, alpha=0.45,
                        label=f'{ns}: its tool path (thin)')
            ax.scatter(p[picked, i], p[picked, j], s=70, color=c, zorder=3, label=f'{ns}: {len(picked)} apples')
            # Numbers written on their apples (white on the colour), never beside them where they collide.
            for n, k in enumerate(picked):
                ax.annotate(str(n + 1), p[k, [i, j]], ha='center', va='center', fontsize=6, color='white',
                            zorder=4)
        if skipped:
            ax.scatter(p[skipped, i], p[skipped, j], s=70, color='0.6', marker='X', zorder=3, label='left on the tree')
        for k, (ns, pts) in enumerate(drawn):
            ax.plot(pts[:, i], pts[:, j], color=colours[ns], lw=3, alpha=0.8, solid_capstyle='round',
                    label='an arm\'s links at a grasp (thick)' if k == 0 else None)
        ax.scatter(b[:, i], b[:, j], s=160, marker='s', color='k', zorder=4, label='arm bases')
    return _tree_figure(path, draw, title, 'front view (y, z): apples, tool paths, arms at grasps', (12, 5.4))


def plot_harvest(path, apples, order, skipped, tool, title):
    """A harvested tree from the front (y-z) and from above (x-y): the apples numbered in the order
    they were picked (skipped ones grey), the tool's path over the whole harvest."""
    p = np.array([T[:3, 3] for T in apples])

    def draw(ax, i, j):
        ax.plot(tool[:, i], tool[:, j], color='tab:blue', lw=0.6, alpha=0.6, label='tool path')
        ax.plot(p[order, i], p[order, j], color='tab:green', lw=1.2, ls='--', label='visiting order')
        picked = [k for k in range(len(p)) if k not in skipped]
        ax.scatter(p[picked, i], p[picked, j], s=90, color='tab:red', zorder=3, label='apple')
        if skipped:
            ax.scatter(p[skipped, i], p[skipped, j], s=90, color='0.6', marker='X', zorder=3, label='skipped')
        for n, k in enumerate(order):
            ax.annotate(str(n + 1), p[k, [i, j]], textcoords='offset points', xytext=(6, 6), fontsize=8)
    return _tree_figure(path, draw, title, 'front view (y, z)', (11, 5.2))


def plot_orchard(path, orchard, picked, skipped, tools, title):
    """A tree among branches from the front (y-z) and from above (y-x): the scene's branches and wires
    (drawn as wide as they are), the twigs the cloud holds, the apples (picked with branch awareness,
    skipped), and the tool path of each run (``tools``: label -> (N, 3), m)."""
    p = np.array([T[:3, 3] for T in orchard.apples])
    lo, hi = p.min(axis=0) - 0.3, p.max(axis=0) + 0.3
    styles = dict(zip(tools, (dict(color='tab:blue', lw=0.7, alpha=0.7), dict(color='tab:orange', lw=0.7, alpha=0.5))))

    def draw(ax, i, j):
        for o in orchard.scene.obstacles:
            if o.ends is None or o.name.startswith('twig'):            # (the twigs are drawn below)
                continue
            e = np.clip(o.ends, lo, hi)              # a wire along the whole row: the part beside the tree
            ax.plot(e[:, i], e[:, j], color='saddlebrown' if o.kind == 'branch' else '0.4', lw=_width(o.radius),
                    alpha=0.8, solid_capstyle='round', label=f'{"branches" if o.kind == "branch" else "wires"} (scene)')
        for e, r in zip(orchard.twigs, orchard.twig_radius):
            ax.plot(e[:, i], e[:, j], color='peru', lw=_width(r), alpha=0.9, solid_capstyle='round',
                    label='twigs (scene and cloud)')
        for label, tool in tools.items():
            if len(tool):
                ax.plot(tool[:, i], tool[:, j], label=f'tool path, {label}', **styles[label])
        ax.scatter(p[picked, i], p[picked, j], s=80, color='tab:red', zorder=3, label='apple picked')
        if skipped:
            ax.scatter(p[skipped, i], p[skipped, j], s=80, color='0.6', marker='X', zorder=3, label='apple skipped')
    return _tree_figure(path, draw, title, 'front view (y, z): branches, twigs, apples, tool paths', (12, 5.6))


def _width(radius):
    """A line width (points) about as wide as a rod of ``radius`` m in a tree figure's views."""
    return max(1.0, 2 * radius * 220)


def plot_viewer(path, links, moments, tool, world, title):
    """What a 3D viewer shows of a recording, for a reader with no viewer: the arm's links as a skeleton at a few
    ``moments`` ({label: {frame: (3,) position}}, each drawn from ``links``' (parent, child) pairs), the tool's
    path ((N, 3)) and the world's boxes and rods (``world``: ``('box', 4x4 pose, size)`` or ``('rod', (2, 3) ends,
    radius)``)."""
    plt = _pyplot()
    fig = plt.figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot(projection='3d')
    drawn = [tool]
    for kind, where, size in world:
        if kind == 'box':
            T = where
            corners = np.array([[sx, sy, sz] for sx in (-0.5, 0.5) for sy in (-0.5, 0.5) for sz in (-0.5, 0.5)])
            xyz = (T[:3, :3] @ (corners * size).T).T + T[:3, 3]
            for i in range(8):
                for j in range(i + 1, 8):
                    if np.count_nonzero(corners[i] != corners[j]) == 1:      # an edge of the box
                        ax.plot(*xyz[[i, j]].T, color='0.55', lw=0.8)
        else:
            ax.plot(*np.asarray(where).T, color='saddlebrown', lw=max(1.0, size * 200))
    ax.plot(*tool.T, color='0.25', lw=1.2, ls='--', label='the tool (tool0) over the pick')
    for k, (label, where) in enumerate(moments.items()):
        segments = [(where[a], where[b]) for a, b in links if a in where and b in where]
        for i, (a, b) in enumerate(segments):
            ax.plot(*np.array([a, b]).T, color=('C0', 'C1', 'C3', 'C4')[k % 4], lw=3, alpha=0.85,
                    label=label if i == 0 else None)
        drawn.append(np.array(list(where.values())))
    ax.set_xlabel('x [m]'), ax.set_ylabel('y [m]'), ax.set_zlabel('z [m]')
    _equal_axes(ax, np.vstack(drawn))
    return _save_3d(plt, fig, ax, path, title)


def plot_sway_picks(path, picks, title, span=60.0):
    """Swaying apples picked: one panel per pick of ``picks`` (``(label, t_apple (N,), y_apple (N,), t_tool (M,),
    y_tool (M,), t_closed or None)``, times in s from the grasp, y in mm across the approach): where the apple truly
    was and where the grasp point went, the fingers' closing marked; ``span`` mm either side of where the apple hangs
    (the grasp point comes in from beyond it)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(picks), figsize=(4.2 * len(picks), 3.8), squeeze=False, sharey=True)
    for ax, (label, ta, ya, tt, yt, closed) in zip(axes.flat, picks):
        ax.plot(ta, ya, 'o-', color='tab:red', ms=3, label="the apple's centre (the simulator's truth)")
        ax.plot(tt, yt, color='tab:blue', label='the grasp point (from joint_states)')
        if closed is not None:
            ax.axvline(closed, color='k', lw=0.8, ls='--', label='the fingers take the apple')
        ax.set_title(label, fontsize='medium')
        ax.set_ylim(-span, span)
        ax.set_xlabel('time from the grasp [s]')
        ax.grid(True, alpha=0.3)
    axes.flat[0].set_ylabel('across the approach, from where it hangs (y) [mm]')
    fig.suptitle(title)
    legend_below(fig, axes.flat[0], ncol=3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
