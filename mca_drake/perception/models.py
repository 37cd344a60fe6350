"""Vestibular models: the transfer functions of the semicircular canals and the otoliths.

The canals sense angular velocity w (rad/s) and the otoliths specific force f (m/s^2), each
per head axis, as linear filters; the perceived signal is the filter's output in the same
units. Two published parameter sets are kept, each under its name in `VESTIBULAR_MODELS`:

- "telban-cardullo" (the default; Telban & Cardullo 2005, NASA CR-2005-213747, the models of
  their human-centred motion-cueing algorithms and of Bruschetta et al.'s 2016 NMPC for a
  driving simulator):

      canal    w_hat / w = tau_a tau_L s^2 / ((tau_a s + 1)(tau_L s + 1)(tau_S s + 1)),
               tau_L = 5.73 s, tau_S = 0.005 s, tau_a = 80 s (mid-band gain 1);
      otolith  f_hat / f = K (tau_a s + 1) / ((tau_L s + 1)(tau_S s + 1)),
               K = 0.4, tau_a = 10 s, tau_L = 5 s, tau_S = 0.016 s (gain 0.4 at DC, 0.8
               between 0.2 and 60 rad/s).

- "ormsby" (Ormsby 1974, the afferent-firing models of MPI's offline motion simulation
  framework, in which offline optimal cueing was rated best by drivers):

      canal    w_hat / w = tau_A tau_L s^2 (tau_R s + 1)
                           / ((tau_A s + 1)(tau_L s + 1)(tau_S s + 1)),
               tau_A = 30 s, tau_L = 18 s, tau_S = 0.005 s, tau_R = 0.01 s;
      otolith  f_hat / f = (s + 0.1) / (s + 0.2) = 0.5 (10 s + 1) / (5 s + 1).

  Ormsby's models give firing rates: the canal 6300 tau_S = 31.5 impulses/s per rad/s at
  mid-band, the otolith 90 impulses/s per g at high frequency. Here both are divided by that
  sensitivity, so that they output perceived signals in the input's units (mid-band gain 1)
  and the two models' errors compare on the same scale.

The canal is a band-pass: a constant rotation is felt at first and fades (time constant
tau_L, then the adaptation tau_a), which is why a simulator can wash a sustained rotation out.
The otolith passes a constant specific force (gain K at DC): it cannot tell a tilt (gravity
along the head's x axis) from a sustained acceleration, which is why tilt coordination works.

Every model here is a `TransferFunction` of a single axis; `mca_drake.perception.filters`
discretises it exactly at the control period and stacks the six channels of y.
"""

import dataclasses

import numpy as np

from mca_drake.input_checks import check_config_numbers
from mca_drake.metrics import ROTATION_THRESHOLD_RAD_S, SPECIFIC_FORCE_THRESHOLD_M_S2


@dataclasses.dataclass(frozen=True)
class TransferFunction:
    """A rational transfer function numerator(s) / denominator(s) of one input and output.

    Attributes:
        numerator: polynomial coefficients in s, highest power first (scipy.signal's order).
        denominator: the same for the denominator; its degree is at least the numerator's.
    """

    numerator: tuple[float, ...]
    denominator: tuple[float, ...]

    def __post_init__(self):
        num = np.trim_zeros(np.asarray(self.numerator, float), "f")
        den = np.trim_zeros(np.asarray(self.denominator, float), "f")
        if den.size == 0 or not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
            raise ValueError(f"transfer function needs finite coefficients; got {self}")
        if num.size > den.size:
            raise ValueError(f"transfer function must be proper; got {self}")
        # plain floats, trimmed: the realisation's order is the denominator's degree
        object.__setattr__(self, "numerator", tuple(float(c) for c in num) or (0.0,))
        object.__setattr__(self, "denominator", tuple(float(c) for c in den))

    def frequency_response(self, omega) -> np.ndarray:
        """H(j omega) at the angular frequencies `omega` (rad/s), complex, omega's shape."""
        s = 1j * np.asarray(omega, dtype=float)
        return np.polyval(self.numerator, s) / np.polyval(self.denominator, s)

    def dc_gain(self) -> float:
        """H(0): the steady-state gain to a constant input (0 for a band-pass)."""
        return float(self.numerator[-1] / self.denominator[-1])

    def poles(self) -> np.ndarray:
        """The roots of the denominator, rad/s (negative real parts: stable)."""
        return np.roots(self.denominator)


