"""A model's few-step student in the viewer: folded into its teacher's file, solved as the sampler "student", one
button from the teacher's full denoising, compared with it from the same x_T, and a drag's preview.

A tiny Panda teacher (T = 10) and a 2-step student distilled from it by ikdp.distill, folded into the teacher's file
by ikdp.ship and also in a file of its own: the poses are poor, which model ran and what the panel says are checked.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from viz_helpers import running_app, settle, solves_shown_by_a_robot_drag

import ikdp
from ikdp_viz.student import (
    STUDENT,
    TEACHER,
    is_student_of,
    matched_its_teacher,
    model_and_student,
    target_title,
)

K = 4
STUDENT_STEPS = 2


@pytest.fixture
def models(tiny_chain_student):
    return tiny_chain_student


@pytest.fixture
def app(models):
    teacher, _, folder = models
    with running_app(ikdp.load(teacher), solve_now=False, animation_seconds=0.0, checkpoint_folder=folder) as app:
        app.panel.samples.value = K
        settle(app)
        yield app


def test_the_student_is_the_one_folded_into_its_teachers_file(models, tiny_chain_checkpoint, tiny_checkpoint):
    teacher_path, student_path, folder = models
    teacher = ikdp.load(teacher_path)
    opened, student = model_and_student(teacher, folder)
    assert opened is teacher and student is teacher.student
    own_file = ikdp.load(student_path)
    for name, weights in own_file.model.state_dict().items():
        assert torch.equal(student.model.state_dict()[name], weights), name
    assert model_and_student(ikdp.load(tiny_checkpoint), folder)[1] is None  # another model has no student
    assert model_and_student(ikdp.load(tiny_chain_checkpoint), folder)[1] is None  # nor has the unshipped teacher
    record = dict(student.metadata["distill"])
    assert is_student_of(record, teacher)
    record["teacher_metrics"] = {**record["teacher_metrics"], "tip_error_median": 1.0}  # another model, same name
    assert not is_student_of(record, teacher)


def test_the_sampler_student_solves_with_the_students_network_in_its_own_steps(app, models):
    panel = app.panel
    assert panel.sampler.options[0] == STUDENT and STUDENT in panel.learn.compare.options
    assert panel.teacher_student.visible
    panel.sampler.value = STUDENT
    settle(app)
    request, view = app.solved.request, app.solved.view
    assert request.solver is app.session.student and request.solver is not app.solver
    assert (request.sampler, request.steps) == ("ddim", STUDENT_STEPS) and view.num_states == STUDENT_STEPS + 1
    assert panel.steps.disabled and panel.steps.value == STUDENT_STEPS  # the slider says the steps it takes
    assert "student's ddim" in panel.readout_text.content
    assert panel.teacher_student.label == "Show the teacher (DDPM, 10 steps)"


def test_one_click_shows_the_teachers_full_denoising_and_one_brings_the_student_back(app):
    panel = app.panel
    panel.sampler.value = STUDENT
    settle(app)
    app.writer.run(lambda _: app.sampling.on_switch())  # what the button's click does, on the loop
    settle(app)
    assert panel.sampler.value == "ddpm" and app.solved.request.solver is app.solver
    assert app.solved.view.num_states == app.solver.timesteps + 1 and panel.steps.value == app.solver.timesteps
    assert "teacher's ddpm" in panel.readout_text.content
    assert panel.teacher_student.label == f"Show the student (DDIM, {STUDENT_STEPS} steps)"
    app.writer.run(lambda _: app.sampling.on_switch())
    settle(app)
    assert panel.sampler.value == STUDENT and app.solved.request.solver is app.session.student


def test_teacher_and_student_are_compared_from_the_same_noise(app):
    panel = app.panel
    panel.sampler.value = STUDENT
    panel.learn.compare.value = "ddpm"  # the teacher's DDPM beside the student
    settle(app)
    solved = app.solved
    request, view, compare = solved.request, solved.view, solved.compare
    assert request.solver is app.session.student and request.compared_by is app.solver
    assert compare.num_states == app.solver.timesteps + 1 and view.num_states == STUDENT_STEPS + 1
    assert np.allclose(compare.joint_values[0], view.joint_values[0])  # x_T: the very same noise
    nodes = app.writer.stage.compare.nodes
    assert nodes["title"].text == "Teacher: DDPM (stochastic), 10 steps"
    assert nodes["main_title"].text == f"Student: DDIM (deterministic ODE), {STUDENT_STEPS} steps: same x_T"
    panel.sampler.value = "ddpm"  # and the other way round: the student beside the teacher
    panel.learn.compare.value = STUDENT
    settle(app)
    assert app.solved.request.compared_by is app.session.student
    assert app.writer.stage.compare.nodes["title"].text.startswith("Student: DDIM")


def test_the_student_beside_the_teacher_run_it_learnt_to_match(app, models):
    """What distillation does, seen: the teacher's own sampler of the distillation (DPM-Solver++(2M), 4 steps
    packed here) from the student's x_T."""
    panel = app.panel
    assert {TEACHER, STUDENT} <= set(panel.learn.compare.options)
    panel.sampler.value = STUDENT
    panel.learn.compare.value = TEACHER
    settle(app)
    solved = app.solved
    request, view, compare = solved.request, solved.view, solved.compare
    assert request.compared_by is app.solver and (request.compare_sampler, request.compare_steps) == ("dpmpp2m", 4)
    assert request.compare_spacing == "quadratic" and compare.num_states == 5
    assert np.allclose(compare.joint_values[0], view.joint_values[0])
    title = app.writer.stage.compare.nodes["title"].text
    assert title == "Teacher: DPM-Solver++, 4 steps, what the student learnt to match"


