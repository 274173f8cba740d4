"""The viewer's command line, run as a user runs it: a subprocess."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import torch

REPO = Path(__file__).resolve().parent.parent


def with_repo_on_path() -> dict[str, str]:
    """This process's environment with the repository first on PYTHONPATH: a viewer started from another folder
    still imports this checkout."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}


def run_cli(*arguments: str, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "ikdp_viz", *arguments], cwd=cwd, capture_output=True, text=True, timeout=120
    )


@pytest.fixture
def bad_checkpoints(tmp_path):
    text = tmp_path / "notes.pt"
    text.write_text("hello")
    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    return {"missing": (tmp_path / "absent.pt", "no such file"), "text": (text, "not an IKDP checkpoint"),
            "foreign": (foreign, "not an IKDP checkpoint"), "folder": (tmp_path, "not a file")}  # fmt: skip


@pytest.mark.parametrize("case", ["missing", "text", "foreign", "folder"])
def test_a_bad_checkpoint_is_one_line_and_exit_status_2(bad_checkpoints, case):
    path, reason = bad_checkpoints[case]
    result = run_cli("--ckpt", str(path), "--port", "0")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("ikdp-viz: error: ") and str(path) in lines[0] and reason in lines[0]
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_an_unknown_device_is_one_line_and_exit_status_2(tiny_checkpoint):
    result = run_cli("--ckpt", str(tiny_checkpoint), "--device", "nonsense")
    assert result.returncode == 2
    assert result.stderr.strip().startswith("ikdp-viz: error: --device nonsense:")
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_a_tree_target_of_too_few_numbers_is_one_line_naming_how_many_it_takes():
    # the shipped G1 model: two hands, a target of 14 numbers (every hand's position, then every hand's w x y z)
    result = run_cli("--ckpt", "ikdp_g1", "--port", "0", "--target", "0.3", "0.2", "0.1")
    assert result.returncode == 2 and "Traceback" not in result.stderr and "open http" not in result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("ikdp-viz: error: --target 0.3 0.2 0.1: ")
    assert "14 numbers" in lines[0] and "got 3 numbers" in lines[0]


def test_help_lists_every_option_once_with_its_one_default():
    result = run_cli("--help")
    assert result.returncode == 0
    text = " ".join(result.stdout.replace("│", " ").split())  # the help box wraps lines
    options = (("--ckpt", "ikdp_n4"), ("--host", "127.0.0.1"), ("--port", "8080"), ("--device", "cpu"),
               ("--target", "None"), ("--samples", "16"), ("--sampler", "None"), ("--seed", "0"))  # fmt: skip
    for option, default in options:
        assert text.count(f"{option} ") == 1, text  # listed once
        entry = text.split(f"{option} ")[1].split(" --")[0]
        assert entry.count("(default:") == 1 and f"(default: {default})" in entry, entry
    assert "(default: )" not in text


