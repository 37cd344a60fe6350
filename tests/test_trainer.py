"""Curriculum trainer: it learns, it resumes after a kill, and checkpoints are safe."""

from __future__ import annotations

import json

import pytest
import torch

from mca_drake.learning import CheckpointError, CurriculumTrainer, TrainConfig
from mca_drake.learning.checkpoint import load_checkpoint
from mca_drake.learning.plant_candidates import (
    make_output_model,
    make_state_model,
    output_objective,
    state_objective,
)
from mca_drake.learning.trainer import TrainingDivergedError
from mca_drake.platforms.excitation import ExcitationConfig, generate_excitation_dataset


@pytest.fixture(scope="module")
def tiny_split():
    data = generate_excitation_dataset(
        ExcitationConfig(
            signals=("sine", "walk"),
            repetitions=3,
            duration_s=2.0,
            horizon=16,
            initial_state_fraction=0.3,
            seed=3,
        ),
        progress=False,
    )
    assert len(data) >= 40
    train, validation, _ = data.split((0.7, 0.2, 0.1), seed=0)
    return train, validation


def _config(**overrides) -> TrainConfig:
    base = dict(
        batch_size=32,
        max_epochs=6,
        horizons=(8, 16),
        early_stopping_patience=50,
        checkpoint_interval_s=0.0,
        device="cpu",
    )
    return TrainConfig(**{**base, **overrides})


def test_training_lowers_validation_loss(tiny_split, tmp_path):
    train, validation = tiny_split
    torch.manual_seed(0)
    model = make_state_model("nssm")
    trainer = CurriculumTrainer(
        model, state_objective, _config(max_epochs=15, horizons=(16,)), tmp_path / "nssm.pt"
    )
    from mca_drake.learning.data import to_tensors

    before = trainer.evaluate(to_tensors(validation))
    result = trainer.fit(train, validation, progress=False)
    after = trainer.evaluate(to_tensors(validation))
    assert after < 0.5 * before, (before, after)
    assert result.stages[0].best_validation_loss == pytest.approx(after, rel=1e-5)
    assert (tmp_path / "nssm_loss.csv").read_text().count("\n") == 16  # header + 15 epochs
    assert (tmp_path / "nssm_loss.png").stat().st_size > 1000


def test_output_model_training_on_node2_states(tiny_split, tmp_path):
    train, validation = tiny_split
    torch.manual_seed(0)
    objective = output_objective(make_state_model("node2"))
    trainer = CurriculumTrainer(
        make_output_model("mixed"), objective, _config(max_epochs=8), tmp_path / "mixed.pt"
    )
    result = trainer.fit(train, validation, progress=False)
    losses = [r.validation_loss for r in result.history]
    assert min(losses[-3:]) < losses[0]


class SimulatedKillError(Exception):
    pass


def test_resume_after_kill_continues_to_the_same_weights(tiny_split, tmp_path):
    train, validation = tiny_split

    def run(path, kill_at=None, resume=False):
        torch.manual_seed(0)
        model = make_state_model("nssm")

        def kill(record):
            if kill_at is not None and len(trainer_log) == 0 and record.epoch == kill_at:
                trainer_log.append(record)
                raise SimulatedKillError

        trainer_log: list = []
        trainer = CurriculumTrainer(
            model, state_objective, _config(), path, {"model": "nssm"}, callbacks=[kill]
        )
        return trainer.fit(train, validation, resume=resume, progress=False)

    reference = run(tmp_path / "a.pt")
    with pytest.raises(SimulatedKillError):
        run(tmp_path / "b.pt", kill_at=4)  # killed in the first curriculum step
    payload, _ = load_checkpoint(tmp_path / "b.pt")
    assert payload["progress"]["stage"] == 0 and payload["progress"]["epoch"] == 4
    resumed = run(tmp_path / "b.pt", resume=True)
    assert len(resumed.history) == len(reference.history)
    for key, value in reference.model.state_dict().items():
        torch.testing.assert_close(resumed.model.state_dict()[key], value, rtol=0, atol=1e-6)
    # A finished run resumed again changes nothing.
    again = run(tmp_path / "b.pt", resume=True)
    assert len(again.history) == len(reference.history)


def test_existing_checkpoint_is_not_overwritten_without_resume(tiny_split, tmp_path):
    train, validation = tiny_split
    path = tmp_path / "x.pt"
    CurriculumTrainer(make_state_model("nssm"), state_objective, _config(max_epochs=1), path).fit(
        train, validation, progress=False
    )
    with pytest.raises(ValueError, match="exists: resume it"):
        CurriculumTrainer(make_state_model("nssm"), state_objective, _config(), path).fit(
            train, validation, progress=False
        )


