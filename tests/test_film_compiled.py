"""The compiled FiLM step (film_kernel.c): the torch path's numbers to float rounding, and a quiet fallback."""

import os
import subprocess
import sys

import pytest
import torch

import ikdp
from ikdp.denoisers import DenoiserConfig, film_compiled
from ikdp.denoisers.film import FiLMWorkspace
from ikdp.denoisers.film_compiled import CompiledFiLMWorkspace, load_kernel
from ikdp.model import IKDiffusion, ModelConfig


@pytest.fixture(scope="module")
def kernel():
    library = load_kernel()
    if library is None:
        if os.environ.get("CI"):  # CI installs a C compiler: there the fast path must build
            pytest.fail("the compiled FiLM kernel did not build (is a C compiler installed?)")
        pytest.skip("no C compiler here")
    return library


def random_model(lengths, hidden, blocks, kinematic_until=0):
    torch.manual_seed(0)
    config = ModelConfig(
        lengths=lengths, denoiser=DenoiserConfig(hidden=hidden, blocks=blocks, kinematic_until=kinematic_until)
    )
    model = IKDiffusion(config)
    # the output layer starts at zero: give it a say; biases too. Weights of a trained model's scale
    # (1 / sqrt(fan-in)) keep the turn angles moderate, where float rounding is what it is in training
    for parameter in model.denoiser.parameters():
        fan_in = parameter.shape[1] if parameter.dim() == 2 else 16
        torch.nn.init.normal_(parameter, std=1 / fan_in**0.5)
    return model.eval()


@pytest.mark.parametrize(
    ("lengths", "hidden", "blocks", "rows", "kinematic_until"),
    [
        ((1.0, 1.0, 1.0, 1.0), 128, 3, 16, 0),  # the shipped shape: 4-row tiles, 16-wide register blocks
        ((1.0, 0.5, 2.0), 32, 2, 7, 30),  # rows left over after the tiles; features switched off at t >= 30
        ((0.7, 1.3), 24, 1, 5, 0),  # a width that is no multiple of 16: the plain loops
        ((1.0,) * 8, 64, 4, 33, 0),
    ],
)
@pytest.mark.parametrize("per_row_condition", [False, True])
def test_compiled_step_matches_the_torch_step(
    kernel, lengths, hidden, blocks, rows, kinematic_until, per_row_condition
):
    model = random_model(lengths, hidden, blocks, kinematic_until)
    generator = torch.Generator().manual_seed(1)
    with torch.inference_mode():
        x = torch.randn((rows, 2 * len(lengths)), generator=generator)
        targets = torch.randn((rows, 2), generator=generator)
        t = torch.randint(model.schedule.num_timesteps, (rows if per_row_condition else 1,), generator=generator)
        film = model.denoiser.condition(t, targets[: len(t)])
        compiled = model.denoiser.workspace(rows, x)
        assert isinstance(compiled, CompiledFiLMWorkspace)
        expected = model.denoiser.denoise(x, targets, film)
        for _ in range(2):  # a reused workspace gives the same answer again
            result = model.denoiser.denoise(x, targets, film, workspace=compiled)
            torch.testing.assert_close(result, expected, atol=2e-5, rtol=1e-5)
        one_target = model.denoiser.denoise(x, targets[:1].expand(rows, -1), film, workspace=compiled)
        torch.testing.assert_close(
            one_target, model.denoiser.denoise(x, targets[:1].expand(rows, -1), film), atol=2e-5, rtol=1e-5
        )