@pytest.mark.parametrize(
    "arguments, reason",
    [
        (("--port", "-5"), "--port -5: expected a port from 0 to 65535"),
        (("--port", "70000"), "--port 70000: expected a port from 0 to 65535"),
        (("--host", "10.254.254.254", "--port", "0"), "--host 10.254.254.254: cannot listen there"),
        (("--host", "no.such.host.invalid", "--port", "0"), "--host no.such.host.invalid: cannot listen there"),
        (("--sampler", "euler"), "--sampler euler: expected one of ddpm, ddim, dpmpp2m"),
        (("--samples", "0"), "--samples 0: expected 1 to 64"),
        (("--target", "1", "2", "3"), "--target 1 2 3: target: a planar arm's target is x y, got 3 numbers"),
    ],
)
def test_a_bad_port_or_host_is_one_line_and_exit_status_2(arguments, reason):
    result = run_cli(*arguments)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert lines == [lines[0]] and lines[0].startswith(f"ikdp-viz: error: {reason}"), result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_default_model_a_taken_port_and_ctrl_c_even_started_with_sigint_ignored(tmp_path):
    """From another folder, with no --ckpt: the shipped model loads, the next port is used, Ctrl-C exits cleanly."""
    from ikdp.shipped import DEFAULT_MODEL, list_shipped

    if DEFAULT_MODEL not in {path.stem for path in list_shipped()}:
        pytest.skip(f"the shipped {DEFAULT_MODEL} is not there")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        process = subprocess.Popen(
            [sys.executable, "-m", "ikdp_viz", "--port", str(port)],
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=with_repo_on_path(),
            # as `nohup ... &` or a CI runner starts it: SIGINT ignored, so Python installs no Ctrl-C handler of
            # its own (without it the viewer ran on through Ctrl-C); main() installs one
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
        )
        try:
            first = process.stdout.readline()
            second = process.stdout.readline()
            match = re.fullmatch(r"ikdp-viz: open http://127\.0\.0\.1:(\d+)\n", first)
            assert match, first + second + (process.stderr.read() if process.poll() is not None else "")
            used = int(match.group(1))
            assert used != port and f"port {port} was taken, using {used}" in second
            assert str(Path("checkpoints") / "ikdp_n4.pt") in second and "N=4" in second
            assert f"http://127.0.0.1:{used}/?fixedDpr=0.5" in process.stdout.readline()  # the slow-page hint
            with urllib.request.urlopen(f"http://127.0.0.1:{used}", timeout=30) as response:
                assert response.status == 200 and b"<html" in response.read(2000).lower()
            process.send_signal(signal.SIGINT)
            stdout, stderr = process.communicate(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
    assert process.returncode == 0, stderr
    assert "Traceback" not in stderr and "ikdp-viz: stopped" in stderr


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux's /proc to name a thread")
def test_ctrl_c_landing_on_another_thread_still_stops_the_viewer(tiny_checkpoint):
    """A process's signal goes to any of its threads; the C handler then runs there, and Python raises
    KeyboardInterrupt in the main thread only once that thread wakes. Sent here to one of viser's or torch's
    threads on purpose (tgkill), as the kernel does now and then (2 stops in 25 under load hung)."""
    import ctypes

    tgkill = getattr(ctypes.CDLL(None, use_errno=True), "tgkill", None)
    if tgkill is None:
        pytest.skip("this C library has no tgkill")
    process = subprocess.Popen(
        [sys.executable, "-m", "ikdp_viz", "--ckpt", str(tiny_checkpoint), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=with_repo_on_path(),
    )
    try:
        first = process.stdout.readline()
        assert first.startswith("ikdp-viz: open http"), first + (process.stderr.read() if process.poll() else "")
        process.stdout.readline(), process.stdout.readline()  # its last two lines: then the main thread waits
        time.sleep(0.5)
        threads = [int(entry.name) for entry in Path(f"/proc/{process.pid}/task").iterdir()]
        other = next(thread for thread in threads if thread != process.pid)  # the main thread's id is the pid
        assert tgkill(process.pid, other, signal.SIGINT) == 0, os.strerror(ctypes.get_errno())
        _, stderr = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, stderr[-500:]
    assert "ikdp-viz: stopped" in stderr


def test_the_flags_open_the_viewer_on_a_given_target_with_given_settings(tiny_checkpoint):
    """--target and the sampling flags reproduce a view (for bug reports), in-process."""
    from viz_helpers import running_app, settle

    import ikdp
    from ikdp_viz.__main__ import VizConfig, apply_settings

    config = VizConfig(target=(0.5, -1.0), samples=5, sampler="ddim", steps=4, seed=3, refine_steps=2)
    with running_app(ikdp.load(tiny_checkpoint), solve_now=False, animation_seconds=0.0) as app:
        apply_settings(app, config)
        settle(app)
        request, view = app.solved.request, app.solved.view
        assert np.allclose(view.target, [0.5, -1.0]) and view.num_samples == 5 and view.num_states == 5
        assert (request.sampler, request.steps, request.seed, request.refine_steps) == ("ddim", 4, 3, 2)


def test_without_sampler_flags_planar_and_robot_models_open_on_ddpm_the_setting_with_good_poses(
    tiny_checkpoint, tiny_chain_checkpoint
):
    from viz_helpers import running_app, settle

    import ikdp
    from ikdp_viz.__main__ import VizConfig, apply_settings

    for checkpoint, expected in ((tiny_checkpoint, ("ddpm", None)), (tiny_chain_checkpoint, ("ddpm", None))):
        with running_app(ikdp.load(checkpoint), solve_now=False, animation_seconds=0.0) as app:
            apply_settings(app, VizConfig(samples=2))
            settle(app)
            assert (app.solved.request.sampler, app.solved.request.steps) == expected


def test_the_readme_tells_a_cpu_only_machine_where_torch_comes_from():
    """The pin alone lets pip fetch a multi-GB CUDA build on Linux; PyTorch's CPU wheel index beside it does not
    (pip takes 2.13.0+cpu), and the same line serves macOS and Windows."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert 'pip install "torch==2.13.0" --extra-index-url https://download.pytorch.org/whl/cpu' in readme
    assert "`torch==2.13.0` is the version CI installs" in readme
