"""NmpcController: the NMPC motion cueing algorithm as a Drake system."""

from __future__ import annotations

import time

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from mca_drake.conventions import MCA_STATISTICS, NUM_CHANNELS
from mca_drake.cueing.nmpc import MotionCueingOcp, NmpcConfig
from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.kinematics import plant_output
from mca_drake.platforms.serial import SerialChain
from mca_drake.systems.mca_update import DeclareMcaUpdate


class NmpcController(LeafSystem):
    """NMPC motion cueing (see `mca_drake.cueing.nmpc` for the optimal control problem).

    .. pydrake_system::

        name: NmpcController
        input_ports:
        - state
        - reference
        - reference_preview (optional)
        output_ports:
        - joint_acceleration
        - statistics

    Every `config.time_step` an unrestricted update reads `state` x = [q, qd] (12) and the
    reference (6), solves the OCP warm-started from the shifted previous plan and hot-started
    from the previous active set (both kept in the context), and stores the first input u_0
    (rad/s^2, 6), which `joint_acceleration` outputs. The update runs before the plant's
    discrete update at the same instant, so the command computed from x_n is applied at t_n
    (no extra delay). Over the horizon the reference is held constant (causal, the default)
    or, when `reference_preview` is connected, read from the preview at each grid node
    (clamped to the preview's end). With the perceived objective (`NmpcConfig.objective`),
    the state also holds the vestibular model's state of the perceived output minus the
    perceived reference, advanced every step with the output of the applied command against
    the reference (the OCP starts each solve from it). A failed solve falls back to the
    shifted previous plan. Whatever the plan, the command passes the viability clamp of
    `mca_drake.safety` (the robot can always brake inside its limits); failures and clamp
    interventions are counted and the output is never NaN.

    `statistics` (4) holds MCA_STATISTICS: the wall-clock time of the last control step (s) and
    running counts of solver failures, safety-filter interventions and QPs solved; log it to get the
    per-step times. The plan (the next warm start) is discrete state too, so contexts can be
    cloned and diagrams run in parallel.

    Args:
        config: NMPC settings (mode "rti" or "converged", horizon, weights, QP solver).
        robot: the platform (n joints).
        preview_samples: length N of the `reference_preview` port (6 N values, sample after
            sample); 0 declares no preview port; default `config.preview_steps`.
        update_event: the phase of t_k the step runs in (`mca_update.MCA_UPDATE_EVENTS`):
            "unrestricted" offline, "discrete" in the live loop (after its telemetry poll).
    """

    def __init__(
        self,
        config: NmpcConfig | None,
        robot: SerialChain,
        preview_samples: int | None = None,
        update_event: str = "unrestricted",
    ):
        super().__init__()
        self._ocp = MotionCueingOcp(config, robot)
        self._clamp = platform_clamp(self._ocp.robot, self._ocp.config.time_step)
        self._config = self._ocp.config
        if preview_samples is None:
            preview_samples = self._config.preview_steps
        self._preview_samples = int(preview_samples)
        self._n = n = self._ocp.nu
        self._state_port = self.DeclareVectorInputPort("state", 2 * n)
        self._reference_port = self.DeclareVectorInputPort("reference", NUM_CHANNELS)
        self._preview_port = None
        if self._preview_samples > 0:
            self._preview_port = self.DeclareVectorInputPort(
                "reference_preview", NUM_CHANNELS * self._preview_samples
            )
        self._command_index = self.DeclareDiscreteState(n)
        self._plan_index = self.DeclareDiscreteState(self._ocp.N * n)
        # The last QP's active set (-1, 0, +1 per row): the next step's hot start. State, not
        # a cache, so that a run's result never depends on what the system solved before.
        self._active_index = self.DeclareDiscreteState(self._ocp.num_rows)
        # converged mode: the output Hessians at the plan's nodes (`output_curvature`), the
        # next step's start; all zeros (the initial state) means none: finite differences.
        self._hessians_index = None
        if self._config.mode == "converged":
            self._hessians_shape = (self._ocp.N, NUM_CHANNELS, 3 * n, 3 * n)
            self._hessians_index = self.DeclareDiscreteState(int(np.prod(self._hessians_shape)))
        # perceived objective: the vestibular model's state of perceived y minus perceived r
        # (`MotionCueingOcp.perceived_references`), advanced with each applied command
        self._perception_index = None
        if self._ocp.perception_filter is not None:
            size = self._ocp.perception_filter.num_states
            self._perception_index = self.DeclareDiscreteState(size)
        self._statistics_index = self.DeclareDiscreteState(len(MCA_STATISTICS))
        DeclareMcaUpdate(self, self._config.time_step, self._update, update_event)
        self._command_port = self.DeclareStateOutputPort("joint_acceleration", self._command_index)
        self._statistics_port = self.DeclareStateOutputPort("statistics", self._statistics_index)

    @property
    def config(self) -> NmpcConfig:
        """The settings it runs."""
        return self._config

    @property
    def preview_samples(self) -> int:
        """Samples of `reference_preview` it reads (0: causal, no such port)."""
        return self._preview_samples

    @property
    def predictor(self) -> str:
        """The forecast its preview reads (`NmpcConfig.predictor`; "": the recorded
        future, or none for a causal NMPC)."""
        return self._config.predictor

    @property
    def ocp(self) -> MotionCueingOcp:
        """The optimal control problem this controller solves."""
        return self._ocp

    def statistics(self, context: Context) -> dict[str, float]:
        """The controller's `statistics` in its `context`, by name."""
        values = context.get_discrete_state(self._statistics_index).value()
        return dict(zip(MCA_STATISTICS, (float(v) for v in values), strict=True))

    def perception_state(self, context: Context) -> np.ndarray | None:
        """The perceived objective's state in `context`: the vestibular model's state of the
        perceived output minus the perceived reference (`MotionCueingOcp.perception_filter`),
        shape (n,); None for the inertial objective."""
        if self._perception_index is None:
            return None
        return context.get_discrete_state(self._perception_index).value().copy()

    def _node_references(self, context: Context) -> np.ndarray:
        reference = self._reference_port.Eval(context)
        if self._preview_port is not None and self._preview_port.HasValue(context):
            preview = self._preview_port.Eval(context).reshape(self._preview_samples, 6)
            rows = np.minimum(self._ocp.node_steps[:-1], self._preview_samples - 1)
            return preview[rows]
        return np.broadcast_to(reference, (self._ocp.N, 6))

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        x = self._state_port.Eval(context)
        refs = self._node_references(context)
        # Timed from here: evaluating the inputs computes upstream systems (the plant's
        # output), which is simulation, not this MCA's work.
        start = time.perf_counter()
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(refs))):
            raise RuntimeError(
                f"NmpcController: non-finite state or reference at t = {context.get_time()} s"
            )
        plan = context.get_discrete_state(self._plan_index).value().reshape(-1, self._n)
        _, failures, interventions, iterations = context.get_discrete_state(
            self._statistics_index
        ).value()
        warm = self._ocp.shift(plan)
        active = context.get_discrete_state(self._active_index).value()
        hessians = None
        if self._hessians_index is not None:
            stored = context.get_discrete_state(self._hessians_index).value()
            if np.any(stored):
                hessians = self._ocp.shift_output_hessians(stored.reshape(self._hessians_shape))
        perception = None
        if self._perception_index is not None:
            perception = context.get_discrete_state(self._perception_index).value()
        result = self._ocp.solve(
            x,
            refs,
            U_guess=warm,
            active_guess=active,
            output_hessians=hessians,
            perception_state=perception,
        )
        plan = result.U
        if not result.success:
            failures += 1
            plan = warm  # the shifted previous plan; its u_0 is made viable below
        # Safety filter: u_0 into the exact viability interval of the true limits (the QP
        # already plans inside slightly tighter ones; this catches solver tolerances and
        # failures).
        command, intervened = self._clamp(x, plan[0])
        interventions += intervened
        discrete.set_value(self._command_index, command)
        discrete.set_value(self._plan_index, plan.reshape(-1))
        if result.active is not None:
            discrete.set_value(self._active_index, result.active.astype(float))
        if self._hessians_index is not None and result.output_hessians is not None:
            discrete.set_value(self._hessians_index, result.output_hessians.reshape(-1))
        if perception is not None:
            # the error the occupant's model integrates over this period: the output the
            # command makes now against the reference now
            f = self._ocp.perception_filter
            error = plant_output(x[: self._n], x[self._n :], command, self._ocp.robot)
            error = error - refs[0]
            discrete.set_value(self._perception_index, f.A @ perception + f.B @ error)
        step_time = time.perf_counter() - start
        discrete.set_value(
            self._statistics_index,
            [step_time, failures, interventions, iterations + result.iterations],
        )
