"""Cache keys: a digest of everything that shapes a cached result.

A cached model or stage result is named by the digest of its full dataclass
configuration (nested dataclasses, tuples and tensors included) plus a version
constant, so a changed setting, or changed code that bumps the version, never
reuses a stale entry. The readable part of a cache file's name is for people only;
nothing reads it back.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import torch

import ikdp

CACHE_VERSION = 2  # bump when the code that produces a cached model or stage result changes its output


def _plain(value):
    """A JSON-ready copy of a config value, in a stable order."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"__type__": type(value).__name__, **_plain(dataclasses.asdict(value))}
    if isinstance(value, dict):
        return {str(key): _plain(item) for key, item in sorted(value.items(), key=lambda pair: str(pair[0]))}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, torch.Tensor):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return value


def config_digest(*parts, length: int = 12) -> str:
    """Hex digest of the parts (dataclasses, dicts, plain values) with CACHE_VERSION and ikdp's version."""
    payload = json.dumps([CACHE_VERSION, ikdp.__version__, *map(_plain, parts)], sort_keys=True, default=repr)
    return hashlib.sha1(payload.encode()).hexdigest()[:length]


def file_digest(path: Path, length: int = 12) -> str:
    """Hex digest of a file's bytes: what a shipped checkpoint contributes to a key."""
    return hashlib.sha1(Path(path).read_bytes()).hexdigest()[:length]
