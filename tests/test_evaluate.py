"""The evaluation pipeline: cache keys, the stage driver, the CLI, and the quick run end to end."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from ikdp.arm import PlanarArm
from ikdp.evaluate import INDEPENDENT_STAGES, STAGES, EvaluateConfig, Run, evaluate, main, measure_in_parallel
from ikdp.evaluation.models import Sizes
from ikdp.evaluation.pool import single_threaded_pool
from ikdp.evaluation.training import baseline_job, ikdp_job, train_missing
from ikdp.priors import PosePrior

TINY = Sizes(
    joints=(2, 4),
    table2_timesteps=(40,),
    accuracy_targets=8,
    diversity_targets=2,
    diversity_samples=2,
    fidelity_targets=2,
    fidelity_samples=4,
    reference_radius=0.1,
    runtime_batch=4,
    runtime_repeats=(1, 1),
    variant_steps=2,
    variant_batch=8,
    baseline_steps=2,
    baseline_batch=8,
    standin_steps=2,
)
FIGURES = ("reverse_process", "forward_noising", "training_curves", "tip_error_cdf", "solution_fans")


def tiny_baseline(cache: Path, **changes):
    settings = dict(kind="mlp", prior=PosePrior("uniform"), arm=PlanarArm((1.0, 1.0)), steps=2, batch=8, seed=0)
    settings.update(changes)
    kind, prior, arm = settings.pop("kind"), settings.pop("prior"), settings.pop("arm")
    return baseline_job(kind, cache, prior, arm, **settings)


def test_a_changed_baseline_setting_misses_the_cache_and_an_unchanged_one_hits_it(tmp_path):
    job = tiny_baseline(tmp_path)
    assert train_missing([job], workers=1) == [job.output]
    assert train_missing([tiny_baseline(tmp_path)], workers=1) == []  # same settings: cached
    for changed in (
        tiny_baseline(tmp_path, seed=1),
        tiny_baseline(tmp_path, steps=3),
        tiny_baseline(tmp_path, arm=PlanarArm((1.0, 0.5))),
        tiny_baseline(tmp_path, prior=PosePrior("relaxed")),
        tiny_baseline(tmp_path, prior=PosePrior("relaxed", relaxed_std=0.3)),
        replace(job, model=replace(job.model, hidden=16)),
    ):
        assert changed.output != job.output
        assert train_missing([changed], workers=1) == [changed.output]
    assert len({path.name for path in tmp_path.glob("*.pt")}) == 7


def test_an_ikdp_job_is_keyed_by_what_shapes_the_model_not_where_it_trains(tmp_path):
    arguments = dict(label="paper", joints=4, timesteps=80, steps=100, batch=32, seed=0, settings={"denoiser": "paper"})
    job = ikdp_job(tmp_path, **arguments)
    assert ikdp_job(tmp_path, **arguments).output == job.output
    assert ikdp_job(tmp_path / "elsewhere", **arguments).output.name == job.output.name
    for how in ({"device": "cuda"}, {"graph": True}):  # how fast it trains: the cache still holds the same model
        assert ikdp_job(tmp_path, **{**arguments, "settings": {"denoiser": "paper", **how}}).output == job.output, how
    for change in ({"timesteps": 40}, {"seed": 1}, {"steps": 101}, {"prior": "relaxed"}, {"settings": {"lr": 3e-4}}):
        assert ikdp_job(tmp_path, **{**arguments, **change}).output != job.output, change


@pytest.mark.slow
def test_pool_workers_run_one_thread_each_and_the_parent_keeps_its_environment(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    with single_threaded_pool(2) as pool:
        threads = [pool.submit(torch.get_num_threads) for _ in range(2)]
        omp = pool.submit(os.getenv, "OMP_NUM_THREADS")
        assert [future.result() for future in threads] == [1, 1]
        assert omp.result() == "1"
    assert os.environ["OMP_NUM_THREADS"] == "2"
    with pytest.raises(ValueError, match="workers"), single_threaded_pool(0):
        pass


def test_help_lists_each_option_once_with_its_default(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for option in ("--quick", "--out-dir", "--cache-dir", "--checkpoints", "--seed", "--threads", "--only"):
        assert text.count(option) == 1, option
    assert text.count("(default:") == 7
    assert "--no-quick" not in text


def test_every_stage_needs_only_stages_before_it():
    names = list(STAGES)
    for position, stage in enumerate(STAGES.values()):
        assert all(names.index(need) < position for need in stage.needs), stage.name
    assert names[0] == "data" and names[-1] == "report"


@pytest.mark.slow
def test_quick_run_writes_every_table_and_figure_and_a_stage_alone_reproduces_its_part(tmp_path):
    out_dir, cache = tmp_path / "out", tmp_path / "cache"
    config = EvaluateConfig(
        quick=True, out_dir=str(out_dir), cache_dir=str(cache), checkpoints=str(tmp_path / "none"), threads=1
    )
    results = evaluate(config, ["--quick"])
    report = (out_dir / "RESULTS.md").read_text()
    for heading in (
        "## Table I",
        "## Table II",
        "## Table III",
        "## Accuracy",
        "## Diversity",
        "## Fidelity",
        "## Runtime",
    ):
        assert heading in report
    for name in FIGURES:
        png = out_dir / "figures" / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    saved = json.loads((out_dir / "results.json").read_text())
    assert set(saved["arms"]) == {"2", "4", "8"}
    assert set(saved["variants"]) == {"n2_T80", "n4_T40", "n4_T80", "n4_T100", "n8_T80"}
    assert set(saved["stage_seconds"]) == set(STAGES) - {"report"}
    closed_form = saved["arms"]["2"]["methods"]["Closed form (exact)"]
    assert closed_form["fk_uniform"]["target_distance"]["success@0.001"] == 1.0
    assert closed_form["diversity"]["both_elbows_share"] == 1.0
    methods = saved["arms"]["4"]["methods"]
    assert "diversity" in methods["IKDP ours, DDPM + DLS"] and "diversity" not in methods["IKDP ours, DDPM"]
    for prior in ("uniform", "relaxed"):
        entry = saved["fidelity"][prior]
        assert entry["targets"] > 0 and entry["noise_floor"]["mmd2"] > 0
    assert results["wall_seconds"] >= max(saved["stage_seconds"].values())

    # one stage alone: it reruns from the cached models and reproduces its part of the full run
    cached = sorted(path.name for path in cache.glob("*.pt"))
    alone = evaluate(replace(config, only="tables_1_2"), ["--quick", "--only", "tables_1_2"])
    assert alone["variants"] == saved["variants"]
    assert sorted(path.name for path in cache.glob("*.pt")) == cached  # nothing trained again

    # the report alone takes every measurement from the cache
    (out_dir / "results.json").unlink()
    main(
        [
            "--quick",
            "--only",
            "report",
            "--out-dir",
            str(out_dir),
            "--cache-dir",
            str(cache),
            "--checkpoints",
            str(tmp_path / "none"),
            "--threads",
            "1",
        ]
    )
    again = json.loads((out_dir / "results.json").read_text())
    for part in ("arms", "variants", "fidelity", "runtime", "figures"):
        assert again[part] == saved[part], part
    assert sorted(path.name for path in cache.glob("*.pt")) == cached


@pytest.mark.slow
def test_the_independent_stages_in_worker_processes_match_a_run_in_this_process(tmp_path):
    config = EvaluateConfig(
        quick=True, out_dir=str(tmp_path / "out"), cache_dir=str(tmp_path / "cache"), checkpoints=str(tmp_path / "none")
    )
    here = evaluate(replace(config, threads=1, only="tables_1_2"), [], sizes=TINY)  # trains, then one stage here
    run = Run(config, TINY, "test")
    run.workers = 2
    measure_in_parallel(run)
    assert set(run.results) == set(INDEPENDENT_STAGES)
    assert run.results["tables_1_2"].variants == here["variants"]
    assert set(run.results["accuracy"].arms) == {"2", "4"}


def test_missing_shipped_checkpoint_is_an_error_in_a_full_run(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(
            [
                "--out-dir",
                str(tmp_path / "out"),
                "--cache-dir",
                str(tmp_path / "cache"),
                "--checkpoints",
                str(tmp_path / "none"),
            ]
        )
    assert exit_info.value.code == 2
    assert "shipped checkpoint missing" in capsys.readouterr().err


@pytest.mark.parametrize(("absent", "only"), [("matplotlib", None), ("matplotlib", "figures"), ("tensorboard", None)])
def test_a_missing_extra_is_named_in_one_line_before_any_work(tmp_path, capsys, monkeypatch, absent, only):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *rest: None if name == absent else find_spec(name))
    argv = ["--quick", "--out-dir", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "cache")]
    with pytest.raises(SystemExit) as exit_info:
        main(argv + (["--only", only] if only else []))
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip()
    assert error == f"error: {absent} not installed: pip install 'ikdp[eval]'"
    assert not (tmp_path / "out").exists() and not (tmp_path / "cache").exists()  # nothing was started
