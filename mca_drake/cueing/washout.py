"""Classical washout filter (Reid and Nahon's classical algorithm, adapted to head-frame
references): the filters that turn a motion-cueing reference into a head pose trajectory.

Channels (input -> output), all linear and discretised exactly (zero-order hold) at the
control period:

    translation  f_x, f_y, a_z  -> third-order high-pass -> double integration
                 -> head displacement and velocity (m, m/s) along world x, y, z
                 H(s) = k_t s^3 / ((s^2 + 2 zeta w_t s + w_t^2)(s + w_b)) on acceleration
    tilt         f_x, f_y -> second-order low-pass -> pitch = -asin(f_x / g),
                 roll = asin(f_y / g), rate-limited (tilt coordination)
    rotation     w_x, w_y, w_z -> second-order high-pass -> integration
                 -> roll, pitch, yaw angles and rates (rad, rad/s)

At the neutral pose (q = 0) the head axes are the world axes, so displacements are world
offsets from the neutral head position and angles are roll-pitch-yaw of R_WH. Default
cut-offs are the textbook ones scaled to the KR500's small workspace; every one is a field
of `WashoutConfig`.
"""

import dataclasses
import math

import numpy as np
from scipy import signal

from mca_drake.conventions import GRAVITY
from mca_drake.input_checks import check_config_numbers
from mca_drake.resources import check_profile


@dataclasses.dataclass
class WashoutConfig:
    """Cut-offs (rad/s), damping, gains and limits of the classical washout; the defaults
    are tuned, `classic()` gives the textbook ones."""

    # The filters below are tuned (the textbook ones are `WashoutConfig.classic()`):
    #   mca-drake tune --mca washout --trials 30 --duration 60 --workers 2
    #       --flights light:100,light:101,jet:100,jet:101
    # on 2026-11-23 (TPE seed 0; the best of 30 trials: median PI -1.724 against the
    # classic 1.032 and zero motion's 1.544 on those four training flights).
    # Translational high-pass: second-order break frequency and damping, and the extra
    # first-order washout break that returns the displacement to zero.
    translation_frequency: float = 4.94891620387039
    translation_damping: float = 1.1379264587060924
    translation_washout_frequency: float = 1.9072781901191604
    # Gain on the (already scaled) translational references.
    translation_gain: float = 0.2541553116723521
    # Tilt coordination: second-order low-pass of f_x, f_y, and the tilt-rate limit (rad/s;
    # tuned to 1.6 deg/s, below the vestibular threshold of rotation perception).
    tilt_frequency: float = 2.797509317958913
    tilt_damping: float = 1.4607925859899
    tilt_rate_limit: float = 0.02777193110323053
    # Largest tilt angle (rad; tuned to 16 deg).
    tilt_limit: float = 0.28263604266738585
    # Rotational high-pass of the angular rates: break frequency and damping, and gain.
    rotation_frequency: float = 0.2295794718796234
    rotation_damping: float = 0.9881390998594926
    rotation_gain: float = 0.29299007713281566
    # Gain of the pose-error feedback of the head velocity command (1/s).
    pose_feedback_gain: float = 10.67891731813125
    # Joint positions (rad, m for a prismatic joint) the washout works about; empty: the
    # platform's `washout_home` (`mca_drake.platforms.serial.SerialChain`), a pose away from
    # singularities (the KR500's: joints 3 and 5 bent by +-0.5 rad, since at q = 0 its wrist
    # is singular and no joint velocity rolls or yaws the head about the head point).
    home_position: list[float] = dataclasses.field(default_factory=list)
    # The shipped profile (`mca_drake.cueing.profiles`: "ground" for cars) these settings
    # are, set by asking for it by name ("washout-ground"); it names the MCA in summaries
    # and reports. "": the flight defaults above.
    profile: str = ""

    @classmethod
    def classic(cls) -> "WashoutConfig":
        """The textbook cut-offs scaled to the KR500 (translation 2.5 rad/s, washout 0.5,
        tilt 5 rad/s at 3 deg/s up to 20 deg, rotation 1 rad/s, unit gains, pose gain 10):
        the untuned baseline, whatever the defaults."""
        return cls(
            translation_frequency=2.5,
            translation_damping=1.0,
            translation_washout_frequency=0.5,
            translation_gain=1.0,
            tilt_frequency=5.0,
            tilt_damping=1.0,
            tilt_rate_limit=math.radians(3.0),
            tilt_limit=math.radians(20.0),
            rotation_frequency=1.0,
            rotation_damping=1.0,
            rotation_gain=1.0,
            pose_feedback_gain=10.0,
        )

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        check_profile(self.profile)
        values = {
            k: v
            for k, v in dataclasses.asdict(self).items()
            if k not in ("home_position", "profile")
        }
        if any(not (v > 0) for v in values.values()):
            bad = [k for k, v in values.items() if not v > 0]
            raise ValueError(f"washout settings must be positive; got {bad}")


