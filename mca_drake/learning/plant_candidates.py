"""The plant-model candidates by name, their training objectives and their accuracy.

    make_state_model("node2")       -> a StateModel  (nssm, node1, node2, exact)
    make_output_model("mixed")      -> an OutputModel (nssm, latent, mixed, exact)

Objectives follow the paper: a state model is trained on the MSE of its recursive state
prediction (eq. 2); an output model on its own loss (eqs. 6-8) with the states predicted by
a frozen state model (the paper used NODE 2) from the segment's first state. A segment of n
steps gives n - 1 predictions: X[:, 1:] from X[:, 0] and U[:, :-1]; Y[:, 1:] from those
states, U[:, 1:] and Y[:, 0] (the latent model's initial output).
"""

from __future__ import annotations

import torch

from mca_drake.learning.data import SegmentTensors
from mca_drake.learning.output_models import OUTPUT_MODELS, OutputModel
from mca_drake.learning.state_models import STATE_MODELS, StateModel


def make_state_model(name: str, **kwargs) -> StateModel:
    """A state-transition candidate by registry name (keyword arguments go to its class)."""
    if name not in STATE_MODELS:
        raise ValueError(f"unknown state model '{name}'; valid: {', '.join(STATE_MODELS)}")
    return STATE_MODELS[name](**kwargs)


def make_output_model(name: str, **kwargs) -> OutputModel:
    """An output candidate by registry name (keyword arguments go to its class)."""
    if name not in OUTPUT_MODELS:
        raise ValueError(f"unknown output model '{name}'; valid: {', '.join(OUTPUT_MODELS)}")
    return OUTPUT_MODELS[name](**kwargs)


def predict_states(model: StateModel, batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """States X[:, 1:] (B, n - 1, 12) predicted from X[:, 0] and U[:, :-1]."""
    return model(batch["X"][:, 0], batch["U"][:, :-1])[:, 1:]


def state_objective(model: StateModel, batch: dict[str, torch.Tensor]) -> torch.Tensor:
    """Equation (2)'s loss: MSE of the recursive state prediction."""
    return torch.mean((predict_states(model, batch) - batch["X"][:, 1:]) ** 2)


def output_objective(state_model: StateModel):
    """The objective of an output model trained on `state_model`'s predicted states."""

    def objective(model: OutputModel, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        with torch.no_grad():
            X = predict_states(state_model, batch)
        targets = {k: batch[k][:, 1:] for k in ("Y", "dF", "ddF")}
        return model.training_loss(X, batch["U"][:, 1:], batch["Y"][:, 0], targets)

    return objective


def predict_outputs(
    output_model: OutputModel, state_model: StateModel, batch: dict[str, torch.Tensor]
) -> torch.Tensor:
    """Outputs Y[:, 1:] (B, n - 1, 6) of the plant made of the two models."""
    X = predict_states(state_model, batch)
    return output_model(X, batch["U"][:, 1:], batch["Y"][:, 0])


@torch.no_grad()
def rmse(
    data: SegmentTensors,
    *,
    state_model: StateModel,
    output_model: OutputModel | None = None,
    batch_size: int = 1024,
) -> float:
    """RMSE over all predicted entries: of the states if no output model is given, else of
    the outputs (the plant of both models). Units: mixed (rad, rad/s; rad/s, m/s^2)."""
    total, count = 0.0, 0
    for batch in data.batches(batch_size, shuffle=False):
        if output_model is None:
            error = predict_states(state_model, batch) - batch["X"][:, 1:]
        else:
            error = predict_outputs(output_model, state_model, batch) - batch["Y"][:, 1:]
        total += float(torch.sum(error.double() ** 2))
        count += error.numel()
    return (total / count) ** 0.5
