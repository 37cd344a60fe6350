"""torch learning: plant-model candidates, trainer with curriculum and checkpoints, and
the Table II study. See `plant_candidates` for the registry."""

from mca_drake.learning.checkpoint import CheckpointError
from mca_drake.learning.plant_candidates import make_output_model, make_state_model
from mca_drake.learning.trainer import CurriculumTrainer, TrainConfig, TrainResult

__all__ = [
    "CheckpointError",
    "CurriculumTrainer",
    "TrainConfig",
    "TrainResult",
    "make_output_model",
    "make_state_model",
]
