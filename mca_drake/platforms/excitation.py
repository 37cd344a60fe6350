"""Open-loop excitation dataset, exactly as Algorithm 1 of the paper.

    for Signal in [step, walk, periodic, sine, splines]:
      for i in 1..6: for j in i..6: for k in 1..repetitions (100):
        generate qdd profiles for joints i..j with Signal (other joints: 0)
        initialise the plant to a random valid state
        simulate the plant open loop for 20 s
        trim at the first state violation (keep the steps before it)
        split into n_p-long segments and keep them

The plant is the exact discretised double integrator, so each batch of repetitions is rolled
out in closed form at once; outputs and head-pose derivatives are computed only for the
kept segments. Every signal stays inside the acceleration limits by construction.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy.interpolate import CubicSpline
from tqdm.auto import tqdm

from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.input_checks import MAX_DURATION_S, check_config_numbers, check_range
from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.kinematics import (
    head_motion,
    output_from_motion,
    pose_derivatives_from_motion,
)
from mca_drake.platforms.serial import NUM_JOINTS, SerialChain
from mca_drake.segments import SegmentDataset, package_versions

SIGNALS = ("step", "walk", "periodic", "sine", "splines")
SOURCE_COLUMNS = ("signal", "first_joint", "last_joint", "repetition", "start_step")


@dataclasses.dataclass
class ExcitationConfig:
    """Size and randomness of the open-loop dataset; the defaults are the paper's."""

    # Signal types to use, a subset of SIGNALS.
    signals: tuple[str, ...] = SIGNALS
    # Simulations per (signal, first joint, last joint) combination.
    repetitions: int = 100
    # Length of each open-loop simulation, s.
    duration_s: float = 20.0
    # Segment length n_p, steps.
    horizon: int = 256
    # Plant period, s.
    time_step: float = CONTROL_PERIOD_S
    # Seed of every random draw (profiles and initial states).
    seed: int = 0
    # The platform excited: a packaged name (`mca-drake platforms`) or a platform file.
    platform: str = DEFAULT_PLATFORM
    # Initial states are drawn uniformly from this fraction of the position and velocity
    # ranges (1.0: anywhere valid, the paper's "random valid state").
    initial_state_fraction: float = 1.0
    # Floating-point type of the stored arrays ("float32" halves the file size).
    dtype: str = "float32"

    def validate(self) -> None:
        """Raises ValueError for a setting that cannot run, naming it."""
        check_config_numbers(self)
        if not 0 <= self.seed < 2**32:
            raise ValueError(f"seed must be in [0, 2^32); got {self.seed}")
        check_range("ExcitationConfig", "duration_s", self.duration_s, 0.0, MAX_DURATION_S)
        unknown = [s for s in self.signals if s not in SIGNALS]
        if unknown or not self.signals:
            raise ValueError(f"unknown signals {unknown}; valid: {', '.join(SIGNALS)}")
        if self.repetitions < 1 or self.horizon < 1:
            raise ValueError("repetitions and horizon must be at least 1")
        if self.duration_s < self.horizon * self.time_step:
            raise ValueError(
                f"duration_s = {self.duration_s} s is shorter than one segment "
                f"({self.horizon} x {self.time_step} s)"
            )
        if not 0 < self.initial_state_fraction <= 1:
            raise ValueError("initial_state_fraction must be in (0, 1]")
        if self.dtype not in ("float32", "float64"):
            raise ValueError(f"dtype must be float32 or float64; got {self.dtype}")


# ------------------------------------------------------------------------ signal shapes
# Each returns accelerations in units of the joint's limit, shape (R, N, m) in [-1, 1], for
# R repetitions, N steps and m active joints.


def _step(rng, R, N, m, h):
    out = np.empty((R, N, m))
    for r in range(R):
        for j in range(m):
            k = 0
            while k < N:
                hold = max(int(rng.uniform(0.2, 3.0) / h), 1)
                out[r, k : k + hold, j] = rng.uniform(-1, 1)
                k += hold
    return out


def _walk(rng, R, N, m, h):
    # Gaussian increments (about 0.3 of the limit per second), reflected at +-1.
    sigma = 0.3 * np.sqrt(h)
    start = rng.uniform(-1, 1, size=(R, 1, m))
    walk = start + np.cumsum(rng.normal(0.0, sigma, size=(R, N, m)), axis=1)
    return 1.0 - np.abs(np.mod(walk + 1.0, 4.0) - 2.0)  # fold into [-1, 1]


