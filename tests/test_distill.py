"""ikdp.distill: the student's unrolled training loop is the solver's loop, and a run saves, resumes and loads."""

import warnings
from dataclasses import replace

import pytest
import torch

import ikdp
from ikdp.checkpoint import read_checkpoint
from ikdp.describe import describe
from ikdp.distill import SKIP_WEIGHTS, DistillConfig, distill, main, student_network
from ikdp.distill_reference import energy_distance, refined_in_place
from ikdp.distill_step import spread_miss, student_sampler, unrolled_student
from ikdp.train import parse_config


def small_config(tmp_path, teacher, **changes):
    values = dict(
        teacher=str(teacher),
        student_steps=2,
        teacher_steps=4,
        steps=6,
        batch=16,
        save_every=3,
        eval_targets=8,
        output=str(tmp_path / "student.pt"),
        log_dir=str(tmp_path / "tb"),
        threads=1,
    )
    values.update(changes)
    return DistillConfig(**values)


def test_the_unrolled_student_is_the_solvers_ddim(tiny_checkpoint, monkeypatch):
    # the loop the student is trained through must be the one it solves with, or training would optimise another map
    monkeypatch.setattr("ikdp.denoisers.film.compiled_workspace", lambda *args: None)
    solver = ikdp.load(tiny_checkpoint)
    model = solver.model
    config = DistillConfig(student_steps=3, spacing="quadratic")
    targets = torch.tensor([[1.0, 0.5], [0.0, -2.0]])
    noise = torch.randn((2, model.representation.dim), generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        unrolled = unrolled_student(model, student_sampler(model, config), noise, targets)
    out = solver.solve(
        targets, num_samples=1, sampler="ddim", steps=3, spacing="quadratic", initial_noise=noise[:, None]
    )
    assert out.timesteps == student_sampler(model, config).timesteps == [19, 5, 0]
    torch.testing.assert_close(model.representation.decode(unrolled), out.raw_angles[:, 0], atol=1e-5, rtol=0)


def test_a_student_saves_resumes_and_solves_in_its_own_steps(tiny_checkpoint, tmp_path):
    straight = distill(small_config(tmp_path / "a", tiny_checkpoint))
    distill(small_config(tmp_path / "b", tiny_checkpoint, steps=3))
    resumed = distill(small_config(tmp_path / "b", tiny_checkpoint, steps=6, resume=True))
    a, b = (torch.load(path, weights_only=True) for path in (straight, resumed))
    assert b["train"]["step"] == 6
    # --resume on the command line reads the run's own options back, the ones given override them
    again = parse_config(["--output", str(resumed), "--resume", "--steps", "9"], DistillConfig, "ikdp-distill")
    assert (again.teacher_steps, again.batch, again.steps) == (4, 16, 9)
    for name, value in a["state_dict"].items():
        torch.testing.assert_close(b["state_dict"][name], value, rtol=0, atol=0)
    teacher = torch.load(tiny_checkpoint, weights_only=True)["state_dict"]
    assert any(not torch.equal(a["state_dict"][name], teacher[name]) for name in teacher)  # it trained

    student = ikdp.load(straight)
    record = student.metadata["distill"]
    assert (record["sampler"], record["steps"], record["spacing"]) == ("ddim", 2, "quadratic")
    assert record["teacher_path"] == tiny_checkpoint.name  # a file name: another machine has other paths
    assert set(a["metrics"]) >= {"tip_error_median", "tip_error_mean", "step"}
    out = student.solve([[1.0, 0.5]], num_samples=4, sampler="ddim", steps=2)
    assert out.network_evaluations == 2 and out.timesteps == [19, 0]
    # its own (sampler, steps) take its grid; other solves keep the planar default
    assert student.default_spacing("ddim", 2) == "quadratic" and student.default_spacing("ddim", 4) == "uniform"


def test_a_run_that_shows_its_losses_warns_of_nothing(tiny_checkpoint, tmp_path):
    """The progress bar reads the losses every 10 steps: a gradient-carrying tensor read as a float made torch warn
    at every run."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        distill(small_config(tmp_path, tiny_checkpoint, steps=10))


def test_describe_prints_a_students_command_and_its_teachers_arm(tiny_checkpoint, tmp_path):
    config = small_config(tmp_path, tiny_checkpoint, steps=1, eval_targets=0)
    path = distill(config, command="python -m ikdp.distill --steps 1")
    text = describe([str(path)])
    assert "`python -m ikdp.distill --steps 1`" in text and "planar, 3 links" in text


def test_minutes_end_the_run_before_its_steps(tiny_checkpoint, tmp_path):
    path = distill(small_config(tmp_path, tiny_checkpoint, steps=1000, minutes=1e-9, eval_targets=0))
    train = read_checkpoint(path)["train"]
    assert train["step"] == 0 and train["finished"]  # the budget was spent before the first step


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--student-steps", "0"], "student_steps: got 0, expected a positive number"),
        (["--minutes", "-1"], "minutes: got -1.0, expected 0 (no clock) or a positive number"),
        (["--teacher", "no_such_model"], "no_such_model"),
        (["--spread-weight", "1"], "spread_weight: needs noises_per_target 2 or more"),
        (["--noises-per-target", "3", "--batch", "256"], "batch: got 256, expected a multiple of noises_per_target 3"),
        (["--refine-teacher-steps", "-1"], "refine_teacher_steps: got -1, expected 0 or more"),
        (["--distribution-weight", "1"], "distribution_weight: needs noises_per_target 2 or more"),
        (["--init", "no_such_student.pt"], "no_such_student.pt"),
        (["--reference-pool", "64"], "reference_pool: the pool is the distribution term's reference"),
        (["--match-weight", "0"], "match_weight: with 0 nothing ties the student to its teacher"),
        (["--match-weight", "-1"], "match_weight: got -1.0, expected 0 or more"),
        (["--dls-skip"], "dls_skip: for a robot's chain_film denoiser; ikdp_n4 has 'film'"),
        (["--device", "cuda:7"], "device: got 'cuda:7'"),  # as typed, before the teacher loads
    ],
)
def test_bad_options_are_one_line_errors(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--output", str(tmp_path / "s.pt")])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    assert "ikdp-distill: error:" in error and message in error and "Traceback" not in error


def test_the_spread_term_is_zero_for_a_moved_copy_of_the_teachers_spread_and_not_for_a_collapse():
    teacher = torch.randn((2 * 4, 5), generator=torch.Generator().manual_seed(0))  # 2 targets, 4 noises each
    rotation, _ = torch.linalg.qr(torch.randn((5, 5), generator=torch.Generator().manual_seed(1)))
    moved = teacher @ rotation + 0.3  # other poses, the same distances between them
    assert torch.allclose(spread_miss(moved, teacher, 4), torch.zeros(2), atol=1e-6)
    collapsed = teacher.unflatten(0, (2, 4)).mean(1, keepdim=True).expand(2, 4, 5).reshape(8, 5).clone()
    collapsed.requires_grad_(True)
    miss = spread_miss(collapsed, teacher, 4)
    assert (miss > 0.1).all()
    miss.sum().backward()
    assert torch.isfinite(collapsed.grad).all()  # no NaN where poses coincide


def test_a_run_with_the_spread_term_draws_several_noises_per_target(tiny_checkpoint, tmp_path):
    config = small_config(tmp_path, tiny_checkpoint, noises_per_target=4, spread_weight=1.0, steps=2)
    student = torch.load(distill(config), weights_only=True)
    assert student["train"]["spread_weight"] == 1.0 and student["train"]["noises_per_target"] == 4


def test_the_teachers_poses_are_refined_in_their_own_mode_only(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)
    arm = solver.model.arm
    generator = torch.Generator().manual_seed(0)
    solutions = solver.prior.sample(64, arm, generator=generator)
    targets = arm.end_effector(solutions)
    near = arm.normalize_joints(solutions + 0.02 * torch.randn(solutions.shape, generator=generator))
    refined = refined_in_place(arm, near, targets, steps=3)
    before, after = arm.task_error(near, targets).norm(dim=-1), arm.task_error(refined, targets).norm(dim=-1)
    assert (after <= before).all() and after.median() < 0.1 * before.median()  # a near pose reaches its target
    far = arm.normalize_joints(solutions + 2.0)  # far from any solution of its target: the solver would jump
    moved = refined_in_place(arm, far, targets, steps=3)
    jumped = (moved - far).norm(dim=-1) > 0
    assert ((moved - far).norm(dim=-1)[jumped] < 0.5).all()  # no pose is moved past the bound
    assert not jumped.all()


def test_a_run_starts_from_a_student_of_the_same_teacher_and_refuses_another(
    tiny_checkpoint, tmp_path, capsys, monkeypatch
):
    first = distill(small_config(tmp_path, tiny_checkpoint, steps=2))
    config = small_config(
        tmp_path, tiny_checkpoint, steps=1, init=str(first), refine_teacher_steps=2, output=str(tmp_path / "next.pt")
    )
    state = torch.load(first, weights_only=True)["state_dict"]
    started = {}
    original = torch.optim.AdamW.step

    def record_the_start(optimizer, *args, **kwargs):  # the weights as the first step finds them
        if not started:
            started.update({id(p): p.detach().clone() for group in optimizer.param_groups for p in group["params"]})
        return original(optimizer, *args, **kwargs)

    monkeypatch.setattr(torch.optim.AdamW, "step", record_the_start)
    student = torch.load(distill(config), weights_only=True)
    assert sorted(v.sum().item() for v in started.values()) == pytest.approx(
        sorted(v.sum().item() for v in state.values() if v.dtype.is_floating_point), rel=1e-5
    )
    assert student["train"]["refine_teacher_steps"] == 2 and student["distill"]["teacher_path"] == tiny_checkpoint.name
    with pytest.raises(SystemExit):
        main(["--teacher", str(tmp_path / "next.pt"), "--init", str(first), "--output", str(tmp_path / "x.pt")])
    assert "is a student of" in capsys.readouterr().err


def test_the_energy_distance_is_near_zero_for_one_distribution_and_not_for_a_shifted_or_collapsed_one():
    generator = torch.Generator().manual_seed(0)
    reference = torch.randn((50 * 16, 3), generator=generator)  # 50 targets, 16 samples each
    same = torch.randn((50 * 16, 3), generator=generator)
    shifted = same + torch.tensor([1.0, 0.0, 0.0])
    collapsed = same.unflatten(0, (50, 16)).mean(1, keepdim=True).expand(50, 16, 3).reshape(-1, 3).clone()
    collapsed.requires_grad_(True)
    assert abs(float(energy_distance(same, reference, 16).mean())) < 0.05
    assert float(energy_distance(shifted, reference, 16).mean()) > 0.3
    distance = energy_distance(collapsed, reference, 16)
    assert float(distance.detach().mean()) > 0.3
    distance.sum().backward()
    assert torch.isfinite(collapsed.grad).all()  # no NaN where poses coincide


def test_a_run_with_the_distribution_term_samples_the_teachers_ddpm(tiny_checkpoint, tmp_path, monkeypatch):
    import ikdp.distill_reference as reference_module

    calls = []
    real = reference_module.teacher_samples
    monkeypatch.setattr(reference_module, "teacher_samples", lambda *a: calls.append(len(a[1])) or real(*a))
    config = small_config(tmp_path, tiny_checkpoint, noises_per_target=4, distribution_weight=1.0, steps=2)
    student = torch.load(distill(config), weights_only=True)
    assert calls == [16, 16] and student["train"]["distribution_weight"] == 1.0  # one DDPM batch a step


def test_without_the_match_term_the_teachers_ode_is_not_run(tiny_checkpoint, tmp_path, monkeypatch):
    import ikdp.distill_step as step_module

    calls = []
    real = step_module.teacher_poses
    monkeypatch.setattr(step_module, "teacher_poses", lambda *a: calls.append(len(a[2])) or real(*a))
    config = small_config(tmp_path, tiny_checkpoint, noises_per_target=4, distribution_weight=1.0, steps=2)
    distill(config)
    assert calls == [16, 16]  # with the match term: the teacher's ODE once a step
    calls.clear()
    student = torch.load(
        distill(replace(config, match_weight=0.0, output=str(tmp_path / "free.pt"))), weights_only=True
    )
    assert calls == [] and student["train"]["match_weight"] == 0.0 and student["train"]["step"] == 2


def test_a_reference_pool_is_drawn_once_and_every_step_picks_its_targets_from_it(tiny_checkpoint, tmp_path):
    from ikdp.distill_reference import PoseStream

    solver = ikdp.load(tiny_checkpoint)
    config = small_config(tmp_path, tiny_checkpoint, noises_per_target=4, distribution_weight=1.0, reference_pool=6)
    stream = PoseStream(solver.model, solver.prior, config, torch.device("cpu"))
    pool_joints, pool_samples = stream.pool
    assert pool_joints.shape[0] == 6 and pool_samples.shape == (6, 4, solver.model.representation.dim)
    joints, reference = stream.draw(torch.Generator().manual_seed(0))
    assert joints.shape == (16, pool_joints.shape[1]) and reference.shape == (16, pool_samples.shape[-1])
    for row in range(0, 16, 4):  # each target's four rows: one pool entry, its own four samples
        entry = int((pool_joints - joints[row]).abs().sum(-1).argmin())
        assert torch.equal(joints[row : row + 4], pool_joints[entry].expand(4, -1))
        assert torch.equal(reference[row : row + 4], pool_samples[entry])
    again = PoseStream(solver.model, solver.prior, config, torch.device("cpu")).pool  # a resume draws the same pool
    assert torch.equal(again[1], pool_samples)
    student = torch.load(distill(replace(config, steps=2)), weights_only=True)
    assert student["train"]["reference_pool"] == 6


def test_init_refuses_a_student_of_another_network_under_the_teachers_name(
    tiny_checkpoint, tiny_chain_checkpoint, tmp_path, capsys
):
    import shutil

    first = distill(small_config(tmp_path, tiny_checkpoint, steps=1))
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(tiny_chain_checkpoint, other / tiny_checkpoint.name)  # the teacher's file name, another network
    with pytest.raises(SystemExit):
        main(["--teacher", str(other / tiny_checkpoint.name), "--init", str(first), "--output", str(other / "s.pt")])
    error = capsys.readouterr().err
    assert "has another network than its teacher" in error and "Traceback" not in error


def test_a_robot_student_with_the_dls_skip_starts_from_the_teacher_or_a_student_without_it(tmp_path):
    teacher = ikdp.load("ikdp_z1")  # a shipped robot model without the skip
    payload = read_checkpoint(teacher.metadata["path"])
    student = student_network(payload, teacher.metadata["path"], dls_skip=True)
    assert student.config.denoiser.dls_skip and not teacher.model.config.denoiser.dls_skip
    weights, teachers = student.state_dict(), teacher.model.state_dict()
    assert set(weights) - set(teachers) == SKIP_WEIGHTS
    assert all(torch.equal(weights[name], value) for name, value in teachers.items())  # the teacher's own weights
    assert all(not weights[name].any() for name in SKIP_WEIGHTS)  # the gain at its schedule's start

    robot = dict(student_steps=2, teacher_steps=2, steps=1, batch=8, eval_targets=0)
    plain = distill(small_config(tmp_path / "plain", "ikdp_z1", **robot))
    skip = distill(small_config(tmp_path / "skip", "ikdp_z1", **robot, init=str(plain), dls_skip=True))
    solver = ikdp.load(skip)
    assert solver.model.config.denoiser.dls_skip
    started = read_checkpoint(plain)["state_dict"]
    moved = read_checkpoint(skip)["state_dict"]
    assert set(moved) - set(started) == SKIP_WEIGHTS  # --init gave the rest: one step moved them only a little
    assert max(float((moved[name] - value).abs().max()) for name, value in started.items()) < 0.01
    with pytest.raises(ValueError, match="has another network than its teacher"):  # a skip student as a plain start
        distill(small_config(tmp_path / "back", "ikdp_z1", **robot, init=str(skip)))


def test_a_reference_pool_is_kept_for_the_next_run_of_the_same_teacher_and_redrawn_when_damaged(
    tiny_checkpoint, tmp_path, monkeypatch, capsys
):
    import ikdp.distill_reference as reference_module
    from ikdp.distill_reference import PoseStream

    solver = ikdp.load(tiny_checkpoint)
    config = small_config(tmp_path, tiny_checkpoint, noises_per_target=4, distribution_weight=1.0, reference_pool=6)
    folder = tmp_path / "pools"

    def stream(config):
        return PoseStream(solver.model, solver.prior, config, torch.device("cpu"), tiny_checkpoint, folder)

    drawn = []
    real = reference_module.teacher_samples
    monkeypatch.setattr(reference_module, "teacher_samples", lambda *a: drawn.append(len(a[1])) or real(*a))
    first = stream(config).pool
    (kept,) = folder.iterdir()
    assert drawn == [24] and kept.name.startswith(f"{tiny_checkpoint.stem}-")
    again = stream(config).pool  # the next run reads it: no DDPM
    assert drawn == [24] and torch.equal(again[0], first[0]) and torch.equal(again[1], first[1])
    assert "read from" in capsys.readouterr().err
    stream(replace(config, seed=5))  # another seed: another pool, another file
    assert drawn == [24, 24] and len(list(folder.iterdir())) == 2
    kept.write_bytes(kept.read_bytes()[:100])  # a run killed while copying it, say: drawn again and replaced
    redrawn = stream(config).pool
    assert drawn == [24, 24, 24] and torch.equal(redrawn[1], first[1])
    assert "drawing it again" in capsys.readouterr().err
    assert torch.equal(stream(config).pool[1], first[1]) and drawn == [24, 24, 24]


def test_refined_reference_samples_reach_their_targets_in_their_own_mode(tiny_chain_checkpoint):
    from ikdp.distill_reference import REFINE_MAX_MOVE, teacher_samples

    solver = ikdp.load(tiny_chain_checkpoint)
    model, arm = solver.model, solver.model.arm
    targets = arm.end_effector(solver.prior.sample(64, arm, generator=torch.Generator().manual_seed(2)))
    raw = model.representation.decode(teacher_samples(model, targets, torch.Generator().manual_seed(3)))
    refined = model.representation.decode(teacher_samples(model, targets, torch.Generator().manual_seed(3), 3))
    before, after = arm.task_error(raw, targets).norm(dim=-1), arm.task_error(refined, targets).norm(dim=-1)
    moved = (refined - raw).norm(dim=-1)
    assert (after <= before + 1e-6).all() and (after < 0.5 * before).any()
    assert (moved < REFINE_MAX_MOVE).all()


def test_refining_the_reference_needs_the_distribution_term(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["--refine-reference-steps", "3", "--output", str(tmp_path / "s.pt")])
    assert capsys.readouterr().err.strip() == (
        "ikdp-distill: error: refine_reference_steps: it refines the DDPM's samples; give distribution_weight > 0"
    )


def test_the_distance_form_of_the_fk_miss_keeps_pulling_where_the_square_fades():
    from ikdp.distill_step import fk_distance

    span = 1.3
    misses = torch.tensor([0.0, 5e-4, 0.02], requires_grad=True)  # metres: none, half a millimetre, two centimetres
    distance = fk_distance((misses / span) ** 2, span)
    assert distance[0] == 0 and torch.isclose(distance[2], (misses[2] - 1e-3) / span, rtol=0.01)  # the miss, less 1 mm
    (pull,) = torch.autograd.grad(distance.sum(), misses)
    (square_pull,) = torch.autograd.grad(((misses / span) ** 2).sum(), misses)
    assert pull[1] / pull[2] > 0.4 and square_pull[1] / square_pull[2] < 0.03  # at 0.5 mm: ~0.45 of the pull, not 1/40


def test_a_run_with_the_distance_term_records_it_and_a_negative_weight_is_refused(tiny_checkpoint, tmp_path, capsys):
    config = small_config(tmp_path, tiny_checkpoint, tip_distance_weight=30.0, steps=2)
    student = torch.load(distill(config), weights_only=True)
    assert student["train"]["tip_distance_weight"] == 30.0 and student["train"]["step"] == 2
    with pytest.raises(SystemExit):
        main(["--tip-distance-weight", "-1", "--output", str(tmp_path / "s.pt")])
    assert capsys.readouterr().err.strip().endswith("tip_distance_weight: got -1.0, expected 0 or more")


def test_a_posterior_pool_holds_prior_poses_that_reach_each_target_in_several_modes(tiny_checkpoint, tmp_path):
    from ikdp.distill_reference import PoseStream

    solver = ikdp.load(tiny_checkpoint)
    model, arm = solver.model, solver.model.arm
    options = dict(noises_per_target=16, distribution_weight=1.0, reference_pool=5, reference="posterior")
    config = small_config(tmp_path, tiny_checkpoint, **options)
    folder = tmp_path / "pools"
    joints, samples = PoseStream(model, solver.prior, config, torch.device("cpu"), tiny_checkpoint, folder).pool
    assert joints.shape == (5, arm.num_joints) and samples.shape == (5, 16, model.representation.dim)
    poses = model.representation.decode(samples.flatten(0, 1)).unflatten(0, (5, 16))
    targets = arm.end_effector(joints)[:, None].expand(-1, 16, -1)
    assert float(arm.tip_error(poses.flatten(0, 1), targets.flatten(0, 1)).max()) < 1e-3 * arm.span  # polished on
    assert float((poses - poses.mean(1, keepdim=True)).norm(dim=-1).mean()) > 0.3  # spread over the posterior
    (kept,) = folder.iterdir()
    assert kept.name.endswith("-posterior.pt")
    student = torch.load(distill(replace(config, steps=2, noises_per_target=4)), weights_only=True)
    assert student["train"]["reference"] == "posterior"


def test_a_pool_kept_before_the_reference_option_reads_as_the_teachers(tiny_checkpoint, tmp_path):
    from ikdp.reference_pool_cache import pool_key, pool_path, read_pool, write_pool

    key = pool_key(tiny_checkpoint, 2, 4, 1, 0)
    older = {name: value for name, value in key.items() if name != "reference"}
    path = pool_path(tmp_path, key)
    write_pool(path, older, torch.zeros(2, 3), torch.zeros(2, 4, 6))
    assert read_pool(path, key, 3, 6) is not None
    assert read_pool(path, pool_key(tiny_checkpoint, 2, 4, 1, 0, "posterior"), 3, 6) is None


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--reference", "posterior"], "reference: the posterior feeds the distribution term"),
        (["--reference", "posterior", "--distribution-weight", "1", "--noises-per-target", "2"], "give reference_pool"),
        (
            ["--reference", "posterior", "--distribution-weight", "1", "--noises-per-target", "2",
             "--reference-pool", "8", "--refine-reference-steps", "2"],
            "the posterior's samples reach their targets already",
        ),
        (
            ["--teacher", "ikdp_z1", "--reference", "posterior", "--distribution-weight", "1",
             "--noises-per-target", "2", "--reference-pool", "8"],
            "ikdp_z1's targets have 7: use --reference teacher",
        ),
    ],
)  # fmt: skip
def test_a_posterior_reference_it_cannot_draw_is_refused_in_one_line(tmp_path, capsys, options, message):
    with pytest.raises(SystemExit):
        main([*options, "--output", str(tmp_path / "s.pt")])
    error = capsys.readouterr().err
    assert message in error and error.count("\n") == 1 and not (tmp_path / "s.pt").exists()


def test_a_sample_predicting_student_of_an_epsilon_teacher_reads_its_network_output_as_the_pose(tmp_path):
    from ikdp.train import TrainConfig, train

    torch.manual_seed(0)
    teacher_path = train(
        TrainConfig(joints=3, steps=3, batch=32, hidden=32, blocks=1, timesteps=20, prediction="epsilon",
                    eval_targets=4, save_every=1000, output=str(tmp_path / "eps.pt"), log_dir=str(tmp_path / "tb"))
    )  # fmt: skip
    payload = read_checkpoint(teacher_path)
    teacher = ikdp.load(teacher_path).model
    student = student_network(payload, str(teacher_path), dls_skip=False, prediction="sample")
    assert teacher.config.prediction == "epsilon" and student.config.prediction == "sample"
    weights = student.state_dict()
    assert all(torch.equal(weights[name], value) for name, value in teacher.state_dict().items())
    noise = torch.randn((4, student.representation.dim), generator=torch.Generator().manual_seed(1))
    targets = torch.tensor([[1.0, 0.5], [0.0, -2.0], [1.5, 1.5], [-2.0, 0.0]])
    with torch.no_grad():
        pose = unrolled_student(student, student_sampler(student, DistillConfig(student_steps=1)), noise, targets)
        output = student.denoiser(noise, torch.full((4,), 19), targets)
    torch.testing.assert_close(pose, student.representation.project(output))  # x̂0 is the output, not eps's formula
    config = small_config(tmp_path, teacher_path, student_steps=1, student_prediction="sample", steps=2)
    solver = ikdp.load(distill(config))
    assert solver.model.config.prediction == "sample"
    assert solver.solve(targets, num_samples=2, sampler="ddim", steps=1).raw_angles.shape == (4, 2, 3)


def test_a_posterior_pool_from_a_prior_that_never_lands_near_its_own_tips_stops_with_an_error(tiny_checkpoint):
    import ikdp.posterior_pool as posterior

    solver = ikdp.load(tiny_checkpoint)
    arm, model = solver.model.arm, solver.model

    class Scattered:  # each draw far from the last: no pose lands near another's tip
        def sample(self, count, arm, generator):
            return torch.rand((count, arm.num_joints), generator=generator) * 1e-9 + torch.rand(1, generator=generator)

    with pytest.raises(ValueError, match="targets from the prior got 4 poses in"):
        posterior.posterior_pool(Scattered(), arm, model.representation, 3, 4, torch.Generator().manual_seed(0))
