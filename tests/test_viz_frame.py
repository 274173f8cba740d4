"""One Frame of truth: the readouts, the chart and the legend of a picture come from the same snapshot
as its colours, so they name the same sample and the same colours. Plain values: no viser, no server."""

from __future__ import annotations

import dataclasses
import itertools
from types import SimpleNamespace

import numpy as np
import pytest
from viz_helpers import hand_made_result

from ikdp_viz.chain_kind import ChainKind, TreeKind
from ikdp_viz.frame import Palettes, ViewSettings, build_frame
from ikdp_viz.planar_kind import PlanarKind
from ikdp_viz.planar_scene import build_view, trail_points
from ikdp_viz.style import ACCENT_DARK, HOLDS, REFINED, TIP_DARK, TIP_FAINT, VIOLATES


def planar_solve(violation=None):
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))  # sample 1 lands on the target
    view = dataclasses.replace(view, estimate_joints=view.joints[1:].copy())  # a guess of x̂0 into each state
    request = SimpleNamespace(
        sampler="ddpm",
        sampler_label="ddpm",
        seed=0,
        refine_steps=0,
        compare_sampler=None,
        constraints=(),
        compare_note=None,
    )
    return SimpleNamespace(request=request, view=view, trail_points=trail_points(view.joints), solve_seconds=0.01,
                           compare=None, state_violation=violation, preview_of=None)  # fmt: skip


def frame_of(solved, state, **settings):
    return build_frame(PlanarKind(), solved, state, ViewSettings(**settings), palettes=Palettes(), animating_to=None)


def test_the_readout_and_the_chart_follow_the_sample_the_scene_highlights():
    solved = planar_solve()
    for choice, highlight in (("best", 0), ("2", 1)):
        frame = frame_of(solved, 1, highlight=choice)
        assert frame.highlight == highlight
        assert f"sample {highlight + 1} of 2" in frame.readout
        t, _, followed, now = frame.chart
        assert np.allclose(followed, np.log10(np.maximum(solved.view.tip_error[::-1, highlight], 1e-6)))
        assert np.isnan(now).sum() == len(now) - 1  # one dot: the state shown
        assert (frame.palette.arms[:, highlight] == ACCENT_DARK).all()  # the scene's blue is that sample too
    assert "(chosen in the panel's highlight)" in frame_of(solved, 1, highlight="2").readout


def test_the_legend_names_the_colours_the_frame_draws():
    """Green meant both refined and constraints-hold; under constraint colours the legend
    still showed the highlighted arm blue; the tips' swatch was their final orange only; 3-D listed a red cross."""
    solved = planar_solve(violation=np.array([[0.5, 0.5], [0.5, 0.0], [0.0, 0.3]]))  # (S+1, K)
    plain = frame_of(solved, 2, color_by_constraint=False)
    colored = frame_of(solved, 2)
    blue = lambda legend: any(e.swatch.color == ACCENT_DARK and e.text.startswith("highlighted") for e in legend)  # noqa
    assert blue(plain.legend) and not blue(colored.legend)
    assert {HOLDS, VIOLATES} <= {entry.swatch.color for entry in colored.legend}
    assert tuple(colored.palette.arms[2, 0]) == HOLDS  # the highlighted arm is green where the legend says green
    assert REFINED not in (HOLDS, VIOLATES)
    tips = next(entry for entry in plain.legend if entry.text.startswith("tip"))
    # one dot, drawn at the step shown pale (t = T) to orange (t = 0), as the words say: no ramp of tips
    assert (tips.swatch.shape, tips.swatch.faint, tips.swatch.color) == ("dot", TIP_FAINT, TIP_DARK)
    assert tuple(plain.palette.tips[0]) == TIP_FAINT and tuple(plain.palette.tips[-1]) == TIP_DARK
    robot = ChainKind().legend_entries(ViewSettings(), constraint_colors=False, view=None, solved=None)
    assert not any(entry.swatch.shape == "cross" for entry in robot)  # 3-D draws the target as the gizmo


LAYERS = ("x̂0", "refined", "poses drawn from the prior")  # the legend's entries of layers drawn only at times


def listed_layers(entries) -> set[str]:
    return {word for word in LAYERS if any(entry.text.startswith(word) for entry in entries)}