def _periodic(rng, R, N, m, h):
    # Non-sinusoidal periodic waves: square, triangle or sawtooth.
    t = h * np.arange(N)[None, :, None]
    period = rng.uniform(0.5, 10.0, size=(R, 1, m))
    phase = rng.uniform(0, 1, size=(R, 1, m))
    amplitude = rng.uniform(0.1, 1.0, size=(R, 1, m))
    kind = rng.integers(0, 3, size=(R, 1, m))
    cycle = np.mod(t / period + phase, 1.0)
    square = np.where(cycle < 0.5, 1.0, -1.0)
    triangle = 1.0 - 4.0 * np.abs(cycle - 0.5)
    sawtooth = 2.0 * cycle - 1.0
    wave = np.choose(np.broadcast_to(kind, cycle.shape), [square, triangle, sawtooth])
    return amplitude * wave


def _sine(rng, R, N, m, h):
    t = h * np.arange(N)[None, :, None]
    frequency = np.exp(rng.uniform(np.log(0.05), np.log(2.0), size=(R, 1, m)))
    amplitude = rng.uniform(0.1, 1.0, size=(R, 1, m))
    phase = rng.uniform(0, 2 * np.pi, size=(R, 1, m))
    return amplitude * np.sin(2 * np.pi * frequency * t + phase)


def _splines(rng, R, N, m, h):
    t = h * np.arange(N)
    out = np.empty((R, N, m))
    for r in range(R):
        for j in range(m):
            spacing = rng.uniform(0.3, 3.0)
            knots = np.arange(0.0, t[-1] + spacing, spacing)
            out[r, :, j] = CubicSpline(knots, rng.uniform(-1, 1, size=knots.size))(t)
    return np.clip(out, -1.0, 1.0)


_GENERATORS = {
    "step": _step,
    "walk": _walk,
    "periodic": _periodic,
    "sine": _sine,
    "splines": _splines,
}


def excitation_profiles(
    signal: str,
    first_joint: int,
    last_joint: int,
    repetitions: int,
    steps: int,
    time_step: float,
    rng: np.random.Generator,
    robot: SerialChain,
) -> np.ndarray:
    """Joint-acceleration profiles (rad/s^2), shape (repetitions, steps, 6): joints
    first_joint..last_joint (0-based, inclusive) driven by `signal`, the others zero."""
    if signal not in _GENERATORS:
        raise ValueError(f"unknown signal '{signal}'; valid: {', '.join(SIGNALS)}")
    active = np.arange(first_joint, last_joint + 1)
    U = np.zeros((repetitions, steps, NUM_JOINTS))
    shape = _GENERATORS[signal](rng, repetitions, steps, active.size, time_step)
    U[:, :, active] = shape * robot.qdd_max[active]
    return U


def rollout_states(x0: np.ndarray, U: np.ndarray, h: float) -> np.ndarray:
    """Exact double-integrator states, x0 (R, 12), U (R, N, 6) -> X (R, N + 1, 12)."""
    q0, qd0 = x0[:, None, :NUM_JOINTS], x0[:, None, NUM_JOINTS:]
    sum_u = np.concatenate([np.zeros_like(U[:, :1]), np.cumsum(U, axis=1)], axis=1)
    sum_sum_u = np.concatenate([np.zeros_like(U[:, :1]), np.cumsum(sum_u[:, :-1], axis=1)], 1)
    steps = np.arange(U.shape[1] + 1)[None, :, None]
    q = q0 + h * steps * qd0 + h * h * sum_sum_u + 0.5 * h * h * sum_u
    return np.concatenate([q, qd0 + h * sum_u], axis=-1)


def first_violation(X: np.ndarray, robot: SerialChain) -> np.ndarray:
    """Index of the first state outside the position or velocity limits, per row of X
    (R, N + 1, 12); N + 1 where none is."""
    q, qd = X[..., :NUM_JOINTS], X[..., NUM_JOINTS:]
    bad = np.any((q < robot.q_min) | (q > robot.q_max) | (np.abs(qd) > robot.qd_max), axis=-1)
    return np.where(bad.any(axis=1), bad.argmax(axis=1), X.shape[1])


