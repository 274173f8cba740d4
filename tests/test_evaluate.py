"""The quick evaluation run end to end, into a temporary folder."""

from __future__ import annotations

import json

import pytest

from ikdp.evaluate import EvaluateConfig, evaluate, main

FIGURES = ("reverse_process", "forward_noising", "training_curves", "tip_error_cdf", "solution_fans")


@pytest.mark.slow
def test_quick_run_writes_every_table_and_figure(tmp_path):
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
    closed_form = saved["arms"]["2"]["methods"]["Closed form (exact)"]
    assert closed_form["fk_uniform"]["target_distance"]["success@0.001"] == 1.0
    assert closed_form["diversity"]["both_elbows_share"] == 1.0
    for prior in ("uniform", "relaxed"):
        entry = saved["fidelity"][prior]
        assert entry["targets"] > 0 and entry["noise_floor"]["mmd2"] > 0
    assert results["wall_seconds"] < 120
    # a second run reuses the cache instead of training again
    cached = sorted(path.name for path in cache.glob("*.pt"))
    main(
        [
            "--quick",
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
    assert sorted(path.name for path in cache.glob("*.pt")) == cached


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
