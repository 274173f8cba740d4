"""The joint-space field is computed on the solve worker, with the solve or for the solve on screen; the drawing loop
only draws the arrows it is handed, and they are the numbers a direct computation gives for the state shown."""

from __future__ import annotations

import dataclasses
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from viz_helpers import drag_gizmo, running_app, settle

import ikdp
from ikdp_viz import joint_space
from ikdp_viz.joint_space import (
    FieldAsk,
    field_at,
    link_headings,
    model_timestep,
    solve_fields,
    torus_grid,
)
from ikdp_viz.joint_space_view import ARROW_LIFT, arrow_segments
from ikdp_viz.planar_scene import state_labels
from ikdp_viz.solve_worker import Cancelled
from ikdp_viz.solving import SolveRequest, solve


@pytest.fixture(scope="module")
def solver(tiny_checkpoint):
    return ikdp.load(tiny_checkpoint)  # N = 3: a pair of joints and one held


def same(arrows, other) -> bool:
    """The same field to float32 rounding (a condition computed for one row may round otherwise than for many)."""
    return np.allclose(arrows, other, rtol=0.0, atol=1e-6)


def direct_arrows(solver, view, state: int, joints, highlight: int, count: int) -> np.ndarray:
    """The field at `state` as one call for that state alone computes it (joint_space.field_at)."""
    held = link_headings(view.joints[state])[highlight]
    return field_at(solver, view.target, model_timestep(view.labels, state), joints, held, count).arrows


def guard_the_network(monkeypatch, app) -> list[bool]:
    """Every denoiser call from now on is recorded (True: on the drawing loop's thread), and one there raises."""
    calls: list[bool] = []
    denoiser = app.solver.model.denoiser
    plain = denoiser.denoise

    def denoise(*args, **kwargs):
        calls.append(app.writer.on_loop_thread())
        if calls[-1]:
            raise AssertionError("the drawing loop ran the network")
        return plain(*args, **kwargs)

    monkeypatch.setattr(denoiser, "denoise", denoise)
    for name in ("clean_estimates", "clean_estimates_of_vectors", "clean_estimates_of_states"):
        function = getattr(joint_space, name)

        def guarded(*args, _function=function, **kwargs):
            calls.append(app.writer.on_loop_thread())
            if calls[-1]:
                raise AssertionError("the drawing loop computed a joint-space field")
            return _function(*args, **kwargs)

        monkeypatch.setattr(joint_space, name, guarded)
    return calls


def drawn_fields(monkeypatch, nodes) -> list:
    """(state, the field drawn or None, arrows visible) of every joint-space draw from now on."""
    drawn = []
    draw = nodes.draw

    def recording(solver, frame):
        draw(solver, frame)
        visible = nodes.arrows is not None and nodes.arrows.visible
        drawn.append((frame.state, frame.highlight, nodes.last_field, visible))

    monkeypatch.setattr(nodes, "draw", recording)
    return drawn


def test_the_fields_of_every_state_are_the_numbers_of_a_call_for_that_state_alone(solver):
    headings = np.random.default_rng(0).uniform(-np.pi, np.pi, (6, 4, 3))  # 5 steps of 4 samples, 3 links
    view = SimpleNamespace(
        joints=ikdp.forward_kinematics(torch.as_tensor(headings)).numpy(),
        labels=state_labels([19, 15, 10, 5, 0]),
        target=np.array([0.8, -0.4]),
    )
    fields = solve_fields(solver, view, (0, 2), highlight=3, count=7)
    assert fields.arrows.shape == (6, 49, 2) and fields.held_by == 3
    assert fields.timesteps.tolist() == [19, 15, 10, 5, 0, 0]
    for state in range(6):
        field = fields.at(state)
        assert same(field.arrows, direct_arrows(solver, view, state, (0, 2), 3, 7)), state
        assert field.timestep == model_timestep(view.labels, state)
    assert fields.fits((0, 2), 3, 7) and not fields.fits((0, 1), 3, 7)
    assert not fields.fits((0, 2), 2, 7) and not fields.fits((0, 2), 3, 8)  # another held pose, another grid
    final = solve_fields(solver, view, (0, 2), 3, 7, states=[5])  # a drag's solve: the state it is drawn at
    assert final.computed.tolist() == [False] * 5 + [True] and final.at(0) is None
    assert same(final.at(5).arrows, fields.at(5).arrows)
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(Cancelled):
        solve_fields(solver, view, (0, 2), 3, 7, cancel)


def test_a_solve_asked_with_the_view_shown_brings_the_fields_of_its_highlighted_sample(solver):
    request = SolveRequest(
        solver=solver, target=np.array([0.9, 0.3]), num_samples=5, sampler="ddim", steps=4, refine_steps=0, seed=3,
        arrival=0.0, animate=True, joint_space=FieldAsk((1, 2), 6, "2"),
    )  # fmt: skip
    solved = solve(request)
    fields, last = solved.fields, solved.view.num_states - 1
    assert fields.joints == (1, 2) and fields.count == 6 and fields.held_by == 1  # "2" is the 0-based sample 1
    assert fields.arrows.shape == (last + 1, 36, 2) and fields.computed.all()  # it plays every state
    for state in (0, 2, last):
        assert same(fields.arrows[state], direct_arrows(solver, solved.view, state, (1, 2), 1, 6))
    dragged = solve(dataclasses.replace(request, animate=False)).fields  # drawn at its end, not played
    assert dragged.computed.tolist() == [False] * last + [True]
    assert same(dragged.arrows[last], fields.arrows[last])
    without = solve(dataclasses.replace(request, joint_space=None))
    assert without.fields is None and np.array_equal(without.view.joints, solved.view.joints)


