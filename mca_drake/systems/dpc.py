"""DpcPolicy: the trained DPC motion-cueing policy as a discrete Drake system."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from mca_drake.conventions import CONTROL_PERIOD_S, MCA_STATISTICS
from mca_drake.cueing.dpc import (
    PolicyInference,
    check_policy_platform,
    load_policy_arrays,
    policy_preview_steps,
    preview_offsets,
)
from mca_drake.cueing.recognition import (
    RECOGNIZED_POLICIES,
    RecognitionConfig,
    handover_origin,
    initial_recognition_state,
    policy_changes,
    policy_weights,
    recognition_final,
    recognition_step,
    recognized_policy,
)
from mca_drake.cueing.reference_range import policy_reference_range
from mca_drake.platforms.clamp import platform_clamp
from mca_drake.platforms.serial import SerialChain
from mca_drake.systems.mca_update import DeclareMcaUpdate


class DpcPolicy(LeafSystem):
    """The DPC policy (paper eq. 11) with the viability clamp on its command.

    .. pydrake_system::

        name: DpcPolicy
        input_ports:
        - reference
        - state
        - inertial_output
        - reference_preview (optional)
        output_ports:
        - joint_acceleration
        - statistics

    Every `time_step` an unrestricted update reads the reference Y_t (6), the state
    x_t = [q, qd] (2n for the platform's n joints) and the measured output y_t (6), evaluates
    the network in numpy (weights exported from torch, `mca_drake.cueing.dpc`), clamps u_t
    into the viability interval of the true joint limits (`mca_drake.safety.ViabilityClamp`:
    the robot can always brake inside its limits) and stores it; `joint_acceleration`
    outputs it, so the command computed from x_n acts from t_n (like NmpcController).
    `statistics` has the layout of `mca_drake.conventions.MCA_STATISTICS`: step time (s),
    0 solver failures, safety interventions, 0 QP iterations.

    Args:
        policy: a policy file (`mca_drake.learning.policy_network.save_policy`) or its arrays.
        robot: the platform the policy was trained for (the clamp's limits); a policy file
            trained for another is refused (`cueing.dpc.check_policy_platform`).
        time_step: control period, s.
        update_event: the phase of t_k the step runs in (`mca_update.MCA_UPDATE_EVENTS`):
            "unrestricted" offline, "discrete" in the live loop (after its telemetry poll).
        preview_steps: the reference preview of a policy given as arrays (a file says its
            own).
        recognized: the policies the recognizer chooses between
            (`cueing.recognition.RECOGNIZED_POLICIES`, files or arrays in its order, the
            default first; `policy` is then not read): the vehicle of an unnamed reference
            is recognized from the reference as it goes and each change of policy handed
            over smoothly (`recognition.policy_weights`). None: `policy` throughout.
        recognition: the recognizer's settings (default `RecognitionConfig()`).
        first_policy: with `recognized`, the index of the policy it starts in: 0, the
            default; a named light aircraft's or transport's (`DpcConfig.first_policy`),
            handed back to the default once the reference leaves its envelope
            (`recognition.initial_recognition_state`).
        range_clip: each policy file's network reads the reference clipped into the range
            of the references it was trained on (`cueing.reference_range`;
            `DpcConfig.range_clip`); a policy given as arrays, or without a range, reads it
            as it is.
        predictor: the forecast a policy with a preview reads (`DpcConfig.predictor`:
            "linear", "learned" or a model file), which the diagram feeds to
            `reference_preview` (`systems.predictor.AddReferencePredictor`); "": the
            recorded future, or none for a causal policy.
    """

    def __init__(
        self,
        policy: str | Path | dict,
        robot: SerialChain,
        time_step: float = CONTROL_PERIOD_S,
        update_event: str = "unrestricted",
        preview_steps: int = 0,
        recognized: tuple | None = None,
        recognition: RecognitionConfig | None = None,
        first_policy: int = 0,
        range_clip: bool = False,
        predictor: str = "",
    ):
        super().__init__()
        self._robot = robot
        self._time_step = time_step
        if recognized is None:
            self._inference, preview_steps = _inference(policy, robot, preview_steps, range_clip)
            self._inferences = None
        else:
            if len(recognized) != len(RECOGNIZED_POLICIES):
                raise ValueError(
                    f"recognized: {len(RECOGNIZED_POLICIES)} policies "
                    f"({', '.join(RECOGNIZED_POLICIES)}); got {len(recognized)}"
                )
            loaded = [_inference(p, robot, preview_steps, range_clip) for p in recognized]
            if len({steps for _, steps in loaded}) > 1:
                raise ValueError("the recognized policies must share one reference preview")
            self._inferences = [inference for inference, _ in loaded]
            self._inference, preview_steps = loaded[0]
            self._recognition = recognition or RecognitionConfig()
            self._recognition.validate()
        n = robot.num_joints
        # a policy with a preview reads the reference at its offsets ahead, from a preview
        # of offsets[-1] + 1 samples (the current one first)
        self._offsets = preview_offsets(preview_steps) if preview_steps else None
        if predictor and self._offsets is None:
            raise ValueError(
                f"predictor {predictor!r} forecasts a preview, but the policy reads none: "
                "run a policy trained with a preview (train-policy --preview-steps)"
            )
        self._predictor = predictor
        self._preview_port = None
        if self._offsets is not None:
            self._preview_port = self.DeclareVectorInputPort(
                "reference_preview", 6 * self.preview_samples
            )
        self._clamp = platform_clamp(self._robot, time_step)
        self._reference_port = self.DeclareVectorInputPort("reference", 6)
        self._state_port = self.DeclareVectorInputPort("state", 2 * n)
        self._output_port = self.DeclareVectorInputPort("inertial_output", 6)
        self._command_index = self.DeclareDiscreteState(n)
        self._statistics_index = self.DeclareDiscreteState(len(MCA_STATISTICS))
        self._recognition_index = None
        if self._inferences is not None:
            self._recognition_index = self.DeclareDiscreteState(
                np.array(initial_recognition_state(first_policy))
            )
        DeclareMcaUpdate(self, time_step, self._update, update_event)
        self.DeclareStateOutputPort("joint_acceleration", self._command_index)
        self.DeclareStateOutputPort("statistics", self._statistics_index)

    @property
    def preview_samples(self) -> int:
        """Samples of `reference_preview` the policy reads (0: causal, no such port)."""
        return 0 if self._offsets is None else int(self._offsets[-1]) + 1

    @property
    def predictor(self) -> str:
        """The forecast its preview reads ("": the recorded future, or no preview)."""
        return self._predictor

    def statistics(self, context: Context) -> dict[str, float]:
        """The `statistics` values in `context`, by name."""
        values = context.get_discrete_state(self._statistics_index).value()
        return dict(zip(MCA_STATISTICS, (float(v) for v in values), strict=True))

    def policy_changes(self, context: Context) -> list[tuple[float, int]]:
        """The changes of policy so far, (time s, index in RECOGNIZED_POLICIES) each
        (`recognition.policy_changes`); [] for a DPC that runs one policy."""
        if self._recognition_index is None:
            return []
        return policy_changes(context.get_discrete_state(self._recognition_index).value())

    def _recognize(self, discrete, reference) -> tuple | None:
        """Steps the recognizer on the reference sample; its `policy_weights` and
        `handover_origin` (None for a DPC that runs one policy)."""
        if self._inferences is None:
            return None
        state = discrete.get_value(self._recognition_index).tolist()
        if recognition_final(state, self._recognition):
            return recognized_policy(state), -1, 1.0, (-1, 1.0)
        recognition_step(state, reference.tolist(), self._time_step, self._recognition)
        discrete.set_value(self._recognition_index, np.array(state))
        return (*policy_weights(state, self._recognition), handover_origin(state))

    def _command(self, weights, y, x, reference, preview) -> list[float]:
        """The command for these inputs: the one policy's, or (with the recognizer's
        `weights`) the recognized one's, blended with the one it takes over from while the
        hand-over lasts (with that one's own hand-over, where the change came during it)."""
        if weights is None:
            return self._inference.command(y, x, reference, preview)
        policy, previous, weight, origin = weights
        u = self._inferences[policy].command(y, x, reference, preview)
        if previous < 0:
            return u
        old = self._inferences[previous].command(y, x, reference, preview)
        outer, outer_weight = origin
        if outer >= 0:  # the change came during a hand-over: from the blend it had reached
            first = self._inferences[outer].command(y, x, reference, preview)
            old = [a + outer_weight * (b - a) for a, b in zip(first, old, strict=True)]
        return [a + weight * (b - a) for a, b in zip(old, u, strict=True)]

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        x = self._state_port.Eval(context)
        y = self._output_port.Eval(context)
        reference = self._reference_port.Eval(context)
        preview = ()
        if self._preview_port is not None:
            rows = self._preview_port.Eval(context).reshape(-1, 6)
            preview = rows[self._offsets].reshape(-1)
        # Timed from here: evaluating the inputs computes upstream systems (the plant's
        # output), which is simulation, not this MCA's work.
        start = time.perf_counter()
        weights = self._recognize(discrete, reference)
        u = self._command(weights, y, x, reference, preview)
        # NaN from the network says an input is not finite (or it overflowed): only then are
        # the inputs checked one by one
        if not math.isfinite(u[0]):
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(reference))):
                raise RuntimeError(
                    f"DpcPolicy: non-finite state or reference at t = {context.get_time()} s"
                )
            if not np.all(np.isfinite(y)):
                # a dropped IMU sample: the policy still sees state and target
                u = self._command(weights, np.zeros(6), x, reference, preview)
            # else the network overflowed on huge inputs: the clamp brakes on NaN
        command, intervened = self._clamp(x, u)
        # from `discrete`, which holds the current values on entry (DeclareMcaUpdate): one
        # pybind call fewer than through the context (1.6 against 2.6 us on a loaded core)
        stats = discrete.get_value(self._statistics_index)
        discrete.set_value(self._command_index, command)
        # an array, not a list: pybind's conversion of a list costs 1-2 us of the budget
        discrete.set_value(
            self._statistics_index,
            np.array((time.perf_counter() - start, 0.0, stats[2] + intervened, 0.0)),
        )


def _inference(
    policy, robot: SerialChain, preview_steps: int, range_clip: bool = False
) -> tuple[PolicyInference, int]:
    """(the inference, its reference preview in periods) of a policy file (checked against
    `robot`; with `range_clip`, reading the reference clipped into its range) or arrays
    (whose preview is `preview_steps`)."""
    ranges = None
    if isinstance(policy, str | Path):
        arrays, metadata = load_policy_arrays(policy)
        check_policy_platform(policy, metadata, robot.name)
        preview_steps = policy_preview_steps(metadata)
        if range_clip:
            ranges = policy_reference_range(policy, metadata)
    else:
        arrays, preview_steps = policy, int(preview_steps)
    inference = PolicyInference(arrays, ranges)
    if inference.joints != robot.num_joints:
        raise ValueError(
            f"the DPC policy commands {inference.joints} joints, platform '{robot.name}' has "
            f"{robot.num_joints}"
        )
    return inference, preview_steps


__all__ = ["DpcPolicy"]
