"""What the two arm views (planar_view.py, robot_view.py) do alike, as functions of their nodes: no base class."""

from __future__ import annotations

import numpy as np

from ikdp_viz.style import LINE_PIXELS, PRIOR


def start_rebuild(view, solver, target) -> None:
    """Before an arm view builds its nodes for `solver`: the old samples, prior draw and static nodes go."""
    view.remove_samples()
    view.clear_prior()
    for handle in view._static_nodes:
        handle.remove()
    view._static_nodes = []
    view.solver, view.target = solver, np.asarray(target, dtype=np.float64)


def prior_lines(server, segments: np.ndarray, old=None):
    """The prior's draw, (M, 2, 3) segments in brown until the next solve, replacing `old`'s node."""
    if old is not None:
        old.remove()
    return server.scene.add_line_segments(
        "/prior", segments, colors=PRIOR, thickness=2 * LINE_PIXELS, thickness_units="screen"
    )


def removed(handle) -> None:
    """Remove `handle` if there is one; None, for the attribute that held it."""
    if handle is not None:
        handle.remove()
