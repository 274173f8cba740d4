"""The viewer's command line, run as a user runs it: a subprocess."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
import torch

REPO = Path(__file__).resolve().parent.parent


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


def test_help_lists_the_options_and_their_defaults():
    result = run_cli("--help")
    assert result.returncode == 0
    for option in ("--ckpt", "--host", "--port", "--device"):
        assert option in result.stdout
    assert "127.0.0.1" in result.stdout and "8080" in result.stdout


def test_default_model_a_taken_port_and_ctrl_c(tmp_path):
    """From another folder, with no --ckpt: the shipped model loads, the next port is used, Ctrl-C exits cleanly."""
    default = REPO / "checkpoints" / "ikdp_n4.pt"
    if not default.exists():
        pytest.skip("the shipped checkpoints/ikdp_n4.pt is not there")
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
            env={**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))},
        )
        try:
            first = process.stdout.readline()
            second = process.stdout.readline()
            match = re.fullmatch(r"ikdp-viz: open http://127\.0\.0\.1:(\d+)\n", first)
            assert match, first + second + (process.stderr.read() if process.poll() is not None else "")
            used = int(match.group(1))
            assert used != port and f"port {port} was taken, using {used}" in second
            assert str(Path("checkpoints") / "ikdp_n4.pt") in second and "N=4" in second
            with urllib.request.urlopen(f"http://127.0.0.1:{used}", timeout=30) as response:
                assert response.status == 200 and b"<html" in response.read(2000).lower()
            process.send_signal(signal.SIGINT)
            stdout, stderr = process.communicate(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
    assert process.returncode == 0, stderr
    assert "Traceback" not in stderr and "ikdp-viz: stopped" in stderr
