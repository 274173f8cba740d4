"""Shipped models: one file per model (a few-step student folded into its teacher's), no resume state, every file
loadable, and `python -m ikdp.ship` copying the weights exactly."""

from __future__ import annotations

import pytest
import torch

import ikdp
from ikdp.checkpoint import read_checkpoint
from ikdp.describe import describe_shipped
from ikdp.ship import SHIPPED_KEYS, main, ship
from ikdp.shipped import PURPOSES, list_shipped

RESUME_STATE = ("optimizer", "scheduler", "raw_state_dict", "data_generator", "data_generators")
FOLDED = {"ikdp_n4": 2, "ikdp_n4_relaxed": 4, "ikdp_panda": 4}  # model -> its student's network evaluations


def test_every_shipped_file_loads_and_carries_no_resume_state():
    shipped = {path.stem: path for path in list_shipped()}
    assert set(shipped) == set(PURPOSES)  # every model has its one-line purpose, and nothing else ships
    assert sum(path.stat().st_size for path in shipped.values()) <= 60e6
    for name, path in shipped.items():
        payload = read_checkpoint(path)
        assert not set(RESUME_STATE) & set(payload), name
        solver = ikdp.load(name)
        assert (solver.student is not None) == (name in FOLDED), name


@pytest.mark.parametrize("name", sorted(FOLDED))
def test_a_folded_student_runs_on_the_grid_it_was_distilled_for(name):
    solver = ikdp.load(name)
    targets = solver.arm.end_effector(solver.prior.sample(3, solver.arm, generator=torch.Generator().manual_seed(0)))
    out = solver.solve(targets, num_samples=2, sampler="student", generator=torch.Generator().manual_seed(1))
    assert out.network_evaluations == FOLDED[name] and out.raw_angles.shape[:2] == (3, 2)
    record = solver.student.metadata["distill"]
    direct = solver.student.solve(
        targets, num_samples=2, sampler=record["sampler"], steps=record["steps"], spacing=record["spacing"],
        generator=torch.Generator().manual_seed(1),
    )  # fmt: skip
    assert torch.equal(out.raw_angles, direct.raw_angles)  # the student's network, not the teacher's


def test_the_student_sampler_on_a_model_without_one_says_what_it_has(tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    solver.model.sample = lambda *args, **kwargs: pytest.fail("sampling started")
    with pytest.raises(ValueError, match=r"^sampler: 'tiny' has no distilled student .*'ddpm', 'ddim'") as error:
        solver.solve([[1.0, 0.5]], sampler="student")
    assert "\n" not in str(error.value)
    folded = ikdp.load("ikdp_n4")
    with pytest.raises(ValueError, match=r"^steps, spacing: the student runs the 2 steps \(quadratic\)"):
        folded.solve([[1.0, 0.5]], sampler="student", steps=8)


def test_ship_copies_the_weights_exactly_and_drops_the_resume_state(tiny_checkpoint, tmp_path):
    trained = read_checkpoint(tiny_checkpoint)
    assert "optimizer" in trained  # a training file: resumable
    main(["--model", str(tiny_checkpoint), "--output", str(tmp_path / "tiny.pt")])
    shipped = read_checkpoint(tmp_path / "tiny.pt")
    assert set(shipped) <= {"format", "version", *SHIPPED_KEYS}
    assert shipped["model"] == trained["model"] and shipped["metrics"] == trained["metrics"]
    assert shipped["train"] == trained["train"]  # the recorded training command rebuilds from it
    assert shipped["state_dict"].keys() == trained["state_dict"].keys()
    for key, weights in trained["state_dict"].items():
        assert torch.equal(shipped["state_dict"][key], weights), key


def test_ship_folds_a_student_and_refuses_one_of_another_model(tiny_chain_student, tiny_checkpoint, tmp_path):
    teacher_path, student_path, _ = tiny_chain_student
    student = read_checkpoint(student_path)
    folded = read_checkpoint(teacher_path)["student"]  # the fixture shipped the teacher with its student
    assert folded["distill"] == student["distill"] and folded["train"]["command"] == student["train"]["command"]
    for key, weights in student["state_dict"].items():
        assert torch.equal(folded["state_dict"][key], weights), key
    with pytest.raises(ValueError, match=r"^student: distilled from .*panda_teacher\.pt'.* not the teacher's$"):
        ship(tiny_checkpoint, tmp_path / "wrong.pt", student_path)
    assert not (tmp_path / "wrong.pt").exists()


def test_a_nested_student_whose_weights_do_not_fit_is_refused_in_one_line(tiny_chain_student, tmp_path):
    teacher_path, _, _ = tiny_chain_student
    payload = read_checkpoint(teacher_path)
    name = next(iter(payload["student"]["state_dict"]))
    payload["student"]["state_dict"][name] = torch.zeros(3)
    torch.save(payload, tmp_path / "broken.pt")
    with pytest.raises(ikdp.CheckpointError, match=rf"broken\.pt \(its student\): weights do not match.*{name}"):
        ikdp.load(tmp_path / "broken.pt")
    del payload["student"]["distill"]
    torch.save(payload, tmp_path / "incomplete.pt")
    with pytest.raises(ikdp.CheckpointError, match=r"incomplete\.pt: its student is incomplete, missing distill$"):
        ikdp.load(tmp_path / "incomplete.pt")
    whole = (tmp_path / "broken.pt").read_bytes()
    (tmp_path / "truncated.pt").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(ikdp.CheckpointError, match="truncated.pt: ") as error:
        ikdp.load(tmp_path / "truncated.pt")
    assert "\n" not in str(error.value)


def test_describe_lists_what_ships_in_at_most_twenty_lines():
    lines = describe_shipped().splitlines()
    assert len(lines) <= 20 and len(lines) == 1 + len(PURPOSES)
    panda = next(line for line in lines if line.startswith("ikdp_panda |"))
    assert "the most precise Panda" in panda and "student: ddim 4 steps" in panda and " mm / " in panda