class _Channel:
    """A discretised filter with several outputs (rows of C, D) sharing its state."""

    def __init__(self, outputs: list[tuple[list, list]], h: float):
        # all outputs share the denominator; build from the first and replace C, D per output
        num0, den = outputs[0]
        A, B, _, _ = signal.tf2ss(num0, den)
        C = []
        D = []
        for num, den_k in outputs:
            if list(den_k) != list(den):
                raise ValueError("outputs of one channel must share the denominator")
            _, _, C_k, D_k = signal.tf2ss(num, den)
            C.append(C_k[0])
            D.append(D_k[0, 0])
        Ad, Bd, Cd, Dd, _ = signal.cont2discrete(
            (A, B, np.array(C), np.array(D)[:, None]), h, method="zoh"
        )
        self.A, self.B, self.C, self.D = Ad, Bd[:, 0], Cd, Dd[:, 0]
        self.size = A.shape[0]


class WashoutFilters:
    """The filter bank of one washout MCA: `step(state, reference) -> (state, targets)`.

    The state is a flat vector (size `state_size`) so that a Drake system can keep it in
    its discrete state. Targets: a dict with `position` (3, m, offset from neutral),
    `velocity` (3, m/s), `rpy` (3, rad) and `rpy_rate` (3, rad/s).
    """

    def __init__(self, config: WashoutConfig, time_step: float):
        config.validate()
        self.config, self.h = config, float(time_step)
        w, z, wb = (
            config.translation_frequency,
            config.translation_damping,
            config.translation_washout_frequency,
        )
        den_t = np.polymul([1.0, 2 * z * w, w * w], [1.0, wb])
        k = config.translation_gain
        # displacement = H(s)/s^2 a = k s/den; velocity = k s^2/den (acceleration in)
        self._translation = _Channel([([k, 0.0], den_t), ([k, 0.0, 0.0], den_t)], self.h)
        wl, zl = config.tilt_frequency, config.tilt_damping
        self._tilt = _Channel([([wl * wl], [1.0, 2 * zl * wl, wl * wl])], self.h)
        wr, zr, kr = config.rotation_frequency, config.rotation_damping, config.rotation_gain
        den_r = [1.0, 2 * zr * wr, wr * wr]
        # angle = HP2(s)/s omega = kr s/den; rate = kr s^2/den
        self._rotation = _Channel([([kr, 0.0], den_r), ([kr, 0.0, 0.0], den_r)], self.h)
        nt, nl, nr = self._translation.size, self._tilt.size, self._rotation.size
        # layout: 3 translation channels, 2 tilt low-passes, 2 rate-limited tilt angles,
        # 3 rotation channels
        self._slices = {}
        offset = 0
        for name, size, count in (("t", nt, 3), ("l", nl, 2), ("a", 1, 2), ("r", nr, 3)):
            self._slices[name] = (offset, size, count)
            offset += size * count
        self.state_size = offset

    def _part(self, state, name):
        offset, size, count = self._slices[name]
        return state[offset : offset + size * count].reshape(count, size)

    def step(self, state: np.ndarray, reference: np.ndarray):
        """Advances the filters one period with reference y_ref = [w (3), f_x, f_y, a_z];
        returns (new_state, targets) with the targets valid over the coming period."""
        reference = np.asarray(reference, float)
        new = np.array(state, dtype=float, copy=True)
        out = {}
        # translation: inputs f_x, f_y, a_z (the accelerations to render)
        t = self._part(new, "t")
        ch = self._translation
        acc = reference[3:6]
        y = t @ ch.C.T + acc[:, None] * ch.D[None, :]  # (3, 2): displacement, velocity
        t[:] = t @ ch.A.T + acc[:, None] * ch.B[None, :]
        out["position"], out["velocity"] = y[:, 0], y[:, 1]
        # tilt coordination
        low = self._part(new, "l")
        ch = self._tilt
        f_low = (low @ ch.C.T)[:, 0] + reference[3:5] * ch.D[0]
        low[:] = low @ ch.A.T + reference[3:5, None] * ch.B[None, :]
        limit = np.sin(self.config.tilt_limit) * GRAVITY
        f_low = np.clip(f_low, -limit, limit)
        target = np.array([np.arcsin(f_low[1] / GRAVITY), -np.arcsin(f_low[0] / GRAVITY)])
        angles = self._part(new, "a")[:, 0]  # roll, pitch of tilt
        max_step = self.config.tilt_rate_limit * self.h
        change = np.clip(target - angles, -max_step, max_step)
        tilt_rate = change / self.h
        angles += change
        self._part(new, "a")[:, 0] = angles
        # rotation
        r = self._part(new, "r")
        ch = self._rotation
        y = r @ ch.C.T + reference[:3, None] * ch.D[None, :]
        r[:] = r @ ch.A.T + reference[:3, None] * ch.B[None, :]
        rpy = y[:, 0].copy()
        rpy_rate = y[:, 1].copy()
        rpy[:2] += angles
        rpy_rate[:2] += tilt_rate
        out["rpy"], out["rpy_rate"] = rpy, rpy_rate
        return new, out
