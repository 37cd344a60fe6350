"""Curriculum trainer (paper Section V-A): RAdam, reduce-on-plateau, early stopping, best
weights carried from one horizon to the next; atomic checkpoints and resume after a kill.

    trainer = CurriculumTrainer(model, objective, TrainConfig(), "runs/node1.pt")
    result = trainer.fit(train, validation, resume=True)

`objective(model, batch) -> loss` gets a dict of tensors (B, n, ...) at the current
horizon n (see `mca_drake.learning.data`) and returns a scalar. Validation uses the same
objective without gradients.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

from mca_drake.atomic_io import atomic_write_text
from mca_drake.learning.checkpoint import (
    CheckpointError,
    load_checkpoint,
    load_state_into,
    save_checkpoint,
)
from mca_drake.learning.configs import TrainConfig
from mca_drake.learning.data import TRAINING_ARRAYS, SegmentTensors, to_tensors
from mca_drake.segments import SegmentDataset

Objective = Callable[[nn.Module, dict[str, torch.Tensor]], torch.Tensor]


class TrainingDivergedError(FloatingPointError, RuntimeError):
    """Training cannot go on: the loss or too many batches' gradients were not finite. A
    RuntimeError too, so that the command line reports it as an error the user can act on
    (a lower learning rate, other data), not as a bug."""


@dataclasses.dataclass
class EpochRecord:
    """One epoch of the loss log."""

    stage: int
    horizon: int
    epoch: int
    train_loss: float
    validation_loss: float
    learning_rate: float
    wall_s: float
    # Batches whose gradient was not finite and were skipped (see MAX_SKIPPED_FRACTION).
    skipped_batches: int = 0


# A batch whose loss is finite but whose gradient is not (a long closed-loop rollout can
# pass a state where one branch of a piecewise bound has an infinite slope: seen at
# n_c = 1024 on the mixed-vehicle set, in one batch in a few) is skipped, its step not
# taken; more than this fraction of an epoch's batches skipped stops the run with an error.
MAX_SKIPPED_FRACTION = 0.25


@dataclasses.dataclass
class StageResult:
    """The outcome of one curriculum step."""

    horizon: int
    best_validation_loss: float
    best_epoch: int
    epochs: int
    wall_s: float


@dataclasses.dataclass
class TrainResult:
    """What `fit` returns; the model holds the best weights of the last step."""

    model: nn.Module
    stages: list[StageResult]
    history: list[EpochRecord]
    wall_s: float


# Train settings a resumed run may change (train longer, on another device); every other
# one, and the data, must be those of the checkpoint.
_RESUMABLE_CHANGES = ("max_epochs", "early_stopping_patience", "device")
_PAYLOAD_KEYS = ("model", "best_model", "optimiser", "scheduler", "generator", "progress")


def run_identity(
    config: TrainConfig, train: SegmentDataset, validation: SegmentDataset, names
) -> dict:
    """What makes a training run this run: its settings (less those a resume may change)
    and the SHA-256 of the arrays it trains and validates on."""
    digest = hashlib.sha256()
    for part in (train, validation):
        for name in sorted(names):
            if name in part.arrays:
                array = np.ascontiguousarray(part.arrays[name])
                digest.update(f"{name}{array.shape}{array.dtype}".encode())
                digest.update(array.tobytes())
    settings = {k: v for k, v in dataclasses.asdict(config).items() if k not in _RESUMABLE_CHANGES}
    return {"train_config": json.loads(json.dumps(settings)), "data_sha256": digest.hexdigest()}


def _check_resumable(path: Path, payload: dict, meta: dict, identity: dict) -> None:
    """Raises CheckpointError unless the checkpoint holds every part a resume needs and was
    made by a run with this identity (same settings, same data)."""
    missing = [k for k in _PAYLOAD_KEYS if k not in payload]
    if missing:
        raise CheckpointError(f"checkpoint {path} lacks {missing}: it cannot be resumed")
    saved = meta.get("run_identity")
    if saved is None:
        return  # a checkpoint without a run identity: nothing to compare
    if saved.get("data_sha256") != identity["data_sha256"]:
        raise CheckpointError(
            f"checkpoint {path} was trained on other data; resume it with the same dataset, "
            "or train afresh in another output folder"
        )
    changed = sorted(
        k
        for k in set(saved["train_config"]) | set(identity["train_config"])
        if saved["train_config"].get(k) != identity["train_config"].get(k)
    )
    if changed:
        raise CheckpointError(
            f"checkpoint {path} was trained with other settings ({', '.join(changed)}); a "
            f"resume may change only {', '.join(_RESUMABLE_CHANGES)}"
        )


class CurriculumTrainer:
    """Trains `model` by `objective` over the curriculum of `config.horizons`.

    Args:
        model: the torch module to train (moved to the configured device).
        objective: loss function, see the module docstring.
        config: the training settings.
        checkpoint_path: the .pt file of the checkpoint (a .json, a _loss.csv and a
            _loss.png are written beside it).
        metadata: JSON-serialisable description stored with every checkpoint (model name,
            its arguments, dataset): it lets a reader rebuild the model.
        callbacks: called with each EpochRecord after the epoch's checkpoint decision.
        stage_callbacks: called with (StageResult, model) at the end of each curriculum
            step, the model holding that step's best weights (e.g. to save or score them).
        arrays: the dataset arrays the objective reads (default U, X, Y, dF, ddF).
    """

    def __init__(
        self,
        model: nn.Module,
        objective: Objective,
        config: TrainConfig | None = None,
        checkpoint_path: str | Path = "checkpoint.pt",
        metadata: dict | None = None,
        callbacks: Sequence[Callable[[EpochRecord], None]] = (),
        stage_callbacks: Sequence[Callable[[StageResult, nn.Module], None]] = (),
        arrays: tuple[str, ...] = TRAINING_ARRAYS,
    ):
        self.config = config or TrainConfig()
        self.config.validate()
        self.device = self.config.resolved_device()
        self.model = model.to(self.device)
        self.objective = objective
        self.checkpoint_path = Path(checkpoint_path)
        self.metadata = dict(metadata or {})
        self.callbacks = list(callbacks)
        self.stage_callbacks = list(stage_callbacks)
        self.arrays = tuple(arrays)

    # ----------------------------------------------------------------- helpers
    def _new_optimiser(self):
        cfg = self.config
        optimiser = torch.optim.RAdam(
            self.model.parameters(),
            lr=cfg.learning_rate,
            weight_decay=cfg.weight_decay,
            decoupled_weight_decay=True,
        )
        scheduler = torch.optim.lr_scheduler.ReduceLROnPlateau(
            optimiser, factor=cfg.plateau_factor, patience=cfg.plateau_patience
        )
        return optimiser, scheduler

    def evaluate(self, data: SegmentTensors) -> float:
        """Mean objective over `data` (weighted by batch size), without gradients."""
        self.model.eval()
        total, count = 0.0, 0
        with torch.no_grad():
            for batch in data.batches(self.config.batch_size, shuffle=False):
                n = batch["U"].shape[0]
                total += float(self.objective(self.model, batch)) * n
                count += n
        return total / max(count, 1)

    def _state(
        self, progress: dict, optimiser, scheduler, best_state, generator, average=None
    ) -> dict:
        return {
            "model": self.model.state_dict(),
            "best_model": best_state,
            # the sum of the weights averaged so far (`TrainConfig.average_epochs`)
            "average_model": average,
            "optimiser": optimiser.state_dict(),
            "scheduler": scheduler.state_dict(),
            "generator": generator.get_state(),
            # torch's global generator too: objectives draw from it (DPC's perturbed
            # initial states), so a resumed run continues the same random sequence.
            "torch_rng": torch.get_rng_state(),
            "progress": progress,
        }

    def _save(self, payload: dict, history: list[EpochRecord], stages: list[StageResult]):
        meta = {
            **self.metadata,
            "run_identity": self._identity,
            "train_config": dataclasses.asdict(self.config),
            "stages": [dataclasses.asdict(s) for s in stages],
            "epochs_logged": len(history),
        }
        save_checkpoint(self.checkpoint_path, payload, meta)
        self._write_log(history)

    def _write_log(self, history: list[EpochRecord]) -> None:
        buffer = io.StringIO()
        fields = [f.name for f in dataclasses.fields(EpochRecord)]
        writer = csv.DictWriter(buffer, fieldnames=fields)
        writer.writeheader()
        for record in history:
            writer.writerow(dataclasses.asdict(record))
        atomic_write_text(self.log_path, buffer.getvalue())

    @property
    def log_path(self) -> Path:
        """The per-epoch loss log (CSV) beside the checkpoint."""
        return self.checkpoint_path.with_name(self.checkpoint_path.stem + "_loss.csv")

    @property
    def plot_path(self) -> Path:
        """The loss-curve figure (PNG) beside the checkpoint."""
        return self.checkpoint_path.with_name(self.checkpoint_path.stem + "_loss.png")

    # ----------------------------------------------------------------- training
    def fit(
        self,
        train: SegmentDataset,
        validation: SegmentDataset,
        *,
        resume: bool = False,
        progress: bool = True,
    ) -> TrainResult:
        """Runs (or resumes) the curriculum; returns the best weights of the last step.

        Args:
            train: the training segments, with a horizon >= max(config.horizons).
            validation: the validation segments, with the same horizon bound.
            resume: continue from the checkpoint at `checkpoint_path`. Without it an
                existing checkpoint is an error (nothing is overwritten by accident).
            progress: show a progress bar per curriculum step.
        """
        cfg = self.config
        if max(cfg.horizons) > min(train.horizon, validation.horizon):
            raise ValueError(
                f"curriculum horizon {max(cfg.horizons)} exceeds the dataset horizon "
                f"{min(train.horizon, validation.horizon)}"
            )
        self._identity = run_identity(cfg, train, validation, self.arrays)
        generator = torch.Generator().manual_seed(cfg.seed)
        saved, history, stages = self._load_resume_point(resume, generator)
        start_stage = saved["progress"]["stage"] if saved is not None else 0
        wall_start = time.perf_counter() - (history[-1].wall_s if history else 0.0)
        for stage in range(start_stage, len(cfg.horizons)):
            self._fit_stage(
                stage, train, validation, generator, saved, history, stages, wall_start, progress
            )
            saved = None
        self._plot(history)
        return TrainResult(self.model, stages, history, time.perf_counter() - wall_start)

    def _load_resume_point(self, resume: bool, generator: torch.Generator):
        """(the checkpoint's payload to resume from, its loss log, its finished steps), or
        (None, [], []) for a fresh run; loads the checkpoint's model weights and random
        states into the model, `generator` and torch's global generator."""
        if not self.checkpoint_path.exists():
            return None, [], []
        if not resume:
            raise ValueError(
                f"checkpoint {self.checkpoint_path} exists: resume it (--resume) or "
                "choose another output folder"
            )
        payload, meta = load_checkpoint(self.checkpoint_path, map_location=self.device)
        for key in ("model", "model_kwargs"):
            if key in self.metadata and meta.get(key) != self.metadata[key]:
                raise CheckpointError(
                    f"checkpoint {self.checkpoint_path} holds {key}={meta.get(key)!r}; "
                    f"this run trains {key}={self.metadata[key]!r}"
                )
        _check_resumable(self.checkpoint_path, payload, meta, self._identity)
        load_state_into(self.model, payload["model"], str(self.checkpoint_path))
        p = payload["progress"]
        history = [EpochRecord(**r) for r in p["history"]]
        stages = [StageResult(**s) for s in p["stages"]]
        generator.set_state(payload["generator"])
        if "torch_rng" in payload:
            torch.set_rng_state(payload["torch_rng"])
        return payload, history, stages

    def _fit_stage(
        self, stage, train, validation, generator, saved, history, stages, wall_start, progress
    ) -> None:
        """Trains curriculum step `stage` (from the checkpoint payload `saved` where it is
        not None), appending its epochs to `history` and its result to `stages`; leaves the
        model with the step's best weights and checkpoints them."""
        cfg = self.config
        horizon = cfg.horizons[stage]
        train_t = to_tensors(train, horizon, device=self.device, names=self.arrays)
        val_t = to_tensors(validation, horizon, device=self.device, names=self.arrays)
        optimiser, scheduler = self._new_optimiser()
        best_state = {k: v.clone() for k, v in self.model.state_dict().items()}
        best_val, best_epoch, stage_start = math.inf, -1, time.perf_counter()
        epoch = 0
        # weight averaging: the sum of the weights after each epoch from `average_from` on
        average_from = cfg.max_epochs - cfg.average_epochs
        average, averaged = None, 0
        if saved is not None:
            p = saved["progress"]
            optimiser.load_state_dict(saved["optimiser"])
            scheduler.load_state_dict(saved["scheduler"])
            best_state = saved["best_model"]
            best_val, best_epoch, epoch = p["best_validation"], p["best_epoch"], p["epoch"]
            average, averaged = saved.get("average_model"), p.get("averaged", 0)
            stage_start -= p["stage_wall_s"]
        last_save = time.perf_counter()
        bar = tqdm(
            total=cfg.max_epochs,
            initial=epoch,
            desc=f"n_p={horizon}",
            disable=not progress,
            leave=False,
        )
        while epoch < cfg.max_epochs and (
            cfg.average_epochs or epoch - best_epoch <= cfg.early_stopping_patience
        ):
            train_loss, skipped = self._train_epoch(train_t, optimiser, generator, horizon, epoch)
            scheduler.step(train_loss)
            val_loss = self.evaluate(val_t)
            if val_loss < best_val:
                best_val, best_epoch = val_loss, epoch
                best_state = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
            if cfg.average_epochs and epoch >= average_from:
                average = _add_weights(average, self.model.state_dict())
                averaged += 1
            epoch += 1
            record = EpochRecord(
                stage,
                horizon,
                epoch,
                train_loss,
                val_loss,
                optimiser.param_groups[0]["lr"],
                time.perf_counter() - wall_start,
                skipped,
            )
            history.append(record)
            bar.update(1)
            bar.set_postfix(train=f"{train_loss:.3g}", val=f"{val_loss:.3g}")
            if time.perf_counter() - last_save > cfg.checkpoint_interval_s:
                progress_state = self._progress(
                    stage, epoch, best_val, best_epoch, stage_start, history, stages, averaged
                )
                state = self._state(
                    progress_state, optimiser, scheduler, best_state, generator, average
                )
                self._save(state, history, stages)
                last_save = time.perf_counter()
            for callback in self.callbacks:
                callback(record)
        bar.close()
        if averaged:
            # the step's result is the mean of its last epochs' weights, scored like an epoch
            best_state = _mean_weights(average, averaged, self.model.state_dict())
            self.model.load_state_dict(best_state)
            best_val, best_epoch = self.evaluate(val_t), epoch - 1
        self.model.load_state_dict(best_state)
        stages.append(
            StageResult(horizon, best_val, best_epoch + 1, epoch, time.perf_counter() - stage_start)
        )
        for callback in self.stage_callbacks:
            callback(stages[-1], self.model)
        # The next step starts from these best weights with a fresh optimiser.
        progress_state = self._progress(
            stage + 1, 0, math.inf, -1, time.perf_counter(), history, stages
        )
        optimiser, scheduler = self._new_optimiser()
        self._save(
            self._state(progress_state, optimiser, scheduler, best_state, generator),
            history,
            stages,
        )

    def _train_epoch(self, data: SegmentTensors, optimiser, generator, horizon, epoch):
        """One epoch of optimiser steps over `data` (curriculum horizon `horizon`): (the mean
        training loss of the batches it stepped on, the number of batches it skipped)."""
        cfg = self.config
        self.model.train()
        total, count, batches, skipped = 0.0, 0, 0, 0
        for batch in data.batches(cfg.batch_size, generator):
            batches += 1
            optimiser.zero_grad(set_to_none=True)
            loss = self.objective(self.model, batch)
            if not torch.isfinite(loss):
                raise TrainingDivergedError(
                    f"training loss is {float(loss)} at n_p={horizon}, epoch {epoch}: "
                    "lower the learning rate or check the data"
                )
            loss.backward()
            # The global norm before clipping (inf: only measured, not clipped).
            norm = torch.nn.utils.clip_grad_norm_(
                self.model.parameters(),
                cfg.gradient_clip_norm if cfg.gradient_clip_norm > 0 else math.inf,
            )
            if not torch.isfinite(norm):
                optimiser.zero_grad(set_to_none=True)
                skipped += 1
                continue
            optimiser.step()
            total += loss.item() * batch["U"].shape[0]
            count += batch["U"].shape[0]
        if skipped > MAX_SKIPPED_FRACTION * batches:
            raise TrainingDivergedError(
                f"the gradient was not finite in {skipped} of {batches} batches at "
                f"n_p={horizon}, epoch {epoch}: lower the learning rate or check the "
                "data"
            )
        return total / count, skipped

    @staticmethod
    def _progress(
        stage, epoch, best_val, best_epoch, stage_start, history, stages, averaged=0
    ) -> dict:
        return {
            "stage": stage,
            "epoch": epoch,
            "best_validation": best_val,
            "best_epoch": best_epoch,
            "averaged": averaged,
            "stage_wall_s": time.perf_counter() - stage_start,
            "history": [dataclasses.asdict(r) for r in history],
            "stages": [dataclasses.asdict(s) for s in stages],
        }

    def _plot(self, history: list[EpochRecord]) -> None:
        if not history:
            return
        # matplotlib (heavy): loaded only when a training run draws its loss curve
        from mca_drake.plotting import plot_loss_curves, save_figure

        save_figure(plot_loss_curves(history, title=self.metadata.get("model", "")), self.plot_path)


def _add_weights(total: dict | None, state: dict) -> dict:
    """`total` (None: nothing yet) plus the floating-point weights of `state`, in float64 so
    that a long average loses nothing to round-off."""
    weights = {k: v.detach().to(torch.float64) for k, v in state.items() if v.is_floating_point()}
    if total is None:
        return {k: v.clone() for k, v in weights.items()}
    return {k: total[k] + v for k, v in weights.items()}


def _mean_weights(total: dict, count: int, state: dict) -> dict:
    """The state dict `state` with each floating-point entry replaced by `total / count`, in
    its own dtype (other entries, e.g. counters, as they are in `state`)."""
    return {
        k: (total[k] / count).to(v.dtype) if k in total else v.detach().clone()
        for k, v in state.items()
    }
