"""One call of the planar FiLM denoiser: the compiled C kernel against torch eager and torch.compile.

    OMP_NUM_THREADS=1 python -m benchmarks.film_step

The question it answers: does the C kernel (ikdp/denoisers/film_kernel.c) earn its place, or does
torch's own compiled path come within 20 % of it? Timed at the two sizes a solve uses: K = 16
rows (one target, the viewer's drag; a solve makes 80 such calls) and 1000 targets x 16 rows
(a batch solve). One torch thread; the model `ikdp_n4`; the K rows of a target share its condition.

Rows, all on the same inputs:
- C kernel, this CPU: the build ikdp loads (-march=native), reading one condition per target;
- C kernel, default target: the build a CPU without AVX gets (-march=x86-64 on x86; the compiler's
  default elsewhere);
- torch workspace: the fallback (out= ops into buffers made once per solve);
- torch eager: `FiLMDenoiser.denoise` as training runs it (every op allocates);
- torch.compile: inductor on the same arithmetic written without complex numbers (inductor does not
  generate code for them and falls back op by op), once with its Python wrapper and once with
  `cpp_wrapper` (the call's glue in C++ too); the first call's seconds include the compile (less when
  inductor's cache on disk holds the graph from an earlier run).
Every method is timed once per round, round-robin, so a busy machine slows all alike; the table
gives the median over rounds of the mean call in a round, and each row's ratio to the native C kernel.
Writes benchmarks/results/film_step.json.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import torch
import torch._inductor.config as inductor_config
import tyro
from torch import nn

import ikdp
from ikdp.denoisers import film_compiled
from ikdp.evaluation.machine import cpu_model

REPO_ROOT = Path(__file__).resolve().parents[1]
KEEP_C_ABOVE = 1.2  # the C kernel stays only when the fastest torch path takes more than this times its time


@dataclass(frozen=True)
class FilmStepConfig:
    model: str = "ikdp_n4"  # a shipped planar FiLM model or a checkpoint path
    samples: int = 16  # K: rows per target
    batch: int = 1000  # targets in the batch case
    rounds: int = 15  # round-robin rounds (median quoted)
    calls: tuple[int, int] = (200, 2)  # calls per round at one target and at the batch
    compile: bool = True  # also time torch.compile (a minute or two of compiling on a shared CPU)
    output: str = "benchmarks/results/film_step.json"


def real_arithmetic_denoise(denoiser, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
    """`FiLMDenoiser.denoise` (cossin) with the turn as cos/sin products instead of complex ones, for inductor."""
    rows = x.shape[0]
    unit = nn.functional.normalize(x.view(rows, -1, 2), dim=-1)
    bones = unit * denoiser.lengths[:, None]
    miss = target - bones.sum(dim=-2)
    bones_x, bones_y = bones.unbind(-1)
    xx = (bones_x * bones_x).sum(-1) + denoiser.damping_squared
    yy = (bones_y * bones_y).sum(-1) + denoiser.damping_squared
    xy = (bones_x * bones_y).sum(-1)
    determinant = xx * yy - xy * xy
    solved_x = (xx * miss[:, 0] + xy * miss[:, 1]) / determinant
    solved_y = (xy * miss[:, 0] + yy * miss[:, 1]) / determinant
    step = -bones_y * solved_x[:, None] + bones_x * solved_y[:, None]
    features = torch.cat((x, miss, step), dim=-1) * film[:, -1, 0, : denoiser.input.in_features]
    h = denoiser.input(features)
    for index, block in enumerate(denoiser.blocks):
        h = h + block(nn.functional.silu(torch.addcmul(film[:, index, 1], h, film[:, index, 0])))
    turn = denoiser.output(nn.functional.silu(h))
    cos, sin = turn.cos(), turn.sin()
    unit_x, unit_y = unit.unbind(-1)
    return torch.stack((unit_x * cos - unit_y * sin, unit_x * sin + unit_y * cos), dim=-1).view(rows, -1)


# Two entry points, not one called twice: dynamo keeps its compiled graphs per function, and the second
# torch.compile of one function would run the first one's graph whatever inductor's settings
def compiled_python_wrapper(denoiser, x, target, film):
    return real_arithmetic_denoise(denoiser, x, target, film)


def compiled_cpp_wrapper(denoiser, x, target, film):
    return real_arithmetic_denoise(denoiser, x, target, film)


# name -> (entry point, inductor's cpp_wrapper: the glue around the kernels in C++ too, not Python)
COMPILED = {
    "torch.compile": (compiled_python_wrapper, False),
    "torch.compile, cpp_wrapper": (compiled_cpp_wrapper, True),
}


def portable_flags() -> tuple[str, ...]:
    return ("-march=x86-64",) if platform.machine().lower() in ("x86_64", "amd64") else ()


def methods_for(denoiser, rows: int, targets: torch.Tensor, film: torch.Tensor, x: torch.Tensor, config, compiled):
    """name -> a call of one denoiser step on these rows (per-target conditions for the kernel, per-row for torch)."""
    row_targets = targets.repeat_interleave(config.samples, dim=0)
    row_film = film.repeat_interleave(config.samples, dim=0)
    methods = {}
    library = film_compiled.load_kernel()
    if library is not None:
        native = film_compiled.CompiledFiLMWorkspace(denoiser, rows, library)
        methods["C kernel, this CPU (-march=native)"] = lambda: native.denoise(x, targets, film)
        compiler = film_compiled.find_compiler()
        portable_library = film_compiled.open_library(film_compiled.build(compiler, portable_flags()))
        portable = film_compiled.CompiledFiLMWorkspace(denoiser, rows, portable_library)
        label = " ".join(portable_flags()) or "default target"
        methods[f"C kernel, no AVX ({label})"] = lambda: portable.denoise(x, targets, film)
    workspace = denoiser.workspace(rows, x, compiled=False)
    methods["torch workspace (the fallback)"] = lambda: denoiser.denoise(x, row_targets, row_film, workspace=workspace)
    methods["torch eager (plain denoise)"] = lambda: denoiser.denoise(x, row_targets, row_film)
    for name, function in compiled.items():
        methods[name] = lambda function=function: function(denoiser, x, row_targets, row_film)
    return methods, (x, row_targets, row_film)


def time_round_robin(methods: dict, rounds: int, calls: int) -> dict[str, float]:
    """name -> median over rounds of the mean seconds per call."""
    for function in methods.values():  # warm-up (and torch.compile's first compile for this shape)
        function()
    seconds = {name: [] for name in methods}
    for _ in range(rounds):
        for name, function in methods.items():
            started = time.perf_counter()
            for _ in range(calls):
                function()
            seconds[name].append((time.perf_counter() - started) / calls)
    return {name: statistics.median(values) for name, values in seconds.items()}


def main(config: FilmStepConfig) -> None:
    torch.set_num_threads(1)
    denoiser = ikdp.load(config.model).model.denoiser
    compiled = {}
    if config.compile:  # inductor compiles on the first call of each shape
        compiled = {name: torch.compile(entry, dynamic=False) for name, (entry, _) in COMPILED.items()}

    cases = [("one target", 1, config.calls[0]), (f"{config.batch} targets", config.batch, config.calls[1])]
    results = []
    print(f"FiLM denoiser step, model {config.model}, K = {config.samples}, one torch thread, {cpu_model()}")
    capability = torch.backends.cpu.get_cpu_capability()
    print(f"torch {torch.__version__} ({capability}), load average {os.getloadavg()[0]:.1f} at the start\n")
    for case, batch, calls in cases:
        rows = batch * config.samples
        generator = torch.Generator().manual_seed(0)
        with torch.inference_mode():
            x = torch.randn((rows, denoiser.representation.dim), generator=generator)
            targets = torch.randn((batch, 2), generator=generator)
            film = denoiser.condition(torch.randint(100, (batch,), generator=generator), targets)
            methods, row_inputs = methods_for(denoiser, rows, targets, film, x, config, compiled)
            expected = denoiser.denoise(*row_inputs).clone()
            differences, first_call = {}, {}
            for name, function in methods.items():
                started = time.perf_counter()
                with inductor_config.patch(cpp_wrapper=COMPILED.get(name, (None, False))[1]):  # inductor compiles here
                    result = function()
                first_call[name] = time.perf_counter() - started
                differences[name] = float((result - expected).abs().max())
            timings = time_round_robin(methods, config.rounds, calls)
        reference = next(iter(timings.values()))
        print(f"### {case}: {rows} rows, median of {config.rounds} rounds of {calls} calls")
        print("| method | median us per call | x C kernel | max difference from eager | first call s |")
        print("|---|---:|---:|---:|---:|")
        for name, seconds in timings.items():
            row = {
                "case": case,
                "rows": rows,
                "method": name,
                "median_us": round(1e6 * seconds, 1),
                "ratio_to_c": round(seconds / reference, 2),
                "max_difference": differences[name],
                "first_call_s": round(first_call[name], 2),
            }
            results.append(row)
            print(
                f"| {name} | {row['median_us']:,.1f} | {row['ratio_to_c']:.2f} | {row['max_difference']:.1e} | "
                f"{row['first_call_s']:.2f} |"
            )
        print()

    decision = decide(results)
    print(decision)
    output = REPO_ROOT / config.output
    output.parent.mkdir(parents=True, exist_ok=True)
    document = {
        "command": "OMP_NUM_THREADS=1 python -m benchmarks.film_step",
        "model": config.model,
        "samples": config.samples,
        "batch": config.batch,
        "rounds": config.rounds,
        "calls": list(config.calls),
        "threads": 1,
        "cpu": cpu_model(),
        "machine": platform.machine(),
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),  # the widest vectors torch's kernels use here
        "torch": str(torch.__version__),
        "load_average_1min": os.getloadavg()[0],  # the machine is shared: a busy one slows every row
        "date": time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime()),
        "rows": results,
        "decision": decision,
    }
    output.write_text(json.dumps(document, indent=2) + "\n")
    print(f"wrote {output}")


def decide(results: list[dict]) -> str:
    """Keep the C kernel only where torch's fastest path (eager or compiled) is more than 20 % slower at one target."""
    one_target = [row for row in results if row["case"] == "one target"]
    if not one_target[0]["method"].startswith("C kernel"):
        return "no C kernel here: nothing to decide"
    fastest = min((row for row in one_target if row["method"].startswith("torch")), key=lambda row: row["ratio_to_c"])
    verdict = "keep the C kernel" if fastest["ratio_to_c"] > KEEP_C_ABOVE else "drop the C kernel for torch"
    ratio = fastest["ratio_to_c"]
    return f"{verdict}: torch's fastest path at one target, {fastest['method']}, takes {ratio:.2f} x its time"


if __name__ == "__main__":
    main(tyro.cli(FilmStepConfig, description=__doc__.splitlines()[0]))