def test_a_drag_with_the_teacher_previews_the_student(app):
    app.panel.sampler.value = "ddpm"
    settle(app)
    shown = solves_shown_by_a_robot_drag(app)
    assert [(solved.request.solver is app.session.student, solved.preview_of) for solved in shown] == [
        (True, "teacher's ddpm"),
        (False, None),
    ]
    app.writer.ask(solved=(shown[0], True))
    app.writer.flush()
    expected = f"**Fast preview** (student's ddim, {STUDENT_STEPS} steps) while the teacher's ddpm solve runs"
    assert expected in app.panel.readout_text.content


def test_the_command_line_opens_a_robot_on_its_student(app, models):
    from ikdp_viz.__main__ import apply_settings, parse_config

    apply_settings(app, parse_config(["--ckpt", str(models[0]), "--samples", str(K)]))
    settle(app)
    assert app.panel.sampler.value == STUDENT and app.solved.request.solver is app.session.student


def test_a_model_without_a_student_takes_the_student_away(app, tiny_chain_checkpoint):
    app.panel.sampler.value = STUDENT
    settle(app)
    assert app.load_checkpoint(tiny_chain_checkpoint)  # not in the folder: no student of its own there
    settle(app)
    panel = app.panel
    assert app.session.student is None and STUDENT not in panel.sampler.options
    assert STUDENT not in panel.learn.compare.options and not panel.teacher_student.visible
    assert panel.sampler.value == "ddpm" and app.solved.request.solver is app.solver


def test_a_students_file_opens_with_its_teacher_beside_it(models, tiny_chain_checkpoint):
    teacher_path, student_path, folder = models
    student = ikdp.load(student_path)
    teacher, paired = model_and_student(student, folder)
    assert paired is student and teacher.metadata["path"] == str(folder / "panda_teacher.pt")
    assert model_and_student(student, tiny_chain_checkpoint.parent)[1] is None  # its teacher is not there
    alone = ikdp.load(tiny_chain_checkpoint)
    assert model_and_student(alone, folder) == (alone, None)
    with running_app(student, solve_now=False, animation_seconds=0.0, checkpoint_folder=folder) as app:
        assert app.session.student is student and app.solver.metadata["path"] == teacher.metadata["path"]
        assert app.asked_for_student  # the command line then opens on the student, planar arm or robot


def test_picking_a_students_file_shows_the_student_with_its_teacher(app, models, tiny_chain_checkpoint):
    teacher_path, student_path, folder = models
    assert app.load_checkpoint(tiny_chain_checkpoint)
    settle(app)
    assert app.session.student is None
    assert app.load_checkpoint(student_path)
    settle(app)
    assert app.solver.metadata["path"] == str(teacher_path) and app.session.student is not None
    assert app.panel.sampler.value == STUDENT and app.solved.request.solver is app.session.student


def test_a_folders_checkpoints_are_read_once_for_the_dropdown_and_the_student(models, monkeypatch):
    import ikdp_viz.student as headers
    from ikdp_viz.models import ModelChoices, list_checkpoints

    teacher_path, _, folder = models
    teacher = ikdp.load(teacher_path)
    reads = []
    real = headers.read_checkpoint
    monkeypatch.setattr(headers, "_headers", {})
    monkeypatch.setattr(headers, "read_checkpoint", lambda path: reads.append(path) or real(path))
    ModelChoices(list_checkpoints(folder), teacher, folder)
    assert model_and_student(teacher, folder)[1] is not None
    ModelChoices(list_checkpoints(folder), teacher, folder).refresh(teacher)
    assert sorted(reads) == sorted(folder.glob("*.pt"))  # each file once


def test_the_teachers_run_is_called_what_the_student_matched_only_where_its_distillation_matched_it():
    """A student distilled with --match-weight 0 learnt from the FK miss and the DDPM's samples, not from the teacher's
    ODE run: the comparison's label must not say it learnt to match that run."""
    from types import SimpleNamespace

    matched, free = ({"train": {"match_weight": weight}} for weight in (1.0, 0.0))
    old = {"train": {}}  # a record from before the option: it matched
    assert [matched_its_teacher(SimpleNamespace(metadata=m)) for m in (matched, free, old)] == [True, False, True]
    assert target_title("dpmpp2m", 16, matched=False) == "Teacher: DPM-Solver++, 16 steps, same x_T"
    assert ikdp.load("ikdp_panda").student.metadata["train"]["match_weight"] == 0.0  # the shipped student


def test_comparing_the_sampler_shown_with_itself_says_there_is_nothing_to_compare(app):
    panel = app.panel
    panel.sampler.value = STUDENT
    panel.learn.compare.value = STUDENT  # the very sampler shown: nothing drawn beside it
    settle(app)
    assert app.solved.compare is None
    assert "nothing to compare" in panel.readout_text.content
    panel.learn.compare.value = "ddpm"
    settle(app)
    assert app.solved.compare is not None and "nothing to compare" not in panel.readout_text.content
