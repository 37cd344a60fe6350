"""Checkpoints: torch state dicts in a file loaded with `weights_only=True` (no pickled
code), written atomically, with a JSON file of configuration and metadata beside them.

    <name>.pt     {"model": state_dict, ...}  (tensors, numbers, strings, lists, dicts only)
    <name>.json   {"format": ..., "model": "<registry name>", "config": {...}, ...}

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

FORMAT = "mca-drake-checkpoint-1"


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable, or does not fit the model."""


def save_checkpoint(path: str | os.PathLike, payload: dict, metadata: dict) -> Path:
    """Writes payload to `path` (.pt) and metadata to the .json beside it, both atomically.

    The JSON is written last: its presence with the current format marks a complete pair.
    """
    path = Path(path)
    buffer = io.BytesIO()
    torch.save(payload, buffer)
    atomic_write_bytes(path, buffer.getvalue())
    atomic_write_json(path.with_suffix(".json"), {"format": FORMAT, **metadata})
    return path


def load_checkpoint(path: str | os.PathLike, map_location="cpu") -> tuple[dict, dict]:
    """(payload, metadata) of a checkpoint written by `save_checkpoint`."""
    path = Path(path)
    meta_path = path.with_suffix(".json")
    if not path.is_file() or not meta_path.is_file():
        raise CheckpointError(f"checkpoint not found: {path} (with {meta_path.name})")
    try:
        metadata = json.loads(meta_path.read_text())
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as err:  # torch raises several types for corrupt or unsafe files
        raise CheckpointError(f"cannot read checkpoint {path}: {err}") from err
    if metadata.get("format") != FORMAT:
        raise CheckpointError(f"{meta_path}: unknown format {metadata.get('format')!r}")
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
