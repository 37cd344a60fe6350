"""The training configs, readable without torch: `TrainConfig` (the curriculum trainer's),
`DpcTrainingConfig` (the DPC policy's loss, data and network) and the policy network's input
scales. The command line derives its training flags from them without loading torch.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from mca_drake.cueing import NmpcConfig
from mca_drake.cueing.nmpc_config import OBJECTIVES
from mca_drake.cueing.predictor import check_predictor
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.files import DEFAULT_PLATFORM

# Typical magnitudes of the output channels [w_x, w_y, w_z, f_x, f_y, a_z]: rad/s, m/s^2.
# The scaled references' rates have a spread of 0.02-0.06 rad/s (the mixed-vehicle set; p99
# 0.09-0.28) against 0.3-1.4 m/s^2 for the forces. The rates' scale is 0.1 rad/s because at
# 0.5 rad/s an airliner's yaw rate reaches the network at a fiftieth of a force's size, and
# Adam's bounded steps never grow its weights enough (yaw CC 0.14 against the NMPC's 0.96 on
# a 787 flight).
OUTPUT_SCALE = (0.1, 0.1, 0.1, 2.0, 2.0, 2.0)
# The scales of the policy_v6 file (the paper reproduction), which carries them.
OUTPUT_SCALE_V6 = (0.5, 0.5, 0.5, 2.0, 2.0, 2.0)


@dataclasses.dataclass
class TrainConfig:
    """Training settings; defaults are the paper's for the plant models."""

    # RAdam learning rate and decoupled weight decay.
    learning_rate: float = 0.01
    weight_decay: float = 0.01
    # Segments per batch.
    batch_size: int = 256
    # Epochs per curriculum step at most.
    max_epochs: int = 500
    # Early stopping: epochs without a validation improvement.
    early_stopping_patience: int = 150
    # Reduce-on-plateau of the training loss: factor and patience in epochs.
    plateau_factor: float = 0.5
    plateau_patience: int = 100
    # Curriculum of horizons n_p (steps); each starts from the previous best weights.
    horizons: tuple[int, ...] = (32, 64, 128, 256)
    # Seed of the batch shuffling (the caller seeds the weight initialisation).
    seed: int = 0
    # "auto" (CUDA when present, else CPU), "cpu" or "cuda".
    device: str = "auto"
    # Checkpoint at most this often (s) within a step, and always at the end of a step.
    checkpoint_interval_s: float = 20.0
    # Clip the gradient's global norm to this value (0: no clipping). Long closed-loop
    # rollouts (DPC) can produce exploding gradients that throw the network into saturation.
    gradient_clip_norm: float = 0.0
    # Stochastic weight averaging: each curriculum step runs all its max_epochs (no early
    # stopping) and ends on the mean of the weights after each of its last `average_epochs`
    # epochs; 0: on its best validation weights. A DPC fine-tune's single epochs, which the
    # validation loss does not tell apart, differ by up to 0.1 PI on a flight in closed
    # loop, and two seeds' best epochs as much; the means of two seeds agree within 0.05
    # (docs/decisions/0038-fine-tunes-average-their-last-epochs.md).
    average_epochs: int = 0

    def validate(self) -> None:
        if min(self.batch_size, self.max_epochs) < 1 or not self.horizons:
            raise ValueError("batch_size, max_epochs and horizons must be positive / non-empty")
        if not 0 <= self.average_epochs <= self.max_epochs:
            raise ValueError(
                f"average_epochs must be in [0, max_epochs = {self.max_epochs}]; got "
                f"{self.average_epochs}"
            )
        if not (self.learning_rate > 0 and 0 < self.plateau_factor < 1):
            raise ValueError("learning_rate must be > 0 and plateau_factor in (0, 1)")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"unknown device '{self.device}'; valid: auto, cpu, cuda")

    def resolved_device(self):
        """The torch device to train on; ``auto`` takes CUDA when torch sees one."""
        import torch  # torch: the config itself is read without it (the command line)

        if self.device == "auto":
            return torch.device("cuda" if torch.cuda.is_available() else "cpu")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device 'cuda' requested but torch sees no CUDA device")
        return torch.device(self.device)


TARGETS = ("achieved", "reference")
PLANTS = ("exact", "learned")


def _default_train() -> TrainConfig:
    return TrainConfig(
        learning_rate=1e-3,
        weight_decay=0.01,
        batch_size=256,
        # n_c 256 then 1024, 400 epochs each at most: about 20 min on one core, within the
        # 30-minute training budget on 2 CPUs
        max_epochs=400,
        early_stopping_patience=100,
        plateau_patience=100,
        horizons=(256, 1024),
        gradient_clip_norm=1.0,
    )