@pytest.mark.parametrize(("targets_count", "samples"), [(5, 16), (11, 7), (1, 40)])
def test_per_target_conditions_read_as_if_each_row_had_its_copy(kernel, targets_count, samples):
    """K rows per target read their target's condition in place; groups straddle the kernel's 32-row chunks."""
    model = random_model((1.0, 1.0, 1.0, 1.0), 128, 3)
    generator = torch.Generator().manual_seed(2)
    rows = targets_count * samples
    with torch.inference_mode():
        x = torch.randn((rows, 8), generator=generator)
        targets = torch.randn((targets_count, 2), generator=generator)
        t = torch.randint(model.schedule.num_timesteps, (targets_count,), generator=generator)
        film = model.denoiser.condition(t, targets)
        compiled = model.denoiser.workspace(rows, x)
        per_target = model.denoiser.denoise(x, targets, film, workspace=compiled).clone()
        copied = model.denoiser.denoise(
            x, targets.repeat_interleave(samples, dim=0), film.repeat_interleave(samples, dim=0), workspace=compiled
        )
        torch.testing.assert_close(per_target, copied, atol=0, rtol=0)
        with pytest.raises(ValueError, match="cannot share"):
            model.denoiser.denoise(x, x.new_zeros((3, 2)), film[:1].expand(2, *film.shape[1:]), workspace=compiled)


def test_a_batch_solve_gives_the_torch_paths_samples(kernel, monkeypatch):
    """The sampling loop hands the kernel per-target conditions; torch's path gets per-row copies: same poses."""
    solver = ikdp.load("ikdp_n4")
    targets = torch.tensor([[1.0, 1.5], [-2.0, 0.3], [0.5, -2.5]])
    options = {"num_samples": 20, "sampler": "ddim", "steps": 10}
    compiled = solver.solve(targets, generator=torch.Generator().manual_seed(0), **options)
    monkeypatch.setattr("ikdp.denoisers.film.compiled_workspace", lambda *args: None)
    plain = solver.solve(targets, generator=torch.Generator().manual_seed(0), **options)
    torch.testing.assert_close(compiled.angles, plain.angles, atol=1e-3, rtol=0)


def test_a_shipped_solve_is_the_same_through_either_path(kernel, monkeypatch):
    solver = ikdp.load("ikdp_n4")
    targets = torch.tensor([[1.0, 1.5], [-2.0, 0.3]])
    compiled = solver.solve(targets, num_samples=16, generator=torch.Generator().manual_seed(0))
    monkeypatch.setattr("ikdp.denoisers.film.compiled_workspace", lambda *args: None)
    plain = solver.solve(targets, num_samples=16, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(compiled.angles, plain.angles, atol=1e-3, rtol=0)
    assert compiled.tip_error.median() < 0.02


def test_the_library_is_built_once_and_reused(kernel, tmp_path, monkeypatch):
    monkeypatch.setenv("IKDP_CACHE", str(tmp_path))
    compiler = film_compiled._compiler()
    first = film_compiled._build(compiler)
    built_at = first.stat().st_mtime_ns
    assert film_compiled._build(compiler) == first and first.stat().st_mtime_ns == built_at
    assert [path.name for path in tmp_path.iterdir()] == [first.name]  # no temporary left beside it


@pytest.mark.parametrize(
    "environment",
    [{"IKDP_COMPILED": "0"}, {"CC": "/bin/false", "IKDP_CACHE": "{tmp}"}],
    ids=["switched off", "compiler fails"],
)
def test_without_the_kernel_the_torch_path_runs(environment, tmp_path):
    environment = {name: value.format(tmp=tmp_path) for name, value in environment.items()}
    script = (
        "import torch, ikdp\n"
        "from ikdp.denoisers.film import FiLMWorkspace\n"
        "solver = ikdp.load('ikdp_n4')\n"
        "with torch.no_grad():\n"
        "    assert type(solver.model.denoiser.workspace(16, torch.zeros(16, 8))) is FiLMWorkspace\n"
        "result = solver.solve(torch.tensor([[1.0, 1.5]]), num_samples=4)\n"
        "assert result.tip_error.median() < 0.05\n"
    )
    completed = subprocess.run(
        [sys.executable, "-c", script], env={**os.environ, **environment}, capture_output=True, text=True
    )
    assert completed.returncode == 0, completed.stderr
    assert completed.stderr == ""  # quietly: no warning, no compiler output


def test_gpu_or_float64_tensors_keep_the_torch_workspace(kernel):
    model = random_model((1.0, 1.0), 16, 1)
    with torch.no_grad():
        assert isinstance(model.denoiser.workspace(4, torch.zeros(4, 4, dtype=torch.float64)), FiLMWorkspace)
