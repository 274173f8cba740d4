"""The compiled FiLM step (film_kernel.c): the torch path's numbers to float rounding, on any build, and a fallback
that says once why it runs torch."""

import json
import os
import platform
import re
import subprocess
import sys

import pytest
import torch

import ikdp
from ikdp.denoisers import DenoiserConfig, film_compiled
from ikdp.denoisers.film import FiLMWorkspace
from ikdp.denoisers.film_compiled import CompiledFiLMWorkspace, load_kernel, open_library
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
    compiler = film_compiled.find_compiler()
    first = film_compiled.build_for_this_cpu(compiler)
    built_at = first.stat().st_mtime_ns
    assert film_compiled.build_for_this_cpu(compiler) == first and first.stat().st_mtime_ns == built_at
    assert [path.name for path in tmp_path.iterdir()] == [first.name]  # no temporary left beside it


# the builds a CPU without AVX, or a compiler without GCC's vector types, gets: the same numbers
PORTABLE_BUILDS = {
    "default target": ("-march=x86-64",) if platform.machine().lower() in ("x86_64", "amd64") else (),
    "plain C": ("-DIKDP_PLAIN_C",),
}


@pytest.mark.parametrize("flags", PORTABLE_BUILDS.values(), ids=PORTABLE_BUILDS.keys())
def test_a_portable_build_matches_the_torch_step(kernel, flags, tmp_path, monkeypatch):
    compiler = film_compiled.find_compiler()
    if film_compiled.is_msvc(compiler):
        pytest.skip("these flags are GCC's and Clang's")
    monkeypatch.setenv("IKDP_CACHE", str(tmp_path))
    library = open_library(film_compiled.build(compiler, flags))
    model = random_model((1.0, 1.0, 1.0, 1.0), 128, 3)
    generator = torch.Generator().manual_seed(3)
    rows, targets_count = 48, 3  # full 4-row tiles and a chunk and a half
    with torch.inference_mode():
        x = torch.randn((rows, 8), generator=generator)
        targets = torch.randn((targets_count, 2), generator=generator)
        film = model.denoiser.condition(torch.randint(100, (targets_count,), generator=generator), targets)
        portable = CompiledFiLMWorkspace(model.denoiser, rows, library)
        result = model.denoiser.denoise(x, targets, film, workspace=portable)
        expected = model.denoiser.denoise(x, targets.repeat_interleave(16, dim=0), film.repeat_interleave(16, dim=0))
    torch.testing.assert_close(result, expected, atol=2e-5, rtol=1e-5)


# what a caller may get wrong, as arguments built from good ones (x (16, 8), targets (1, 2), film (1, 4, 2, 128))
BAD_INPUTS = {
    "x with other rows": (lambda x, t, f: (x[:-1], t, f), r"x must have shape \(16, 8\), got \(15, 8\)"),
    "x of another width": (lambda x, t, f: (x[:, :6], t, f), r"x must have shape \(16, 8\), got \(16, 6\)"),
    "x in float64": (lambda x, t, f: (x.double(), t, f), "x must be float32 on the CPU, got torch.float64"),
    "x as one row": (lambda x, t, f: (x.reshape(-1), t, f), r"x must have shape \(16, 8\), got \(128,\)"),
    "a target of one number": (lambda x, t, f: (x, t[:, :1], f), r"target must have shape \(B, 2\), got \(1, 1\)"),
    "no targets": (lambda x, t, f: (x, t[:0], f), r"target must have shape \(B, 2\), got \(0, 2\)"),
    "film of another model": (lambda x, t, f: (x, t, f[..., :64]), r"film must have shape \(B, 4, 2, 128\), got"),
    "film in float16": (lambda x, t, f: (x, t, f.half()), "film must be float32 on the CPU, got torch.float16"),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_the_kernel_refuses_what_its_buffers_were_not_sized_for(kernel, case):
    """A ValueError in one line before the pointer call: a wrong width or row count would read past a buffer."""
    model = random_model((1.0, 1.0, 1.0, 1.0), 128, 3)
    arguments, message = BAD_INPUTS[case]
    with torch.inference_mode():
        x, targets = torch.randn((16, 8)), torch.randn((1, 2))
        film = model.denoiser.condition(torch.tensor([5]), targets)
        workspace = model.denoiser.workspace(16, x)
        assert isinstance(workspace, CompiledFiLMWorkspace)
        with pytest.raises(ValueError, match=message) as raised:
            model.denoiser.denoise(*arguments(x, targets, film), workspace=workspace)
    assert "\n" not in str(raised.value)


FALLBACK_SCRIPT = """
import json, logging, torch, ikdp
logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
solver = ikdp.load("ikdp_n4")
targets = torch.tensor([[1.0, 1.5], [-2.0, 0.3]])
first = solver.solve(targets, num_samples=16, generator=torch.Generator().manual_seed(0))
again = solver.solve(targets, num_samples=16, generator=torch.Generator().manual_seed(0))
assert torch.equal(first.angles, again.angles)
print(json.dumps(first.angles.tolist()))
"""


@pytest.mark.parametrize(
    ("environment", "reason"),
    [
        ({"IKDP_COMPILED": "0"}, "INFO .*IKDP_COMPILED=0"),
        ({"CC": "/nonexistent/cc"}, "WARNING .*CC='/nonexistent/cc' is not on the PATH"),
        ({"CC": "/bin/false"}, "WARNING .*/bin/false could not build film_kernel.c"),
    ],
    ids=["switched off", "no compiler", "compiler fails"],
)
def test_the_forced_fallback_solves_as_the_kernel_and_says_why_once(kernel, environment, reason, tmp_path):
    environment = {**os.environ, **environment, "IKDP_CACHE": str(tmp_path)}  # an empty cache: nothing built
    completed = subprocess.run(
        [sys.executable, "-c", FALLBACK_SCRIPT], env=environment, capture_output=True, text=True, timeout=300
    )
    assert completed.returncode == 0, completed.stderr
    said = [line for line in completed.stderr.splitlines() if "runs in torch" in line]
    assert len(said) == 1, completed.stderr  # two solves, two workspaces: one line
    assert re.match(reason, said[0]), said[0]
    solver = ikdp.load("ikdp_n4")
    targets = torch.tensor([[1.0, 1.5], [-2.0, 0.3]])
    compiled = solver.solve(targets, num_samples=16, generator=torch.Generator().manual_seed(0))
    torch_path = torch.tensor(json.loads(completed.stdout))
    torch.testing.assert_close(torch_path, compiled.angles, atol=1e-3, rtol=0)


def test_gpu_or_float64_tensors_keep_the_torch_workspace(kernel):
    model = random_model((1.0, 1.0), 16, 1)
    with torch.no_grad():
        assert isinstance(model.denoiser.workspace(4, torch.zeros(4, 4, dtype=torch.float64)), FiLMWorkspace)
