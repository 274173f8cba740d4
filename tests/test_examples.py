"""The numbered examples in docs/examples run as a user runs them, and make what they say they make."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from importlib import metadata

import pytest
import torch
from test_viz_cli import REPO, with_repo_on_path

EXAMPLES = REPO / "docs" / "examples"
SCRIPTS = sorted(EXAMPLES.glob("[0-9][0-9]_*.py"))
MAX_LINES = 60  # an example is short enough to read at a glance and copy whole
PUBLIC_MODULES = {"ikdp", "ikdp_viz.record"}  # what an example may import of the project


def run_example(name: str, *arguments: str, timeout: float = 300) -> str:
    """Run docs/examples/`name` with `arguments` from the repository root; its stdout, after it exits 0."""
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *arguments],
        cwd=REPO,
        env={**with_repo_on_path(), "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    return result.stdout


def test_there_are_six_numbered_examples_each_short_with_a_docstring_and_a_typed_main():
    assert len(SCRIPTS) >= 6
    numbers = [script.name[:2] for script in SCRIPTS]
    assert len(set(numbers)) == len(numbers), numbers
    for script in SCRIPTS:
        text = script.read_text(encoding="utf-8")
        assert len(text.splitlines()) <= MAX_LINES, script.name
        tree = ast.parse(text)
        docstring = ast.get_docstring(tree)
        assert docstring and f"python docs/examples/{script.name}" in docstring, script.name  # how to run it
        mains = [node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "main"]
        assert mains and all(argument.annotation is not None for argument in mains[0].args.args), script.name


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda script: script.name)
def test_an_example_imports_only_the_public_api(script):
    tree = ast.parse(script.read_text(encoding="utf-8"))
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
    project = {name for name in imported if name.split(".")[0] in ("ikdp", "ikdp_viz")}
    assert project <= PUBLIC_MODULES, project - PUBLIC_MODULES


@pytest.mark.slow
def test_the_planar_example_plots_poses_that_reach_the_target(tmp_path):
    import matplotlib.image

    output = tmp_path / "poses.png"
    printed = run_example("01_solve_planar.py", "--output", str(output), "--num-samples", "8")
    median, largest = map(float, re.search(r"8 poses, tip error median (\S+), largest (\S+) ", printed).groups())
    assert largest < 1e-3  # every refined pose on the target, to a thousandth of a bone
    image = matplotlib.image.imread(output)
    assert image.ndim == 3 and image.shape[0] > 200 and image.shape[1] > 200
    assert image[..., :3].std() > 0.05  # something drawn, not a blank canvas


@pytest.mark.slow
def test_the_panda_example_reaches_around_the_sphere():
    printed = run_example("02_panda_obstacle.py", "--num-samples", "8")
    both = int(re.search(r"(\d+) of 8 poses reach the target and clear the sphere", printed).group(1))
    clear = int(re.search(r"(\d+) of 8 poses clear the sphere", printed).group(1))
    assert 0 < both <= clear
    assert re.search(r"one of them \(radians\): \[([+-]\d\.\d{3}, ){6}[+-]\d\.\d{3}\]", printed)  # 7 joints


@pytest.mark.slow
def test_the_tracking_example_follows_the_circle_without_a_jump():
    printed = run_example("03_track_path.py", "--points", "12")
    assert len(re.findall(r"^step +\d+: tip error", printed, flags=re.MULTILINE)) == 12
    reached, largest = re.search(r"reached (\d+) of 12 targets; largest joint step (\S+) rad", printed).groups()
    assert int(reached) == 12
    assert float(largest) < 1.0  # a change of branch would jump several radians
    assert "branch switches: none" in printed


@pytest.mark.slow
def test_the_training_example_trains_on_the_ur5_and_solves_with_it(tmp_path):
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("the UR5's URDF comes from example-robot-data (pip install 'ikdp[robots]')")
    import ikdp

    output = tmp_path / "ur5.pt"
    printed = run_example("04_train_your_urdf.py", "--minutes", "0.2", "--output", str(output), timeout=600)
    assert printed.startswith("python -m ikdp.train --urdf ") and "--ee-link tool0 --minutes 0.2" in printed
    assert ikdp.load(output).arm.num_joints == 6
    assert re.search(r"after 5 refinement steps \d+ of 16 poses within 1 mm and 1 degree \(best \S+ mm", printed)


@pytest.mark.slow
def test_the_recording_example_writes_a_page_that_plays_offline(tmp_path):
    output = tmp_path / "denoising.html"
    printed = run_example("05_record_denoising_html.py", "--output", str(output), "--samples", "4", "--seconds", "1")
    assert "no server needed" in printed
    page = output.read_text(encoding="utf-8")
    assert page.lstrip().lower().startswith("<!doctype html")
    assert "window.__VISER_EMBED_DATA__=" in page  # viser's player with the recorded scene
    assert 'id="ikdp-legend"' in page
    assert not re.search(r'<script[^>]+src="http', page)  # nothing fetched from a network


def test_the_gpu_example_skips_in_one_line_without_cuda_and_reaches_with_it():
    printed = run_example("06_gpu_batch_capture.py", "--batch", "64")
    if not torch.cuda.is_available():
        assert printed.count("\n") == 1 and printed.startswith("skipped: no CUDA device")
        return
    reached = int(re.search(r"captured: (\d+) of 64 targets reached", printed).group(1))
    assert reached >= 60
    assert re.search(r"eager solve \S+ ms, captured replay \S+ ms per batch", printed)
