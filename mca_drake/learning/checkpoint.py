"""Checkpoints: torch state dicts in a file loaded with `weights_only=True` (no pickled
code), written atomically as one unit that also holds the configuration and metadata, with
a readable copy of the metadata beside it.

    <name>.pt     {"model": state_dict, ..., "metadata_json": "{...}"}  (tensors, numbers,
                  strings, lists, dicts only)
    <name>.json   {"format": ..., "model": "<registry name>", "config": {...}, ...} (a copy)

Because the metadata travels inside the .pt, a process killed between the two writes leaves
a complete checkpoint (the .pt) whatever state the .json is in. Files of the older format,
whose metadata lived only in the .json, still load.

A checkpoint that does not fit the model (another architecture, other sizes) raises
`CheckpointError` naming the mismatching entries.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import torch
from torch import nn

from mca_drake.atomic_io import atomic_write_bytes, atomic_write_json

FORMAT = "mca-drake-checkpoint-2"
_FORMATS = (FORMAT, "mca-drake-checkpoint-1")


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable, or does not fit the model."""


def save_checkpoint(path: str | os.PathLike, payload: dict, metadata: dict) -> Path:
    """Writes payload and metadata to `path` (.pt) as one atomic unit, then a readable copy
    of the metadata to the .json beside it."""
    path = Path(path)
    metadata = {"format": FORMAT, **metadata}
    buffer = io.BytesIO()
    torch.save({**payload, "metadata_json": json.dumps(metadata)}, buffer)
    atomic_write_bytes(path, buffer.getvalue())
    atomic_write_json(path.with_suffix(".json"), metadata)
    return path


def load_checkpoint(path: str | os.PathLike, map_location="cpu") -> tuple[dict, dict]:
    """(payload, metadata) of a checkpoint written by `save_checkpoint`.

    Raises:
        CheckpointError: no such file, a file that is not a checkpoint (damaged, truncated,
            or holding pickled code), or metadata that is not a checkpoint's.
    """
    path = Path(path)
    meta_path = path.with_suffix(".json")
    if not path.is_file():
        raise CheckpointError(f"checkpoint not found: {path}")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as err:  # torch raises several types for corrupt or unsafe files
        raise CheckpointError(f"cannot read checkpoint {path}: {err}") from err
    if not isinstance(payload, dict):
        raise CheckpointError(f"{path} is not a checkpoint (holds a {type(payload).__name__})")
    try:
        text = payload.pop("metadata_json", None)
        if text is None:  # the older format: metadata only in the .json
            if not meta_path.is_file():
                raise CheckpointError(f"checkpoint {path} has no metadata ({meta_path.name})")
            text = meta_path.read_text()
        metadata = json.loads(text)
    except (OSError, ValueError, TypeError) as err:
        raise CheckpointError(f"cannot read the metadata of checkpoint {path}: {err}") from err
    if not isinstance(metadata, dict) or metadata.get("format") not in _FORMATS:
        found = metadata.get("format") if isinstance(metadata, dict) else type(metadata).__name__
        raise CheckpointError(f"{path}: unknown checkpoint format {found!r}")
    return payload, metadata


def load_state_into(model: nn.Module, state: dict, source: str = "checkpoint") -> None:
    """Loads a state dict strictly; raises CheckpointError listing what does not fit."""
    own = model.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    wrong = sorted(
        f"{k}: {tuple(state[k].shape)} vs model {tuple(own[k].shape)}"
        for k in set(own) & set(state)
        if tuple(state[k].shape) != tuple(own[k].shape)
    )
    if missing or unexpected or wrong:
        raise CheckpointError(
            f"{source} does not fit {type(model).__name__}: missing {missing}, "
            f"unexpected {unexpected}, shape mismatch {wrong}"
        )
    model.load_state_dict(state)
