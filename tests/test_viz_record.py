"""Sharing a denoising: the solve on screen as one HTML page with viser's recorded scene (ikdp_viz/record.py)."""

from __future__ import annotations

import base64
import re

import msgspec
import numpy as np
import pytest
import zstandard
from viz_helpers import running_app, settle

import ikdp
from ikdp_viz.frame import noise_levels, state_offsets
from ikdp_viz.record import HOLD_FINAL, SHORTEST_STATE, RecordSettings, file_name, record_html


def recording(page: str) -> dict:
    """The scene recording a page embeds: viser's base64 of [inner size][zstd([msgpack length][msgpack]...)]."""
    encoded = re.search(r'window\.__VISER_EMBED_DATA__="([^"]+)"', page).group(1)
    raw = base64.b64decode(encoded)
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], max_output_size=int.from_bytes(raw[:8], "little"))
    length = int.from_bytes(inner[:8], "little")
    return msgspec.msgpack.decode(inner[8 : 8 + length])


@pytest.fixture(scope="module")
def shared(tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0, target=(1.2, 0.6)) as app:
        settle(app)
        app.panel.duration.value = 2.0
        name, page = app.share()
        yield app, name, page


def test_the_shared_page_is_viser_s_static_client_with_every_state_on_the_viewer_s_clock(shared):
    app, name, page = shared
    view = app.solved.view
    assert name == file_name(app.solved) and name.startswith("ikdp_ddpm_K16_seed0_+1.200_+0.600")
    assert page.lstrip().lower().startswith("<!doctype html") and "<script" in page
    assert not re.search(r'<script[^>]+src="http', page)  # nothing fetched from a network: it plays offline
    data = recording(page)
    sigmas = noise_levels(view.labels, app.solver.model.schedule.sqrt_one_minus_alphas_cumprod.numpy())
    steps = np.maximum(np.diff(state_offsets(sigmas, "noise level", 2.0)), SHORTEST_STATE)
    assert data["durationSeconds"] == pytest.approx(steps.sum() + HOLD_FINAL)
    # one label per state saying the step, in order, at the times of the clock
    labels = [(time, message) for time, message in data["messages"] if "step" in str(message.get("props", message))]
    texts = [str(message) for _, message in labels]
    for state in (0, view.num_states // 2, view.num_states - 1):
        assert any(f"step {state} of {view.num_states - 1} " in text for text in texts)
    times = sorted({time for time, _ in data["messages"]})
    assert len(times) == view.num_states and times[-1] == pytest.approx(steps.sum())
    assert not any("Gui" in str(message.get("type", "")) for _, message in data["messages"])  # the scene only


def test_a_recording_refuses_a_zero_duration(shared):
    app, _, _ = shared
    with pytest.raises(ValueError, match="seconds"):
        record_html(app.solved, RecordSettings(seconds=0.0))


def test_the_record_command_writes_a_page_for_a_robot(tiny_chain_checkpoint, tmp_path, capsys):
    from ikdp_viz.record import main

    output = tmp_path / "panda.html"
    main(["--ckpt", str(tiny_chain_checkpoint), "--output", str(output), "--samples", "2", "--seconds", "1"])
    data = recording(output.read_text(encoding="utf-8"))
    assert data["durationSeconds"] > 1.0 and "no server needed" in capsys.readouterr().out
    names = {message.get("name") for _, message in data["messages"]}
    assert "/target_frame" in names and any(str(name).startswith("/samples/robot/") for name in names)


def test_the_record_command_answers_a_bad_checkpoint_in_one_line_and_names_itself(tmp_path):
    """`--ckpt nope` once printed a traceback; the usage line showed a file path; the help
    offered a robot target only as a quaternion."""
    import subprocess
    import sys

    from test_viz_cli import REPO, with_repo_on_path

    command = [sys.executable, "-m", "ikdp_viz.record", "--output", str(tmp_path / "x.html")]
    result = subprocess.run([*command, "--ckpt", "nope"], capture_output=True, text=True, timeout=120,
                            env=with_repo_on_path(), cwd=tmp_path)  # fmt: skip
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m ikdp_viz.record: error: nope"), result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "x.html").exists()
    helped = subprocess.run([*command, "--help"], capture_output=True, text=True, timeout=120, env=with_repo_on_path(),
                            cwd=REPO)  # fmt: skip
    assert "usage: python -m ikdp_viz.record" in helped.stdout and "ROLL PITCH YAW" in helped.stdout
    bad_target = subprocess.run([*command, "--target", "1", "2", "3"], capture_output=True, text=True, timeout=120,
                                env=with_repo_on_path(), cwd=REPO)  # fmt: skip
    assert bad_target.returncode == 2 and "--target 1 2 3: target: a planar arm's target is x y" in bad_target.stderr


def test_the_record_command_takes_a_robot_target_in_roll_pitch_yaw(tiny_chain_checkpoint, tmp_path, capsys):
    from ikdp_viz.record import main

    output = tmp_path / "panda.html"
    main(["--ckpt", str(tiny_chain_checkpoint), "--output", str(output), "--samples", "2", "--seconds", "1",
          "--target", "0.4", "0.1", "0.5", "180", "0", "0"])  # fmt: skip
    assert "target x = +400, y = +100, z = +500 mm" in str(recording(output.read_text(encoding="utf-8")))


def created(data: dict, kind: str) -> list[str]:
    """The names of the nodes of message type `kind` the recording creates."""
    return [message["name"] for _, message in data["messages"] if message.get("type") == kind]


def test_a_planar_recording_marks_its_target_once_and_lays_the_legend_over_the_page(shared):
    """The shared page once drew the planar target twice, about 10 px apart (its own
    marker and the viewer's cross), and had no legend."""
    _, _, page = shared
    data = recording(page)
    meshes = created(data, "MeshMessage")
    assert [name for name in meshes if "target" in name] == ["/target_cross"]
    hidden = [message["name"] for _, message in data["messages"]
              if message.get("type") == "SetSceneNodeVisibilityMessage" and not message["visible"]]  # fmt: skip
    assert "/target" in hidden  # the gizmo: no one can drag it in a page of its own
    assert 'id="ikdp-legend"' in page and "trail of the highlighted sample" in page
    assert ".mantine-Notifications-root { display: none" in page  # no toast over the scene


def test_a_robot_recording_labels_every_step_where_its_camera_sees_it(tiny_chain_checkpoint):
    """The Panda's shared page once showed no step label. The target's frame, made before the
    recording began, was /recording/target, a sibling of the label: with it, chromium drew no label (the label at
    the robot's base neither); under a name of its own the label shows. And the label stood about 43 degrees off
    the camera's axis (viser's field of view is 75): it is now recorded where the camera looks."""
    import threading

    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.solving import SolveRequest, solve

    solver = ikdp.load(tiny_chain_checkpoint)
    request = SolveRequest(solver=solver, target=arm_kind(solver).initial_target(solver), num_samples=2,
                           sampler="ddpm", steps=None, refine_steps=0, seed=0, arrival=0.0, animate=False)  # fmt: skip
    solved = solve(request, threading.Event())
    data = recording(record_html(solved, RecordSettings(seconds=1.0)))
    labels = [message for _, message in data["messages"] if message.get("name") == "/recording/step"]
    texts = [str(message) for message in labels]
    for state in range(solved.view.num_states):
        assert any(f"step {state} of {solved.view.num_states - 1} " in text for text in texts), state
    # each label change lands at the instant the robots change to that state, never a sleep before or after
    label_times = sorted({time for time, message in data["messages"] if message.get("name") == "/recording/step"})
    scene_times = sorted({time for time, message in data["messages"] if message.get("name", "").startswith("/samples")})
    assert label_times == scene_times and len(label_times) == solved.view.num_states
    camera = next(m["position"] for _, m in data["messages"] if m.get("type") == "SetCameraPositionMessage")
    look_at = next(m["look_at"] for _, m in data["messages"] if m.get("type") == "SetCameraLookAtMessage")
    where = next(m["position"] for _, m in data["messages"]
                 if m.get("type") == "SetPositionMessage" and m.get("name") == "/recording/step")  # fmt: skip
    forward = np.subtract(look_at, camera)
    toward = np.subtract(where, camera)
    angle = np.degrees(np.arccos(forward @ toward / np.linalg.norm(forward) / np.linalg.norm(toward)))
    assert angle < 30.0  # inside viser's 75-degree field of view, with room for the label's text
    assert not [name for name in created(data, "FrameMessage") if name.startswith("/recording/")]


def legend_texts(page: str) -> list[str]:
    """The legend's lines laid over a recorded page, as plain text (record.with_legend)."""
    from html import unescape

    box = re.search(r'<div id="ikdp-legend".*?</div></div></div>', page, re.S).group(0)
    lines = re.findall(r'<div style="margin:1px 0">(.*?)</div>', box)
    return [unescape(re.sub(r"<span[^>]*>.*?</span>", "", line)) for line in lines]  # the swatch dropped


def shown_nodes(data: dict) -> set[str]:
    """The nodes a recording makes visible at some time (the others stay hidden or are never created)."""
    return {message["name"] for _, message in data["messages"]
            if message.get("type") == "SetSceneNodeVisibilityMessage" and message["visible"]}  # fmt: skip


# a legend word -> the node that draws it, per arm (planar_view.py, robot_view.py, style.py)
PLANAR_LEGEND_NODES = {"x̂0": "/arm/estimate", "refined": "/arm/refined", "poses drawn from the prior": "/prior",
                       "trail": "/arm/trail", "joint space": "/joint_space"}  # fmt: skip
ROBOT_LEGEND_NODES = {"x̂0": "/samples/estimate", "refined": "/samples/refined", "poses drawn from the prior": "/prior",
                      "trail": "/samples/trail"}  # fmt: skip


def assert_legend_lists_what_is_drawn(page: str, nodes: dict[str, str]) -> list[str]:
    texts, shown = legend_texts(page), shown_nodes(recording(page))
    assert texts, "no legend"
    for word, node in nodes.items():
        listed = any(text.startswith(word) for text in texts)
        drawn = any(name == node or name.startswith(node + "/") for name in shown)
        assert listed == drawn, (word, texts, sorted(shown))
    assert not [text for text in texts if "drag" in text or "click" in text or "(show" in text], texts
    return texts


@pytest.mark.parametrize("extras", [False, True], ids=["plain", "x0-and-refined"])
def test_a_recorded_page_s_legend_lists_exactly_what_the_recording_draws(tiny_checkpoint, tiny_chain_checkpoint,
                                                                          extras):  # fmt: skip
    """A recorded Panda page once listed x̂0, refined, the prior and "drag its
    arrows and rings", none of which the page draws or lets anyone do; the planar page listed x̂0, refined and the
    prior too. Each legend line now has its node drawn in the recording, and each of these nodes its line."""
    import threading

    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.solving import SolveRequest, solve

    settings = RecordSettings(seconds=1.0, show_estimate=extras)
    for checkpoint, nodes in ((tiny_checkpoint, PLANAR_LEGEND_NODES), (tiny_chain_checkpoint, ROBOT_LEGEND_NODES)):
        solver = ikdp.load(checkpoint)
        request = SolveRequest(solver=solver, target=arm_kind(solver).initial_target(solver), num_samples=3,
                               sampler="ddpm", steps=None, refine_steps=3 if extras else 0, seed=0, arrival=0.0,
                               animate=False)  # fmt: skip
        texts = assert_legend_lists_what_is_drawn(record_html(solve(request, threading.Event()), settings), nodes)
        assert any(text.startswith("x̂0") for text in texts) == extras
        assert any(text.startswith("refined") for text in texts) == extras
        assert any(text.startswith("target") for text in texts)


def test_the_shared_page_s_legend_drops_the_viewer_s_joint_space_and_prior(shared):
    """The Share button's page: the viewer's legend lists the prior while it is drawn (and, with the view on, the
    joint space); the page draws neither, so its legend does not list them."""
    app, _, _ = shared
    app.panel.joint_space.show.value = True
    try:
        settle(app)
        app.draw_prior()
        legend = [entry.text for entry in app.writer.frame.legend]
        assert any("joint space" in text for text in legend) and "poses drawn from the prior" in legend  # the viewer's
        _, page = app.share()
    finally:
        app.panel.joint_space.show.value = False
        settle(app)
    texts = assert_legend_lists_what_is_drawn(page, PLANAR_LEGEND_NODES)
    assert "target" in texts