def generate_excitation_dataset(
    config: ExcitationConfig | None = None, progress: bool = True
) -> SegmentDataset:
    """Runs Algorithm 1 and returns the kept segments with their provenance.

    The `source` table has columns SOURCE_COLUMNS: signal index (into config.signals),
    first and last joint (0-based), repetition and the segment's first step in its run.
    """
    config = config or ExcitationConfig()
    config.validate()
    robot = load_platform(config.platform)
    rng = np.random.default_rng(config.seed)
    h, n_p = config.time_step, config.horizon
    steps = round(config.duration_s / h)
    combos = [
        (s, i, j)
        for s in range(len(config.signals))
        for i in range(NUM_JOINTS)
        for j in range(i, NUM_JOINTS)
    ]
    lo = np.concatenate([robot.q_min, -robot.qd_max]) * config.initial_state_fraction
    hi = np.concatenate([robot.q_max, robot.qd_max]) * config.initial_state_fraction
    chunks: dict[str, list[np.ndarray]] = {k: [] for k in ("U", "X")}
    sources: list[np.ndarray] = []
    started = time.perf_counter()
    simulated = 0
    for s, i, j in tqdm(combos, disable=not progress, desc="open-loop excitation", unit="combo"):
        U = excitation_profiles(config.signals[s], i, j, config.repetitions, steps, h, rng, robot)
        x0 = rng.uniform(lo, hi, size=(config.repetitions, 2 * NUM_JOINTS))
        X = rollout_states(x0, U, h)
        valid_steps = first_violation(X, robot)  # steps 0..k-1 start from valid states
        simulated += config.repetitions * steps
        for rep in range(config.repetitions):
            for start in range(0, valid_steps[rep] - n_p + 1, n_p):
                chunks["U"].append(U[rep, start : start + n_p])
                chunks["X"].append(X[rep, start : start + n_p])
                sources.append(np.array([s, i, j, rep, start]))
    dtype = np.dtype(config.dtype)
    n_segments = len(sources)
    U_all = np.array(chunks["U"]).reshape(n_segments, n_p, NUM_JOINTS)
    X_all = np.array(chunks["X"]).reshape(n_segments, n_p, 2 * NUM_JOINTS)
    arrays = {"U": U_all.astype(dtype), "X": X_all.astype(dtype)}
    arrays.update(_outputs_and_poses(X_all, U_all, robot, dtype))
    metadata = {
        "kind": "open-loop excitation (Algorithm 1)",
        "config": dataclasses.asdict(config),
        "source_columns": list(SOURCE_COLUMNS),
        "simulated_steps": simulated,
        "kept_steps": n_segments * n_p,
        "generation_wall_s": time.perf_counter() - started,
        "versions": package_versions(),
    }
    source = np.array(sources, dtype=np.int32).reshape(n_segments, len(SOURCE_COLUMNS))
    return SegmentDataset(arrays, source, metadata)


def _outputs_and_poses(X, U, robot, dtype, chunk: int = 65536) -> dict[str, np.ndarray]:
    """Y, F, dF, ddF for states X (J, n_p, 12) and inputs U (J, n_p, 6), in chunks."""
    J, n_p = U.shape[:2]
    flat_x, flat_u = X.reshape(-1, 2 * NUM_JOINTS), U.reshape(-1, NUM_JOINTS)
    out = {
        "Y": np.empty((J * n_p, 6), dtype),
        "F": np.empty((J * n_p, 4, 4), dtype),
        "dF": np.empty((J * n_p, 4, 4), dtype),
        "ddF": np.empty((J * n_p, 4, 4), dtype),
    }
    for a in range(0, J * n_p, chunk):
        b = min(a + chunk, J * n_p)
        motion = head_motion(flat_x[a:b, :6], flat_x[a:b, 6:], flat_u[a:b], robot)
        out["Y"][a:b] = output_from_motion(motion)
        out["F"][a:b], out["dF"][a:b], out["ddF"][a:b] = pose_derivatives_from_motion(motion)
    return {k: v.reshape(J, n_p, *v.shape[1:]) for k, v in out.items()}