def test_checkpoint_that_does_not_fit_is_a_clear_error(tiny_split, tmp_path):
    train, validation = tiny_split
    path = tmp_path / "m.pt"
    meta = {"model": "nssm", "model_kwargs": {"hidden": 64}}
    CurriculumTrainer(
        make_state_model("nssm"), state_objective, _config(max_epochs=1), path, meta
    ).fit(train, validation, progress=False)
    # other sizes, same name: the state dict check names the mismatching tensors
    with pytest.raises(CheckpointError, match="shape mismatch"):
        CurriculumTrainer(
            make_state_model("nssm", hidden=32), state_objective, _config(), path
        ).fit(train, validation, resume=True, progress=False)
    # another model by name
    with pytest.raises(CheckpointError, match="holds model='nssm'"):
        CurriculumTrainer(
            make_state_model("node1"), state_objective, _config(), path, {"model": "node1"}
        ).fit(train, validation, resume=True, progress=False)
    # a corrupt file
    path.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot read checkpoint"):
        load_checkpoint(path)
    assert json.loads(path.with_suffix(".json").read_text())["model"] == "nssm"


def test_horizon_longer_than_data_is_rejected(tiny_split, tmp_path):
    train, validation = tiny_split
    trainer = CurriculumTrainer(
        make_state_model("nssm"), state_objective, _config(horizons=(32,)), tmp_path / "h.pt"
    )
    with pytest.raises(ValueError, match="exceeds the dataset horizon 16"):
        trainer.fit(train, validation, progress=False)


def _noisy_objective(model, batch):
    """An objective that draws from torch's global generator, as DPC's perturbed initial
    states do: a resumed run matches an uninterrupted one only if that state is saved."""
    return state_objective(model, batch) * (1.0 + 0.1 * torch.rand(()))


def _run(tmp_path, name, train, validation, *, kill_at=None, resume=False, **config):
    torch.manual_seed(0)
    model = make_state_model("nssm")

    def kill(record):
        if kill_at is not None and record.epoch == kill_at and not resume:
            raise SimulatedKillError

    trainer = CurriculumTrainer(
        model,
        _noisy_objective,
        _config(**config),
        tmp_path / name,
        {"model": "nssm"},
        callbacks=[kill],
    )
    return trainer.fit(train, validation, resume=resume, progress=False)


def test_resume_restores_torch_global_generator(tiny_split, tmp_path):
    train, validation = tiny_split
    reference = _run(tmp_path, "a.pt", train, validation)
    with pytest.raises(SimulatedKillError):
        _run(tmp_path, "b.pt", train, validation, kill_at=3)
    torch.manual_seed(123)  # whatever the new process's global state is
    resumed = _run(tmp_path, "b.pt", train, validation, resume=True)
    for key, value in reference.model.state_dict().items():
        torch.testing.assert_close(resumed.model.state_dict()[key], value, rtol=0, atol=0)


def test_a_kill_between_the_checkpoint_and_its_json_still_resumes(tiny_split, tmp_path):
    """The .pt is the whole checkpoint: a stale or missing .json (the process killed after
    the .pt was renamed into place) does not stop a resume."""
    train, validation = tiny_split
    reference = _run(tmp_path, "a.pt", train, validation)
    with pytest.raises(SimulatedKillError):
        _run(tmp_path, "b.pt", train, validation, kill_at=3)
    (tmp_path / "b.json").unlink()
    resumed = _run(tmp_path, "b.pt", train, validation, resume=True)
    for key, value in reference.model.state_dict().items():
        torch.testing.assert_close(resumed.model.state_dict()[key], value, rtol=0, atol=0)


def test_resume_refuses_other_data_or_curriculum(tiny_split, tmp_path):
    train, validation = tiny_split
    with pytest.raises(SimulatedKillError):
        _run(tmp_path, "c.pt", train, validation, kill_at=2)
    with pytest.raises(CheckpointError, match="trained on other data"):
        _run(tmp_path, "c.pt", validation, train, resume=True)
    with pytest.raises(CheckpointError, match=r"other settings \(horizons\)"):
        _run(tmp_path, "c.pt", train, validation, resume=True, horizons=(16,))
    # training longer is a legitimate resume
    longer = _run(tmp_path, "c.pt", train, validation, resume=True, max_epochs=8)
    assert len(longer.history) == 16