# The shipped NMPC's weights (tuned), the DPC loss's defaults: one home, NmpcConfig.
_NMPC = NmpcConfig()


@dataclasses.dataclass
class DpcTrainingConfig:
    """DPC policy training settings (defaults: the shipped NMPC's objective, see the module
    docstring and docs/decisions/0001-tuned-objective.md; `paper()` for the paper's loss)."""

    # Targets: "reference" (the references the NMPC was given: the policy learns the
    # objective, not one solver's answers) or "achieved" (the NMPC's outputs, the paper's).
    targets: str = "reference"
    # Frozen plant of the rollouts: "exact" (the analytical torch plant, exact for the robot
    # the policy drives: docs/decisions/0008-exact-plant-for-dpc-training.md) or "learned"
    # (NODE 2 + mixed analytical, the paper's).
    plant: str = "exact"
    # With plant="learned": the mixed analytical model's best weights (a Table II run's
    # output_mixed_n256.pt).
    learned_output_weights: str = ""
    # Weight of the tracking term (paper: 1).
    tracking_weight: float = 1.0
    # Per-channel weights inside the tracking term (w_x, w_y, w_z, f_x, f_y, f_z), applied as
    # sum_k c_k (y_k - Y_k)^2: six numbers (default the NMPC's output weights), "uniform"
    # (all 1, the paper's), or "normalized" (c_k = mean variance / variance of channel k of
    # the training targets: every channel counts alike, as in the PI, whose CC term ignores
    # scale, while doing nothing costs what it costs with uniform weights).
    tracking_channel_weights: str | tuple[float, ...] = tuple(_NMPC.output_weights)
    # What the tracking term compares: "inertial" (y with the targets) or "perceived" (the
    # vestibular model's outputs of both, `mca_drake.perception`: the model of y - Y over
    # each rollout, from rest at its start).
    tracking_signals: str = _NMPC.objective
    # Vestibular model of the perceived tracking term: "telban-cardullo" or "ormsby".
    perception_model: str = _NMPC.perception_model
    # Reference preview of the policy, control periods: 0 (causal) or N, a policy that also
    # reads the reference at 4 instants over the next N periods. Rollouts read it from their
    # own targets, the last held beyond the window (a known future: offline use only), or
    # from `preview_predictor`'s forecast.
    preview_steps: int = 0
    # The forecast the preview reads in training (`mca_drake.cueing.predictor`: "linear",
    # "learned" or a model file), what the policy will read live (`DpcConfig.predictor`):
    # each flight's forecast from its own history, as the predictor runs beside the MCA,
    # mirrored with its window. "": the recorded future. Needs time_stretch_fraction 0 (a
    # stretched window's forecast is not its forecast stretched).
    preview_predictor: str = ""
    # Weight of the state-prediction term ||x_hat_(t+1) - x_(t+1)||^2 (paper: 1).
    state_estimate_weight: float = 1.0
    # Weight of ||u_t||^2, (rad/s^2)^-2: the tuned NMPC's (paper: 0.1).
    input_weight: float = _NMPC.input_weight
    # Washout weight of ||q_t||^2, rad^-2: the tuned NMPC's (paper: 1).
    washout_weight: float = _NMPC.washout_weight
    # Extra washout weight of q_1^2, rad^-2 (m^-2 for a prismatic first joint), on the first
    # joint alone (the KR500's vertical axis: no cue depends on its angle, so pulling it home
    # costs only yaw-rate error; a rail's carriage: no cue depends on where it stands). 0:
    # the first joint is washed out like the others; long turns then walk it to its limit,
    # where the viability clamp takes over.
    base_washout_weight: float = 0.0
    # Weight of the squared violation of the state limits by x_(t+1): large beside the other
    # terms (order 1), so that no tracking gain pays for leaving the limits.
    limit_weight: float = 100.0
    # Terminal cost on the rollout's last state, as the NMPC's (weights of ||q_N||^2 and
    # ||qd_N||^2): an addition to the paper's loss that teaches washout beyond n_c.
    terminal_position_weight: float = _NMPC.terminal_position_weight
    terminal_velocity_weight: float = _NMPC.terminal_velocity_weight
    # The horizon (steps) the terminal weights belong to (the NMPC's horizon_steps); a
    # rollout of n_c steps carries them times this / n_c (0: as they are). The stage costs
    # are averaged over the rollout but the terminal cost is added once, so unscaled, a
    # long rollout washes a sustained turn out faster than the NMPC does
    # (docs/decisions/0003-mirrored-windows-and-scaled-terminal-weights.md).
    terminal_weight_horizon: int = _NMPC.horizon_steps
    # Run the rollouts behind the viability clamp, as the policy runs when deployed
    # (`mca_drake.safety`); gradients pass through the clamp
    # (docs/decisions/0004-viability-clamp-in-training-rollouts.md).
    safety_filter: bool = True
    # Let gradients flow through the clamp's bounds into the state. False: the bounds are
    # constants of each step (the command's gradient passes where it is not clamped), since
    # near a limit the bounds' slopes in the state reach 1/(c h^2) = 2e4 per step and the
    # rollout gradients from far-from-neutral states overflow (same record).
    bound_gradients: bool = False
    # Fraction of each training batch whose rollouts start from the dataset's first state
    # plus uniform noise of `initial_state_noise` joint half-ranges, clipped inside the
    # limits (validation uses the dataset states). 0: on the tuned NMPC's data the perturbed
    # rollouts' losses drown the tracking of small signals
    # (docs/decisions/0009-training-windows-near-neutral.md).
    perturbed_fraction: float = 0.0
    # Noise of the perturbed starts (`perturbed_fraction`), in joint half-ranges.
    initial_state_noise: float = 0.1
    # Fraction of each training batch whose rollouts fly their window's mirror image (left
    # and right swapped: `conventions.MIRROR_CHANNEL_SIGNS`, the platform's `mirror_joint_signs`).
    # Robot and loss are symmetric, so it teaches turns and slips the other way round
    # (docs/decisions/0003-mirrored-windows-and-scaled-terminal-weights.md).
    mirror_fraction: float = 0.5
    # Fraction of each training batch whose rollouts start with the first joint (the
    # KR500's vertical axis, a rail's carriage: no cue depends on its position, checked at
    # the start of training) moved to a uniform random position within 90 % of its range,
    # so that the policy sees that joint's limits, where long turns or sustained sway walk
    # it (docs/decisions/0005-base-yaw-shifted-starts.md).
    yaw_shift_fraction: float = 0.5
    # Fraction of each training batch whose rollouts track their window's targets slowed
    # down by a uniform random factor in [1, time_stretch_max] (linear interpolation: the
    # first 10.24 / k s of the window fill the rollout). 0.5: without stretched windows the
    # policy chases a sustained pull or turn into the joint limits, which no 10.24 s rollout
    # of the flown targets shows (docs/decisions/0002-time-stretched-windows.md).
    time_stretch_fraction: float = 0.5
    # Largest slow-down factor of the stretched windows (`time_stretch_fraction`).
    time_stretch_max: float = 3.0
    # Weight of the correlation term: sum over the six channels of 1 - CC_k, with CC_k the
    # Pearson correlation of the rollouts' outputs with their targets, each window centred
    # on its own mean and the windows of a batch pooled (`pooled_correlation`). 0: the term
    # gains the PI on the jet and unseen aircraft but drives the light aircraft's flights
    # into the joint limits (docs/decisions/0006-correlation-term-off-by-default.md).
    correlation_weight: float = 0.0
    # Per-channel weights inside the correlation term (w_x, w_y, w_z, f_x, f_y, f_z):
    # sum_k c_k (1 - CC_k), times `correlation_weight`. Within a 10 s window a wide-body's
    # slow heave looks like a cue to follow; chasing it buys no heave correlation over a
    # flight and tilts the specific forces the PI counts in m/s^2, so the transports'
    # policy weighs f_z's by 0.5
    # (docs/decisions/0042-the-transports-weigh-heave-correlation-less.md).
    correlation_channel_weights: tuple[float, ...] = (1.0,) * 6
    # Weight of the posture term, rad^-2: the mean over steps of the squared distance of
    # joints 2..n from where the dataset's MCA (the NMPC) held them at the same instant (the
    # first joint, the KR500's base yaw or a rail's carriage, whose position no cue depends
    # on, is left to the washouts). 0: no term.
    # The NMPC renders a wide-body's sustained specific forces almost exactly from its
    # posture; a policy free to fly any posture renders the same outputs over a 10 s window
    # from poses that cost it the sustained forces later
    # (docs/decisions/0043-the-transports-lean-towards-the-nmpc-posture.md).
    posture_weight: float = 0.0
    # Weigh each window's tracking term by 1 / (L + floor), normalised to mean 1 over the
    # training windows, L the recorded MCA's (the dataset's NMPC's) weighted tracking cost of
    # the window without a_z (mean over steps of sum_k c_k (Y_k - target_k)^2); 0: every
    # window alike. Unweighted, a fighter's windows, whose errors no MCA avoids, outweigh a
    # transport's (the NMPC's median cost per step: 0.23 on an F-16 window, 0.005 on a
    # 787-8's), though the PI's CC prices a transport's small cues as much
    # (docs/decisions/0019-windows-weighted-by-their-achievable-cost.md).
    achievable_cost_floor: float = 0.0
    # Train and validate only on windows whose first joint positions are all within this
    # many rad of neutral (inf: all windows). The tuned NMPC's windows that start tilted far
    # out, in states the policy never visits itself, would dominate the clipped gradient;
    # 0.6 keeps about half the windows (docs/decisions/0009-training-windows-near-neutral.md).
    max_start_position_rad: float = 0.6
    # Share of the training windows (of every training flight's windows, also those
    # `max_start_position_rad` leaves out) added a second time, starting from the initial
    # policy's own closed-loop state at the window's start instead of the NMPC's: the
    # policy flies each training flight from its first state (`own_closed_loop_states`),
    # and the copies track the same targets from where it went. A policy trained only from
    # the NMPC's states never learns to come back from poses the NMPC never takes, and a
    # sustained cue can trap it at the joint limits for the rest of a flight. 0: none.
    own_start_fraction: float = 0.0
    # Train and validate only on the flights of these vehicles (the dataset's
    # `flight_vehicles`); empty: every flight. The light and transport aircraft's policy is
    # the default policy fine-tuned on theirs alone
    # (docs/decisions/0016-flight-policies-by-envelope.md).
    vehicles: tuple[str, ...] = ()
    # Train on windows of this many consecutive dataset segments (n_c up to 4 x 256 = 10.24 s;
    # `mca_drake.segments.long_windows`); 1 uses the segments and their split.
    window_segments: int = 4
    # Hidden neurons of the policy (paper: 128).
    hidden: int = 128
    # Scales of the measured and target outputs at the network's input (w_x, w_y, w_z in
    # rad/s, f_x, f_y, a_z in m/s^2; `mca_drake.learning.policy_network.OUTPUT_SCALE`). A policy
    # fine-tuned from `initial_policy` keeps that file's scales.
    output_scale: tuple[float, ...] = OUTPUT_SCALE
    # Optimiser, epochs, batch and the rollout length n_c (train.horizons, one step).
    train: TrainConfig = dataclasses.field(default_factory=_default_train)
    # Seed of the weight initialisation.
    seed: int = 0
    # The platform whose joints the policy commands: a packaged name (`mca-drake platforms`)
    # or a platform file; the dataset must have been made on it.
    platform: str = DEFAULT_PLATFORM
    # Start from the weights of this policy file (fine-tuning) instead of a random
    # initialisation; "" for a fresh policy. A policy of another platform whose joints this
    # one has too (the KR500's for the KR500 on a rail) starts the shared joints from its
    # weights and the others from zero (`policy_network.transfer_policy_network`). Ignored
    # when a run resumes from its checkpoint.
    initial_policy: str = ""
    # Fuse each rollout step with torch.compile (about 9x faster on CPU after a compile of
    # about a minute; needs a C++ compiler). False: plain eager mode.
    compile: bool = True

    @classmethod
    def matching(cls, nmpc: NmpcConfig, **changes) -> DpcTrainingConfig:
        """A config whose loss is `nmpc`'s objective: its output, input, washout and terminal
        weights, tracking the references; `changes` set other fields."""
        weights = dict(
            targets="reference",
            tracking_channel_weights=tuple(float(w) for w in nmpc.output_weights),
            tracking_signals=nmpc.objective,
            perception_model=nmpc.perception_model,
            input_weight=nmpc.input_weight,
            washout_weight=nmpc.washout_weight,
            terminal_position_weight=nmpc.terminal_position_weight,
            terminal_velocity_weight=nmpc.terminal_velocity_weight,
            terminal_weight_horizon=nmpc.horizon_steps,
        )
        return cls(**{**weights, **changes})

    @classmethod
    def paper(cls, **changes) -> DpcTrainingConfig:
        """The paper's loss (equation 9 with the NMPC's paper weights: uniform tracking of the
        NMPC-achieved outputs, input 0.1, washout 1; our terminal cost 1, 1) and the paper's
        training data (all windows, perturbed starts, none augmented), the recipe of the
        policy_v6 file; `changes` set other fields."""
        return cls.matching(
            NmpcConfig.paper(),
            **{
                "targets": "achieved",
                "bound_gradients": True,
                "output_scale": OUTPUT_SCALE_V6,
                "perturbed_fraction": 0.5,
                "max_start_position_rad": math.inf,
                "terminal_weight_horizon": 0,
                "mirror_fraction": 0.0,
                "yaw_shift_fraction": 0.0,
                "time_stretch_fraction": 0.0,
                **changes,
            },
        )

    def validate(self) -> None:
        if self.targets not in TARGETS:
            raise ValueError(f"unknown targets '{self.targets}'; valid: {', '.join(TARGETS)}")
        if self.plant not in PLANTS:
            raise ValueError(f"unknown plant '{self.plant}'; valid: {', '.join(PLANTS)}")
        if self.tracking_signals not in OBJECTIVES:
            valid = ", ".join(OBJECTIVES)
            raise ValueError(f"unknown tracking_signals '{self.tracking_signals}'; valid: {valid}")
        PerceptionConfig(model=self.perception_model).validate()
        if isinstance(self.preview_steps, bool) or self.preview_steps < 0:
            raise ValueError(f"preview_steps must be a whole number >= 0; got {self.preview_steps}")
        if self.preview_predictor:
            check_predictor(self.preview_predictor)
            if not self.preview_steps:
                raise ValueError(
                    f"preview_predictor {self.preview_predictor!r} forecasts the preview: set "
                    "preview_steps > 0"
                )
            if self.time_stretch_fraction > 0:
                raise ValueError(
                    "a forecast preview (preview_predictor) needs time_stretch_fraction 0: a "
                    "stretched window's forecast is not its forecast stretched"
                )
        weights = self.tracking_channel_weights
        if isinstance(weights, str):
            if weights not in ("uniform", "normalized"):
                raise ValueError(
                    f"tracking_channel_weights must be 'uniform', 'normalized' or six numbers;"
                    f" got '{weights}'"
                )
        elif len(weights) != 6 or not all(w >= 0 and w < float("inf") for w in weights):
            raise ValueError(f"tracking_channel_weights needs six finite numbers >= 0: {weights}")
        cc_weights = self.correlation_channel_weights
        if len(cc_weights) != 6 or not all(0 <= w < float("inf") for w in cc_weights):
            raise ValueError(
                f"correlation_channel_weights needs six finite numbers >= 0: {cc_weights}"
            )
        if not isinstance(self.platform, str) or not self.platform:
            raise ValueError(f"platform must name a platform or its file; got {self.platform!r}")
        if self.initial_policy and not Path(self.initial_policy).is_file():
            raise ValueError(f"initial_policy file not found: {self.initial_policy}")
        for name in (
            "tracking_weight",
            "state_estimate_weight",
            "input_weight",
            "washout_weight",
            "base_washout_weight",
            "limit_weight",
            "terminal_position_weight",
            "terminal_velocity_weight",
            "initial_state_noise",
            "correlation_weight",
            "posture_weight",
            "achievable_cost_floor",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0; got {value}")
        if len(self.output_scale) != 6 or not all(0 < v < float("inf") for v in self.output_scale):
            raise ValueError(f"output_scale needs six positive numbers; got {self.output_scale}")
        if self.terminal_weight_horizon < 0:
            raise ValueError(
                f"terminal_weight_horizon must be >= 0 steps; got {self.terminal_weight_horizon}"
            )
        if self.hidden < 1:
            raise ValueError(f"hidden must be at least 1 neuron; got {self.hidden}")
        if not self.max_start_position_rad > 0:
            raise ValueError(
                f"max_start_position_rad must be > 0; got {self.max_start_position_rad}"
            )
        if not (math.isfinite(self.time_stretch_max) and self.time_stretch_max >= 1.0):
            raise ValueError(f"time_stretch_max must be >= 1; got {self.time_stretch_max}")
        for name in (
            "perturbed_fraction",
            "own_start_fraction",
            "mirror_fraction",
            "yaw_shift_fraction",
            "time_stretch_fraction",
        ):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1]; got {getattr(self, name)}")
        if self.plant == "learned" and not Path(self.learned_output_weights).is_file():
            raise ValueError(
                "plant='learned' needs learned_output_weights, the mixed analytical model's "
                f"weights (output_mixed_n256.pt of `mca-drake table2`); got "
                f"'{self.learned_output_weights}'"
            )
        self.train.validate()
