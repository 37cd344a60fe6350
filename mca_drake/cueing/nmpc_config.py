"""NmpcConfig, the NMPC's typed settings: importable without Drake, so that the torch
training path (whose loss defaults to the NMPC's objective) runs where pydrake is not
installed. The solver that reads it is `mca_drake.cueing.nmpc`.
"""

import dataclasses

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing.predictor import check_predictor
from mca_drake.input_checks import check_config_numbers
from mca_drake.perception.models import PerceptionConfig
from mca_drake.resources import check_profile

QP_SOLVERS = ("auto", "clarabel", "osqp")
MODES = ("rti", "converged")
OBJECTIVES = ("inertial", "perceived")


@dataclasses.dataclass
class NmpcConfig:
    """NMPC settings; the weights default to tuned ones, `paper()` gives equation 9's."""

    # Solve mode: "rti" (one Gauss-Newton QP per step) or "converged" (iterate to tolerance).
    mode: str = "rti"
    # Control period, s; must equal the period of the reference it cues.
    time_step: float = CONTROL_PERIOD_S
    # Prediction horizon in control periods (256 x 0.01 s = 2.56 s, the paper's).
    horizon_steps: int = 256
    # Number of intervals of the non-uniform grid over the horizon.
    nodes: int = 20
    # Reference preview in control periods: 0 (causal, the default) holds the current
    # reference over the horizon; N > 0 reads the next N samples of a known future (a planned
    # manoeuvre, a recorded flight) at the grid's nodes, the last held beyond them. Offline
    # only: live telemetry has no future.
    preview_steps: int = 0
    # A forecast as the preview (`mca_drake.cueing.predictor`): "" none (the known future
    # above, or the current reference held); "constant" (the current reference held, the
    # causal NMPC's assumption, as a forecast), "linear" (the packaged linear model fitted
    # on training flights and drives), "learned" (the packaged linear model corrected by a
    # network trained on the same references) or a model file (.npz). With a predictor,
    # preview_steps is the forecast's length; it reads only the past, so it runs live too.
    predictor: str = ""
    # The weights below are tuned (the paper's are `NmpcConfig.paper()`):
    #   mca-drake tune --mca nmpc-rti --trials 30 --duration 120 --workers 2 --budget-ms 10
    #       --vehicles light,jet --seeds 100,101,102 --seed 3
    # on 2026-11-25 with the false-rotation limit (5 deg/s RMS, median over the flights) and
    # the rotation weights searched up to 300: median PI -1.426 against the paper's -0.623 on
    # those six 120 s training flights, false rotation 2.5-6.9 deg/s RMS (the paper's 3.4-36).
    # The limit is there because weights tuned on the PI alone swing the cabin for
    # centripetal heave (docs/decisions/0007-nmpc-tuning-limits-false-rotation.md).
    # Weights of the six output channels (w_x, w_y, w_z, f_x, f_y, a_z) in ||y - r||^2.
    output_weights: list[float] = dataclasses.field(
        default_factory=lambda: [
            11.013867387902454,
            3.4972321849326713,
            232.6481788794929,
            6.801348895846307,
            7.8920753051790085,
            0.2642331791643142,
        ]
    )
    # What the output weights weigh: "inertial" (y - r, equation 9) or "perceived" (the
    # vestibular model's outputs of y against those of r, `mca_drake.perception`).
    objective: str = "inertial"
    # Vestibular model of the perceived objective: "telban-cardullo" or "ormsby".
    perception_model: str = "telban-cardullo"
    # Weight of ||u||^2 (rad/s^2)^-2.
    input_weight: float = 0.0018886712789807029
    # Washout weight on ||q||^2.
    washout_weight: float = 0.010437789341785185
    # Terminal weights on ||q_N||^2 and ||qd_N||^2.
    terminal_position_weight: float = 0.3110176946021279
    terminal_velocity_weight: float = 0.14967150221404674
    # Tangents per side and joint approximating the stoppability parabola at the later nodes.
    # Two tangents are enough: u_0 is held to the exact viability interval anyway, the
    # tangents only keep the later plan realistic, and each costs 12 rows per node.
    stoppability_tangents: int = 2
    # Legged platforms (hexapods, rigs): plan within the legs' stroke and speed, linearised
    # about the plan at every Gauss-Newton iteration at the nodes after the first
    # (`mca_drake.cueing.nmpc_legs`). Off, the plan sees only the coordinates' box and the
    # viability clamp alone holds the legs. Ignored on serial robots.
    leg_constraints: bool = True
    # Corrections of a guessed active set (every offending row changed at once) before the
    # dual active-set method (`mca_drake.qp.dual_active_set`) takes the QP from the
    # guess's dual-feasible part. None: 0 in both modes. Each correction is one KKT solve
    # (0.1 to 1 ms with many active rows) that often fails where many rows change, while the
    # dual method always ends, exactly: on a 300 s light flight at the tuned weights, rti's
    # QP p99 is 2.1 ms with 0 corrections, 2.9 with 1; on the 3 g heave step, converged's
    # worst step is 144 ms with 0, 290 with 20.
    active_set_corrections: int | None = None
    # Drake's QP solver where the hot-started active set does not settle: "clarabel"
    # (interior point, accurate), "osqp" (ADMM with solution polishing, fast) or "auto"
    # (osqp for rti, clarabel for converged).
    qp_solver: str = "auto"
    # OSQP's absolute and relative tolerance (polishing then recovers the active set); rti
    # takes a single approximate Gauss-Newton step, so 1e-3 loses nothing measurable there.
    osqp_tolerance: float = 1e-3
    # OSQP iteration cap: bounds the worst-case step time. A capped solution is still used in
    # rti (the viability clamp guards the command); 0 means 20000.
    osqp_max_iterations: int = 400
    # Clarabel's gap and feasibility tolerances: tight, so that the active set is exact and
    # the converged mode stops at a KKT point of the nonlinear program.
    clarabel_tolerance: float = 1e-10
    # The plan keeps this fraction of every limit in reserve (positions: of the range), so
    # that solver tolerances never turn into limit violations.
    limit_margin: float = 1e-3
    # converged mode: maximum Gauss-Newton iterations, and the stop when the largest change
    # of u in an iteration falls below step_tolerance (rad/s^2).
    max_iterations: int = 50
    step_tolerance: float = 1e-6
    # converged mode: stop at a KKT point of the nonlinear program, once the stationarity
    # residual |grad f(U) + C^T lambda|_inf (cost units per rad/s^2) is below this times
    # max(1, cost), with U feasible and complementary to lambda >= 0 (both exact, from a
    # verified QP solution). On a 30 s light flight 1e-7 gave the PI of 1e-9 to five
    # decimals in 11 % less time; 1e-6 moved it by 2e-5.
    kkt_tolerance: float = 1e-7
    # converged mode: after a full step that the line search rejected (the Gauss-Newton
    # model overshot), the next QPs take Marquardt's damping H + mu diag(H) (`_next_damping`):
    # on a 3 g surge step the worst step takes 0.12 s with it and 0.29 s without, and steps
    # that stop at the iteration cap far from a KKT point without it reach one. The damping
    # does not change the stopping test.
    marquardt_damping: bool = True
    # The shipped profile (`mca_drake.cueing.profiles`: "ground" for cars) these settings
    # are, set by asking for it by name ("nmpc-rti-ground"); it names the MCA in summaries
    # and reports. "": the flight defaults above.
    profile: str = ""

    @classmethod
    def paper(cls, mode: str = "rti") -> "NmpcConfig":
        """The paper's weights (equation 9: tracking 1 per channel, input 0.1, washout 1 on
        ||q||^2, terminal 1 and 1), whatever the defaults: the reproduction's baseline."""
        return cls(
            mode=mode,
            output_weights=[1.0] * 6,
            input_weight=0.1,
            washout_weight=1.0,
            terminal_position_weight=1.0,
            terminal_velocity_weight=1.0,
        )

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        check_profile(self.profile)
        if self.mode not in MODES:
            raise ValueError(f"unknown NMPC mode '{self.mode}'; valid: {', '.join(MODES)}")
        if self.objective not in OBJECTIVES:
            valid = ", ".join(OBJECTIVES)
            raise ValueError(f"unknown NMPC objective '{self.objective}'; valid: {valid}")
        PerceptionConfig(model=self.perception_model).validate()
        if self.qp_solver not in QP_SOLVERS:
            valid = ", ".join(QP_SOLVERS)
            raise ValueError(f"unknown QP solver '{self.qp_solver}'; valid: {valid}")
        if min(self.osqp_max_iterations, self.stoppability_tangents) < 0:
            raise ValueError("osqp_max_iterations and stoppability_tangents must be >= 0")
        if self.active_set_corrections is not None and self.active_set_corrections < 0:
            raise ValueError("active_set_corrections must be >= 0 (or None: by mode)")
        if not 0 <= self.preview_steps <= self.horizon_steps:
            raise ValueError(
                f"preview_steps must be in [0, horizon_steps = {self.horizon_steps}]; got "
                f"{self.preview_steps}"
            )
        check_predictor(self.predictor)
        if self.predictor and not self.preview_steps:
            raise ValueError(
                f"predictor {self.predictor!r} forecasts preview_steps samples: set preview_steps "
                f"(horizon_steps = {self.horizon_steps} for the whole horizon)"
            )
        if self.horizon_steps < 1 or self.max_iterations < 1:
            raise ValueError("horizon_steps and max_iterations must be at least 1")
        tolerances = (
            self.osqp_tolerance,
            self.clarabel_tolerance,
            self.step_tolerance,
            self.kkt_tolerance,
        )
        if min(tolerances) <= 0:
            raise ValueError(
                "osqp_tolerance, clarabel_tolerance, step_tolerance and kkt_tolerance must be > 0"
            )
        if not 1 <= self.nodes <= self.horizon_steps:
            raise ValueError(f"nodes must be in [1, horizon_steps]; got {self.nodes}")
        if len(self.output_weights) != 6 or min(self.output_weights) < 0:
            raise ValueError("output_weights must be six non-negative values")
        if min(self.input_weight, self.washout_weight) < 0 or not self.time_step > 0:
            raise ValueError("weights must be non-negative and time_step positive")