def test_a_checkpoint_without_its_parts_is_refused(tiny_split, tmp_path):
    from mca_drake.learning.checkpoint import save_checkpoint

    train, validation = tiny_split
    path = tmp_path / "d.pt"
    _run(tmp_path, "d.pt", train, validation, max_epochs=1)
    payload, meta = load_checkpoint(path)
    del payload["best_model"]
    save_checkpoint(path, payload, {k: v for k, v in meta.items() if k != "format"})
    with pytest.raises(CheckpointError, match=r"lacks \['best_model'\]"):
        _run(tmp_path, "d.pt", train, validation, resume=True, max_epochs=1)


def test_batches_with_a_non_finite_gradient_are_skipped_and_too_many_stop(tiny_split, tmp_path):
    """A finite loss whose gradient is infinite (sqrt at 0, the trap of a piecewise bound)
    must not reach the weights: that batch is skipped and counted; when most are, an error."""
    train, validation = tiny_split
    torch.manual_seed(0)
    calls = {"n": 0}

    def objective(model, batch, poison_every):
        loss = state_objective(model, batch)
        calls["n"] += 1
        if model.training and calls["n"] % poison_every == 0:
            w = next(model.parameters())
            loss = loss + torch.sqrt(w.sum() - w.sum().detach())  # value 0, slope inf
        return loss

    model = make_state_model("nssm")
    config = _config(max_epochs=3, horizons=(16,), batch_size=4)
    trainer = CurriculumTrainer(
        model, lambda m, b: objective(m, b, 7), config, tmp_path / "skip.pt"
    )
    result = trainer.fit(train, validation, progress=False)
    assert sum(r.skipped_batches for r in result.history) >= 1
    assert all(torch.isfinite(p).all() for p in model.parameters())
    assert "skipped_batches" in (tmp_path / "skip_loss.csv").read_text().splitlines()[0]

    calls["n"] = 0
    every = CurriculumTrainer(
        make_state_model("nssm"), lambda m, b: objective(m, b, 1), config, tmp_path / "all.pt"
    )
    with pytest.raises(TrainingDivergedError, match="gradient was not finite") as raised:
        every.fit(train, validation, progress=False)
    # the command line reports it as an error the user can act on, not as a bug
    assert isinstance(raised.value, RuntimeError) and isinstance(raised.value, FloatingPointError)


def test_weight_averaging_ends_each_step_on_the_mean_of_its_last_epochs(tiny_split, tmp_path):
    """The oracle: the weights after each epoch, copied by a callback and averaged here."""
    train, validation = tiny_split
    torch.manual_seed(0)
    model = make_state_model("nssm")
    after_epoch: list[dict] = []

    def keep(record):
        after_epoch.append({k: v.detach().clone() for k, v in model.state_dict().items()})

    # patience 0 would stop a run without averaging after its first epoch that does not
    # improve: an averaging step runs all its epochs
    config = _config(max_epochs=6, horizons=(16,), average_epochs=3, early_stopping_patience=0)
    trainer = CurriculumTrainer(
        model, state_objective, config, tmp_path / "avg.pt", callbacks=[keep]
    )
    result = trainer.fit(train, validation, progress=False)
    assert len(after_epoch) == 6
    from mca_drake.learning.data import to_tensors

    for key, value in result.model.state_dict().items():
        mean = sum(state[key].double() for state in after_epoch[3:]) / 3
        torch.testing.assert_close(value, mean.to(value.dtype), rtol=1e-6, atol=1e-7)
        assert not torch.equal(value, after_epoch[-1][key])  # not the last epoch's own
    stage = result.stages[0]
    assert stage.best_epoch == 6 and stage.epochs == 6
    assert stage.best_validation_loss == pytest.approx(trainer.evaluate(to_tensors(validation)))


def test_a_run_killed_while_averaging_resumes_to_the_same_mean(tiny_split, tmp_path):
    train, validation = tiny_split
    averaging = dict(max_epochs=6, horizons=(16,), average_epochs=4)
    reference = _run(tmp_path, "a.pt", train, validation, **averaging)
    with pytest.raises(SimulatedKillError):
        _run(tmp_path, "b.pt", train, validation, kill_at=4, **averaging)
    payload, _ = load_checkpoint(tmp_path / "b.pt")
    assert payload["progress"]["averaged"] == 2  # epochs 3 and 4 of 6 summed when killed
    resumed = _run(tmp_path, "b.pt", train, validation, resume=True, **averaging)
    for key, value in reference.model.state_dict().items():
        torch.testing.assert_close(resumed.model.state_dict()[key], value, rtol=0, atol=0)


@pytest.mark.parametrize("average_epochs", [-1, 7])
def test_averaging_more_epochs_than_a_step_runs_is_refused(average_epochs):
    with pytest.raises(ValueError, match="average_epochs"):
        _config(max_epochs=6, average_epochs=average_epochs).validate()
