"""The panel's texts and the plot's range, from plain values."""

from __future__ import annotations

import numpy as np
from viz_helpers import hand_made_result

from ikdp_viz.planar_scene import build_view
from ikdp_viz.readouts import error_range, solve_text, target_text


def test_target_text_gives_the_coordinates_and_says_when_the_target_was_clamped():
    assert target_text(np.array([1.25, -0.5]), False, (0.0, 4.0)) == "**Target** x = +1.250, y = -0.500"
    clamped = target_text(np.array([4.0, 0.0]), True, (0.0, 4.0))
    assert "Clamped to the workspace boundary* (r = 4.00)" in clamped
    assert "(r = 1.00)" in target_text(np.array([0.0, 1.0]), True, (1.0, 3.0))  # pushed out to the inner circle


def test_solve_text_reads_the_shown_step_and_the_end_for_the_highlighted_sample():
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))
    text = solve_text(view, 1, 0, sampler="ddpm", seed=7, refine_steps=0, solve_seconds=0.0314)
    assert "**Step** 1 of 2 (t = 1)" in text
    assert "sample 1 of 2 (the best by tip error at t = 0): 1.4142 now, 0.0000 at t = 0" in text  # counted from 1
    assert "median of K = 2: 1.4142 now, 0.7071 at t = 0" in text
    assert "**Solve** 31.4 ms (ddpm, 2 steps, seed 7)" in text and "refined" not in text
    ddim = solve_text(view, 2, 1, sampler="ddim", seed=0, refine_steps=0, solve_seconds=0.01, error="boom")
    assert "(ddim, 2 steps, seed 0)" in ddim and "**Last solve failed** boom" in ddim
    assert "sample 2 of 2:" in ddim  # not the best: no ranking note


def test_with_refinement_the_best_says_it_ranks_refined_errors_and_names_the_best_raw_sample_apart():
    """Once, "sample 5 ..., by raw tip error at t = 0, sample 11: 0.0167 now" gave sample 5's
    numbers after sample 11's name; the numbers now follow their own sample, the raw best has a line of its own."""
    import dataclasses

    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))  # raw tip errors at t = 0: 0 and 0.7071
    refined = dataclasses.replace(view, refined=True, final_tip_error=np.array([0.5, 0.0]))  # sample 2 polishes best
    text = solve_text(refined, 2, refined.best_sample(), sampler="ddpm", seed=0, refine_steps=5, solve_seconds=0.0)
    assert "sample 2 of 2 (the best by refined tip error): 1.4142 now, 1.4142 at t = 0" in text
    assert "  \nby raw tip error at t = 0 the best is sample 1  \n" in text
    assert "sample 1:" not in text
    same = dataclasses.replace(view, refined=True, final_tip_error=np.array([0.0, 0.5]))  # both rank sample 1 first
    assert "sample 1 of 2 (the best by refined tip error): " in solve_text(
        same, 2, 0, sampler="ddpm", seed=0, refine_steps=5, solve_seconds=0.0
    )


def test_the_readout_says_why_the_highlighted_sample_is_the_one_followed():
    """A sample number chosen (or left by follow mode) must not read like "best"."""
    view = build_view(hand_made_result(), (1.0, 1.0), (2.0, 0.0))  # sample 1 is the best
    options = dict(sampler="ddpm", seed=0, refine_steps=0, solve_seconds=0.0)
    assert "sample 2 of 2 (chosen in the panel's highlight): " in solve_text(
        view, 2, 1, reason="chosen in the panel's highlight", **options
    )
    assert "sample 1 of 2 (kept by follow mode" in solve_text(view, 2, 0, reason="kept by follow mode (x)", **options)


def test_error_range_is_the_whole_decades_around_every_error():
    assert error_range(np.array([[3.0, 0.5], [0.02, 0.0]])) == (-2, 1)  # 0.01 .. 10
    assert error_range(np.array([[9.87], [0.00196]])) == (-3, 1)  # ikdp_n4 at (-0.010, 1.200): not 0.00098, a decade
    assert error_range(np.array([[0.5, 0.5]])) == (-1, 0)  # one decade at least
    assert error_range(np.zeros((2, 2))) == (-3, -2)
