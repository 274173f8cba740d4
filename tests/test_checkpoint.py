import os
import pickle

import pytest
import torch

import ikdp
from ikdp.checkpoint import read_checkpoint, remove_stale_temporaries, save_checkpoint


def test_round_trip_gives_identical_samples(tiny_checkpoint):
    first, second = ikdp.load(tiny_checkpoint), ikdp.load(tiny_checkpoint)
    a = first.solve([[1.0, 1.0]], num_samples=4, generator=torch.Generator().manual_seed(7))
    b = second.solve([[1.0, 1.0]], num_samples=4, generator=torch.Generator().manual_seed(7))
    torch.testing.assert_close(a.angles, b.angles, rtol=0, atol=0)


def test_checkpoint_is_plain_data(tiny_checkpoint):
    payload = torch.load(tiny_checkpoint, weights_only=True)
    assert payload["format"] == "ikdp-checkpoint" and payload["version"] == 1
    assert payload["model"]["lengths"] == (1.0, 1.0, 1.0) or list(payload["model"]["lengths"]) == [1.0, 1.0, 1.0]
    assert payload["train"]["step"] == 30 and payload["train"]["finished"] is True
    assert "tip_error_median" in payload["metrics"]


def test_non_checkpoint_is_refused(tmp_path):
    path = tmp_path / "notes.pt"
    path.write_text("hello")
    with pytest.raises(ikdp.CheckpointError, match="not an IKDP checkpoint"):
        ikdp.load(path)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(ikdp.CheckpointError, match="format tag"):
        ikdp.load(other)
    with pytest.raises(ikdp.CheckpointError, match="no such file"):
        ikdp.load(tmp_path / "missing.pt")


def test_truncated_checkpoint_is_refused(tiny_checkpoint, tmp_path):
    data = tiny_checkpoint.read_bytes()
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(ikdp.CheckpointError) as error:
        ikdp.load(truncated)
    assert "truncated" in str(error.value) and "\n" not in str(error.value)


class _RunsCode:
    def __reduce__(self):
        return (os.system, ("touch pwned_by_checkpoint",))


def test_pickled_code_never_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "evil.pt"
    torch.save({"format": "ikdp-checkpoint", "version": 1, "payload": _RunsCode()}, path, pickle_protocol=2)
    with pytest.raises(ikdp.CheckpointError, match="refused") as error:
        ikdp.load(path)
    assert not (tmp_path / "pwned_by_checkpoint").exists()
    message = str(error.value)
    assert "\n" not in message and "system" in message  # one line, naming what it refused
    assert "weights_only" not in message  # torch's advice to load it anyway must not reach the user


def test_stale_temporaries_are_removed_by_the_next_save(tmp_path):
    path = tmp_path / "model.pt"
    killed_save = tmp_path / ".model.pt.k3_x9q2a.tmp"  # what a SIGKILL during a save leaves
    killed_save.write_bytes(b"")
    not_ours = [".model.pt.backup.tmp", ".other.pt.k3_x9q2a.tmp", "model.pt.k3_x9q2a.tmp", "notes.tmp"]
    for name in not_ours:
        (tmp_path / name).write_bytes(b"keep")
    assert remove_stale_temporaries(tmp_path / "absent" / "model.pt") == []
    save_checkpoint(path, {"model": {}, "prior": {}, "train": {}, "metrics": {}, "state_dict": {}})
    assert not killed_save.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*not_ours, "model.pt"])


def test_other_version_is_refused(tiny_checkpoint, tmp_path):
    payload = torch.load(tiny_checkpoint, weights_only=True)
    payload["version"] = 99
    path = tmp_path / "future.pt"
    torch.save(payload, path)
    with pytest.raises(ikdp.CheckpointError, match="version 99"):
        ikdp.load(path)


def test_mismatched_weights_are_refused(tiny_checkpoint, tmp_path):
    payload = torch.load(tiny_checkpoint, weights_only=True)
    payload["model"]["denoiser"]["hidden"] = 48
    path = tmp_path / "mismatch.pt"
    torch.save(payload, path)
    with pytest.raises(
        ikdp.CheckpointError,
        match=r"model: key 'denoiser.input.weight' has shape \(32, 11\), the model's \(48, 11\) \(and 8 more\)$",
    ):
        ikdp.load(path)
    payload = torch.load(tiny_checkpoint, weights_only=True)
    payload["state_dict"]["denoiser.extra.weight"] = torch.zeros(2)
    torch.save(payload, path)
    with pytest.raises(ikdp.CheckpointError, match=r"weights do not match the model: unexpected key 'denoiser.extra"):
        ikdp.load(path)
    payload = torch.load(tiny_checkpoint, weights_only=True)
    first = next(iter(payload["state_dict"]))
    del payload["state_dict"][first]
    torch.save(payload, path)
    with pytest.raises(ikdp.CheckpointError, match=f"weights do not match the model: missing key '{first}'$"):
        ikdp.load(path)


def test_a_half_written_checkpoint_gets_a_short_message_not_torchs(tiny_checkpoint, tmp_path):
    """The first half of the archive then its directory: a zip whose entries point past the data (torch's own
    message is a 330-character paragraph about miniz)."""
    data = tiny_checkpoint.read_bytes()
    directory = data.find(b"PK\x01\x02")  # the zip's central directory, after every entry's data
    half = tmp_path / "half.pt"
    half.write_bytes(data[: directory // 2] + data[directory:])
    with pytest.raises(ikdp.CheckpointError) as error:
        ikdp.load(half)
    message = str(error.value)
    assert message == f"{half}: unreadable or truncated checkpoint (its archive is damaged: written only in part, " \
        "or changed after saving)"  # fmt: skip


def test_save_is_atomic(tmp_path):
    path = tmp_path / "model.pt"
    save_checkpoint(path, {"model": {}, "prior": {}, "train": {}, "metrics": {}, "state_dict": {}})
    before = path.read_bytes()

    with pytest.raises((pickle.PicklingError, AttributeError, TypeError)):
        save_checkpoint(path, {"model": lambda: None})  # a lambda cannot be pickled: the write fails midway
    assert path.read_bytes() == before  # the old checkpoint survives a failed write
    assert [p.name for p in tmp_path.iterdir()] == ["model.pt"]  # no temp file left behind
    assert read_checkpoint(path)["format"] == "ikdp-checkpoint"