def test_the_drawing_loop_draws_the_fields_it_is_handed_scrubbing_and_playing(solver, monkeypatch):
    with running_app(solver, animation_seconds=0.0, target=(0.9, 0.3)) as app:
        settle(app)
        nodes, controls = app.writer.stage.joint_space, app.panel.joint_space
        calls = guard_the_network(monkeypatch, app)
        controls.show.value = True  # shown after the solve: its fields are computed on the worker, then drawn
        assert calls and not any(calls)
        count, reach = int(controls.grid.value), solver.reach[1]
        view, highlight = app.solved.view, app.highlight_index()
        direct = {}  # state -> the field of a call for that state alone

        def expected(state):
            if state not in direct:
                direct[state] = direct_arrows(solver, view, state, (0, 1), highlight, count)
            return direct[state]

        for state in (0, 3, view.num_states - 1, 1):  # scrubbing
            app.show_state(state)
            assert nodes.arrows.visible and same(nodes.last_field.arrows, expected(state)), state
            drawn = arrow_segments(nodes.square, torus_grid(count), expected(state), count, ARROW_LIFT * reach)
            assert np.allclose(nodes.arrows.points, drawn, atol=1e-6)
        drawn = drawn_fields(monkeypatch, nodes)
        app.panel.duration.value = 0.6
        app.show_state(0)
        app.toggle_play()  # plays to the end, the loop's clock drawing each state
        settle(app)
        played = {state for state, *_ in drawn}
        assert len(played) >= 3 and app.state == view.num_states - 1
        for state, _, field, visible in drawn:
            assert visible and same(field.arrows, expected(state)), state
        assert not any(calls)
        app.move_target((0.2, 1.0))  # a new solve with the view shown brings its own fields
        settle(app)
        fields = app.solved.fields
        assert fields is not None and fields.fits((0, 1), app.highlight_index(), count) and fields.computed.all()
        assert same(nodes.last_field.arrows, fields.arrows[-1])
        jobs = app._fields_job
        drag_gizmo(app, 0.5, 0.9)  # a drag's solve, drawn at its end: that state's field came with it
        settle(app)
        view, highlight, last = app.solved.view, app.highlight_index(), app.solved.view.num_states - 1
        direct.clear()  # `expected` reads the new solve
        assert app.solved.fields.computed.tolist() == [False] * last + [True] and app._fields_job is jobs
        assert app.state == last and same(nodes.last_field.arrows, expected(last))
        app.show_state(2)  # scrubbed: the other states' fields are computed off the loop, then drawn
        settle(app)
        assert app._fields_job is not jobs and nodes.arrows.visible
        assert same(nodes.last_field.arrows, expected(2))
        assert not any(calls)


def test_a_changed_pair_or_highlight_is_computed_off_the_loop_with_no_arrows_meanwhile(solver, monkeypatch):
    with running_app(solver, animation_seconds=0.0, target=(0.9, 0.3)) as app:
        settle(app)
        nodes, controls = app.writer.stage.joint_space, app.panel.joint_space
        controls.show.value = True
        calls = guard_the_network(monkeypatch, app)
        jobs = []  # what the screen showed while each field job ran
        import ikdp_viz.app as app_module

        computed = app_module.solve_fields

        def watched(model, view, joints, highlight, count, cancel=None):
            time.sleep(0.05)  # the loop has long drawn the frame that asked
            jobs.append((joints, highlight, app.writer.on_loop_thread(), nodes.arrows.visible, nodes.last_field))
            return computed(model, view, joints, highlight, count, cancel)

        monkeypatch.setattr(app_module, "solve_fields", watched)
        count, view = int(controls.grid.value), app.solved.view
        controls.second.value = "θ3"  # a Python-set value returns once drawn, arrows too
        assert [job[:3] for job in jobs] == [((0, 2), app.highlight_index(), False)]
        assert jobs[0][3:] == (False, None)  # no arrows of the pair before while the new pair's were computed
        state = app.state
        assert nodes.arrows.visible
        assert same(nodes.last_field.arrows, direct_arrows(solver, view, state, (0, 2), app.highlight_index(),
                                                                     count))  # fmt: skip
        app.panel.highlight.value = "2"  # another sample holds θ2
        assert [job[:2] for job in jobs[1:]] == [((0, 2), 1)] and jobs[1][3:] == (False, None)
        assert same(nodes.last_field.arrows, direct_arrows(solver, view, state, (0, 2), 1, count))
        controls.grid.value = 5
        assert jobs[-1][:2] == ((0, 2), 1) and nodes.last_field.arrows.shape == (25, 2)
        app.panel.highlight.value = "2"  # unchanged: nothing is computed again
        app.show_state(0)
        assert len(jobs) == 3 and not any(calls)