def canal(tau_l: float, tau_a: float, tau_s: float = 0.0, tau_r: float = 0.0) -> TransferFunction:
    """Semicircular canal with adaptation, mid-band gain 1:
    tau_a tau_L s^2 (tau_R s + 1) / ((tau_a s + 1)(tau_L s + 1)(tau_S s + 1)).

    Args:
        tau_l: the cupula's long time constant, s (a constant rotation fades with it).
        tau_a: adaptation time constant, s.
        tau_s: the cupula's short time constant, s (0: left out).
        tau_r: rate-sensitivity lead time constant, s (0: left out).
    """
    numerator = np.polymul([tau_a * tau_l, 0.0, 0.0], [tau_r, 1.0])
    denominator = np.polymul(np.polymul([tau_a, 1.0], [tau_l, 1.0]), [tau_s, 1.0])
    return TransferFunction(
        tuple(np.trim_zeros(numerator, "f")), tuple(np.trim_zeros(denominator, "f"))
    )


def otolith(gain: float, tau_a: float, tau_l: float, tau_s: float) -> TransferFunction:
    """Otolith: gain (tau_a s + 1) / ((tau_L s + 1)(tau_S s + 1)).

    Args:
        gain: steady-state (DC) gain, (m/s^2) / (m/s^2).
        tau_a: lead time constant, s.
        tau_l: long lag time constant, s.
        tau_s: short lag time constant, s (0: left out).
    """
    denominator = np.polymul([tau_l, 1.0], [tau_s, 1.0])
    return TransferFunction((gain * tau_a, gain), tuple(np.trim_zeros(denominator, "f")))


@dataclasses.dataclass(frozen=True)
class VestibularModelParameters:
    """One published vestibular model: a canal and an otolith transfer function (the same
    on every head axis) and where they come from."""

    name: str
    canal: TransferFunction
    otolith: TransferFunction
    source: str


TELBAN_CARDULLO = VestibularModelParameters(
    name="telban-cardullo",
    canal=canal(tau_l=5.73, tau_a=80.0, tau_s=0.005),
    otolith=otolith(gain=0.4, tau_a=10.0, tau_l=5.0, tau_s=0.016),
    source=(
        "Telban, R. J. and Cardullo, F. M. (2005), Motion cueing algorithm development: "
        "human-centered linear and nonlinear approaches, NASA CR-2005-213747"
    ),
)

ORMSBY = VestibularModelParameters(
    name="ormsby",
    canal=canal(tau_l=18.0, tau_a=30.0, tau_s=0.005, tau_r=0.01),
    otolith=otolith(gain=0.5, tau_a=10.0, tau_l=5.0, tau_s=0.0),
    source=(
        "Ormsby, C. C. (1974), Model of human dynamic orientation, PhD thesis, "
        "Massachusetts Institute of Technology; parameters as in Katliar et al.'s offline "
        "motion simulation framework (MPI for Biological Cybernetics)"
    ),
)

# The models a `PerceptionConfig` can name.
VESTIBULAR_MODELS = {m.name: m for m in (TELBAN_CARDULLO, ORMSBY)}


@dataclasses.dataclass
class PerceptionConfig:
    """What the occupant perceives: the vestibular model and the perception thresholds."""

    # Vestibular model, by name: "telban-cardullo" (Telban & Cardullo 2005) or "ormsby"
    # (Ormsby 1974); see `mca_drake.perception.models`.
    model: str = "telban-cardullo"
    # Perception thresholds of rotation about the head's x, y and z axes, rad/s (Reid & Nahon
    # 1985: 3.0, 3.6 and 2.6 deg/s): a perceived rotation error below them is not felt.
    rotation_thresholds: list[float] = dataclasses.field(
        default_factory=lambda: list(ROTATION_THRESHOLD_RAD_S)
    )
    # Perception thresholds of specific force along the head's x, y and z axes, m/s^2 (Reid &
    # Nahon 1985: 0.17, 0.17 and 0.28).
    specific_force_thresholds: list[float] = dataclasses.field(
        default_factory=lambda: list(SPECIFIC_FORCE_THRESHOLD_M_S2)
    )

    def validate(self) -> None:
        """Raises ValueError for an unknown model or thresholds that are not 3 positive
        values each."""
        check_config_numbers(self)
        if self.model not in VESTIBULAR_MODELS:
            valid = ", ".join(VESTIBULAR_MODELS)
            raise ValueError(f"unknown vestibular model '{self.model}'; valid: {valid}")
        for name in ("rotation_thresholds", "specific_force_thresholds"):
            values = getattr(self, name)
            if len(values) != 3 or min(values) <= 0:
                raise ValueError(f"PerceptionConfig.{name} must be 3 positive values; got {values}")

    @property
    def parameters(self) -> VestibularModelParameters:
        """The named model's transfer functions."""
        self.validate()
        return VESTIBULAR_MODELS[self.model]

    @property
    def thresholds(self) -> np.ndarray:
        """The six channels' thresholds in the order of y (rad/s, then m/s^2), shape (6,)."""
        return np.array([*self.rotation_thresholds, *self.specific_force_thresholds], float)