@pytest.mark.parametrize("kind", [PlanarKind(), ChainKind(), TreeKind()], ids=["planar", "chain", "tree"])
def test_the_legend_lists_x0_refined_and_the_prior_only_while_the_scene_draws_them(kind):
    """The viewer's legend listed x̂0 with "show x̂0" off, "refined" for a solve not refined and the prior's poses
    with none on screen: a screenshot's legend named layers its scene did not draw. A recording draws no prior."""
    for show_estimate, refined, prior in itertools.product((False, True), repeat=3):
        settings = ViewSettings(show_estimate=show_estimate, prior=prior, color_by_constraint=False)
        if kind.name == "planar":
            solved = planar_solve()
            solved.view = dataclasses.replace(solved.view, refined=refined)
            legend = build_frame(kind, solved, 1, settings, palettes=Palettes(), animating_to=None).legend  # mid-way
        else:
            solved = SimpleNamespace(view=SimpleNamespace(refined=refined, rotation_measure="rotation"))
            legend = kind.legend_entries(settings, constraint_colors=False, view=solved.view, solved=solved)
        drawn = {word for word, on in zip(LAYERS, (show_estimate, refined, prior), strict=True) if on}
        assert listed_layers(legend) == drawn, (show_estimate, refined, prior, [entry.text for entry in legend])
        assert any(entry.text.startswith("target") for entry in legend)  # the other entries stay
        recorded = dataclasses.replace(settings, recording=True)
        page = kind.legend_entries(recorded, constraint_colors=False, view=solved.view, solved=solved)
        assert listed_layers(page) == drawn - {"poses drawn from the prior"}


def test_the_legend_lists_x0_only_at_the_states_where_the_scene_draws_it():
    """With "show x̂0" on, the legend listed x̂0 at t = 0, where the guess is the final pose itself and no purple is
    seen, and at t = T, where no guess is drawn: it is listed exactly where the scene has a guess to draw."""
    kind, solved = PlanarKind(), planar_solve()
    settings = ViewSettings(show_estimate=True, color_by_constraint=False)
    last = solved.view.num_states - 1
    for state in range(last + 1):
        legend = build_frame(kind, solved, state, settings, palettes=Palettes(), animating_to=None).legend
        drawn = solved.view.estimate_at(state) is not None
        assert ("x̂0" in listed_layers(legend)) == drawn == (0 < state < last), state


@pytest.mark.parametrize("kind", [PlanarKind(), ChainKind(), TreeKind()], ids=["planar", "chain", "tree"])
@pytest.mark.parametrize("recording", [False, True])
def test_the_legend_lists_the_trail_only_while_it_is_drawn(kind, recording):
    def trail_listed(show_trail: bool) -> bool:
        settings = ViewSettings(show_trail=show_trail, recording=recording)
        entries = kind.legend_entries(settings, constraint_colors=False, view=None, solved=None)
        return any("trail" in entry.text for entry in entries)

    assert trail_listed(True) and not trail_listed(False)


def test_under_constraint_colours_the_legend_names_the_highlighted_samples_blue_trail():
    """With every sample's trail shown the highlighted one's stays blue while the arms turn green or red: the
    legend had no blue entry then (the page's browser suite saw blue pixels that no entry named)."""
    solved = planar_solve(violation=np.array([[0.5, 0.5], [0.5, 0.0], [0.0, 0.3]]))
    frame = frame_of(solved, 2, trail_of="all samples")
    assert (frame.palette.trail[2, 0 : solved.view.num_links, 0] == ACCENT_DARK).all()  # sample 1's trail: blue
    assert any(entry.swatch.color == ACCENT_DARK for entry in frame.legend), [e.text for e in frame.legend]


def test_the_3d_legend_gives_the_target_frame_beside_a_swatch_of_its_green_only_while_a_comparison_draws_it():
    """The comparison beside a robot draws the target as a frame of viser's red, green and blue axes; the legend
    named it only in the target's red entry, so its green axis had no swatch."""
    from ikdp_viz.style import FRAME_Y_GREEN

    settings = ViewSettings(color_by_constraint=False)
    for compare in (None, object()):
        solved = SimpleNamespace(view=SimpleNamespace(refined=False, rotation_measure="rotation"), compare=compare,
                                 request=SimpleNamespace(compare_sampler="ddim"))  # fmt: skip
        legend = ChainKind().legend_entries(settings, constraint_colors=False, view=solved.view, solved=solved)
        greens = [entry for entry in legend if entry.swatch.color == FRAME_Y_GREEN]
        assert len(greens) == (compare is not None), [entry.text for entry in legend]
