"""Loss settings for tests that isolate one term of the DPC objective."""

from __future__ import annotations

import dataclasses

from mca_drake.learning.configs import DpcTrainingConfig


def loss_weights_only(**kept: float) -> dict[str, float]:
    """Every loss weight of DpcTrainingConfig (its fields ending in "_weight") at 0 but those
    given: `DpcTrainingConfig(**loss_weights_only(tracking_weight=1.0))` prices tracking
    alone, and a loss term added later is off in such tests too."""
    names = {f.name for f in dataclasses.fields(DpcTrainingConfig) if f.name.endswith("_weight")}
    unknown = set(kept) - names
    if unknown:
        raise ValueError(f"not loss weights of DpcTrainingConfig: {sorted(unknown)}")
    return {name: float(kept.get(name, 0.0)) for name in sorted(names)}
