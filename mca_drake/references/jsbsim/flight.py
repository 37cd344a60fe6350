"""The recorder: fly a vehicle with the seeded pilot and record the eye-point IMU.

`fly` and `fly_with_log` validate the request, route JSBSim's console output to a private
logger, build the model, the loops, the plan and the pilot, then step them at 100 Hz and
package the samples as a `Recording` (head axes, SI) and a `FlightLog`. The package docstring
(`mca_drake.references.jsbsim`) describes the flights.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import jsbsim
import numpy as np
from tqdm.auto import tqdm

from mca_drake.references.jsbsim.aircraft import FT, SAMPLE_RATE_HZ, STEP_S, G
from mca_drake.references.jsbsim.config import FlightConfig, check_config
from mca_drake.references.jsbsim.fleet import (
    AIRFRAMES,
    FULL_FLIGHT_MIN_DURATION_S,
    check_vehicle,
)
from mca_drake.references.jsbsim.loops import Loops
from mca_drake.references.jsbsim.model import Model, QuietLogger
from mca_drake.references.jsbsim.pilot import Pilot
from mca_drake.references.jsbsim.plan import RandomPlan
from mca_drake.references.jsbsim.route import RoutePilot, draw_route
from mca_drake.references.jsbsim.style import PilotStyle
from mca_drake.references.recording import Recording

# The pilots a built-in flight may be flown by (`fly(pilot=...)`).
PILOT_KINDS = ("scripted", "route")

# Steps between the full sanity checks (a load spike is checked every step).
CHECK_EVERY = 10


@dataclasses.dataclass
class FlightLog:
    """Vehicle states alongside a recording, on the same time grid.

    Attributes:
        t: sample times, s, shape (T,).
        attitude: roll, pitch, true heading, rad, shape (T, 3) (roll positive right wing down).
        height_m: height of the centre of gravity above ground, m, shape (T,).
        airspeed_mps: calibrated airspeed, m/s, shape (T,).
        on_ground: weight on wheels, shape (T,), bool.
        phases: (start time s, maneuver) in flying order.
    """

    t: np.ndarray
    attitude: np.ndarray
    height_m: np.ndarray
    airspeed_mps: np.ndarray
    on_ground: np.ndarray
    phases: list[tuple[float, str]]

    def phase_at(self, t: float) -> str:
        """The maneuver flown at time t, s."""
        name = self.phases[0][1] if self.phases else ""
        for start, phase in self.phases:
            if start > t:
                break
            name = phase
        return name


def fly(
    vehicle: str,
    duration_s: float,
    seed: int,
    *,
    config: FlightConfig | None = None,
    progress: bool = False,
    pilot: str = "scripted",
) -> Recording:
    """Flies `vehicle` for `duration_s` with the pilot seeded by `seed`; the eye-point IMU.

    Args:
        vehicle: "light" (JSBSim c172p) or "jet" (global5000).
        duration_s: length of the recording, s (> 0).
        seed: seeds the pilot's plan and JSBSim's turbulence; same seed, same recording.
        config: knobs (None: `default_config(vehicle)`).
        progress: show a tqdm bar over simulated time.
        pilot: "scripted" (`pilot.Pilot` flying the plan of manoeuvres) or "route" (the
            independent `route.RoutePilot`, airborne only, for evaluation flights alone).

    Returns:
        Recording at 100 Hz with round(duration_s * 100) + 1 samples (t = 0, 0.01, ...):
        omega (T, 3) rad/s and f (T, 3) m/s^2 in head axes (x forward, y left, z up);
        metadata: vehicle, jsbsim_model, jsbsim_version, seed, duration_s, from_ground,
        phases ("t name; ...").

    Raises:
        ValueError: unknown vehicle, bad duration or config.
        FlightError: the flight left the sane envelope (crash, overload, overspeed, NaN).
    """
    return fly_with_log(vehicle, duration_s, seed, config=config, progress=progress, pilot=pilot)[0]


def fly_with_log(
    vehicle: str,
    duration_s: float,
    seed: int,
    *,
    config: FlightConfig | None = None,
    progress: bool = False,
    output_directive: str | None = None,
    on_sample: Callable[[float], None] | None = None,
    pilot: str = "scripted",
) -> tuple[Recording, FlightLog]:
    """`fly`, plus the vehicle's attitude, height, airspeed and phases on the same grid.

    Args:
        output_directive: path of a JSBSim output directive to add (e.g. FlightGear packets
            over UDP, `mca_drake.live.fgnetfdm.jsbsim_output_directive`); None: no output.
        on_sample: called with the simulated time (s) after every step (a live streamer
            paces the flight to the wall clock with it).
    """
    check_vehicle(vehicle)
    if pilot not in PILOT_KINDS:
        raise ValueError(f"unknown pilot '{pilot}'; valid: {', '.join(PILOT_KINDS)}")
    if not (math.isfinite(duration_s) and duration_s >= STEP_S):
        raise ValueError(f"duration_s must be a finite number >= {STEP_S}; got {duration_s}")
    config = (config or FlightConfig()).resolved(vehicle)
    check_config(config)
    logger = QuietLogger()
    previous = jsbsim.get_logger()
    jsbsim.set_logger(logger)  # JSBSim's console chatter goes to our buffer instead
    try:
        return _record(
            vehicle,
            float(duration_s),
            int(seed),
            config,
            logger,
            progress,
            output_directive=output_directive,
            on_sample=on_sample,
            pilot=pilot,
        )
    finally:
        jsbsim.set_logger(previous)


def _record(
    vehicle: str,
    duration_s: float,
    seed: int,
    config: FlightConfig,
    logger: QuietLogger,
    progress: bool,
    output_directive: str | None = None,
    on_sample: Callable[[float], None] | None = None,
    pilot: str = "scripted",
) -> tuple[Recording, FlightLog]:
    """Builds the flight, steps it to `duration_s` with the checks, and packages it."""
    style = config.style or PilotStyle()
    air = style.airframe(AIRFRAMES[vehicle])  # the loops' gains and rates as this pilot flies
    rng = np.random.default_rng(seed)
    if config.from_ground is None:
        from_ground = duration_s >= FULL_FLIGHT_MIN_DURATION_S[vehicle] and pilot != "route"
    else:
        from_ground = bool(config.from_ground)
    if from_ground and pilot == "route":
        raise ValueError("the route pilot flies airborne only; set from_ground False")
    if from_ground and not air.ground_ops:
        raise ValueError(
            f"{vehicle} ({air.model}) flies airborne only: the pilot's taxi, take-off and "
            "landing are calibrated for light and jet; set from_ground False"
        )
    # The generator's draws come in a fixed order, so a seed always gives the same flight:
    # the turbulence generator's seed first, then the heading, then the plan's, as it flies.
    model = Model(
        vehicle,
        seed,
        air,
        logger,
        turbulence_seed=int(rng.integers(1, 2**31 - 1)),
        output_directive=output_directive,
    )
    heading = config.initial_heading_rad
    if heading is None:
        heading = float(rng.uniform(0.0, 2.0 * math.pi))
    throttle = model.initialise(config, heading, from_ground)
    if pilot == "route":
        route = draw_route(rng, air, config, heading, duration_s)
        flier = RoutePilot(model, config, route, throttle)
        return _fly_and_package(model, flier, flier, duration_s, False, progress, on_sample)
    loops = Loops(air, config, model.state, model.controls, throttle, style)
    if config.maneuvers is None:
        plan = RandomPlan(
            rng,
            config,
            air,
            from_ground=from_ground,
            duration_s=duration_s,
            time_s=lambda: model.t,
            height_m=lambda: model.state.h,
            held_altitude_m=loops.held_altitude,
            style=style,
        )
    else:
        plan = config.maneuvers
    scripted = Pilot(model, loops, config, from_ground, plan, heading if from_ground else None)
    return _fly_and_package(model, loops, scripted, duration_s, from_ground, progress, on_sample)


def _fly_and_package(model, loops, pilot, duration_s, from_ground, progress, on_sample):
    """Steps `pilot` (its `fly()`) and `loops` (their `step()`) with the model to
    `duration_s` under the checks (`_run`), and packages the recording (`_package`)."""
    vehicle = model.vehicle
    n_samples = round(duration_s * SAMPLE_RATE_HZ) + 1
    bar = None
    if progress:
        bar = tqdm(total=round(duration_s), unit="sim s", desc=f"{vehicle} flight")
    try:
        imu, log = _run(model, loops, pilot, n_samples, bar, on_sample)
    finally:
        if bar is not None:
            bar.close()
    return _package(imu, log, model, pilot, duration_s, from_ground)


def _run(
    model: Model,
    loops: Loops,
    pilot: Pilot,
    n_samples: int,
    bar: tqdm | None,
    on_sample: Callable[[float], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Steps pilot, loops and model to `n_samples` samples, checking the state as it goes.

    Returns:
        imu: JSBSim's eye-point specific force (ft/s^2) and body rates (rad/s), (T, 6).
        log: roll, pitch, heading (rad), wheel height (m), airspeed (m/s), on ground, then
            the pilot's commands (`Model.read_commands`), (T, 11).
    """
    s = model.state
    imu = [None] * n_samples
    log = [None] * n_samples
    values = model.read_state()
    imu[0] = values[:6]
    commands = model.read_commands
    log[0] = (s.phi, s.theta, s.psi, s.h, s.v, s.wow, *commands())
    flying = pilot.fly()
    # JSBSim's gear dampers are massless: a wheel touching down gives a one- or two-sample
    # spike at the eye point (the jet's nose wheel, about 4 g). So the load factor limit
    # applies to the mean over CHECK_EVERY samples; a single sample may reach 3x the limit.
    spike2 = (3.0 * model.air.max_load_factor * G / FT) ** 2  # |a|^2, (ft/s^2)^2
    model.logger.messages.clear()  # set-up warnings do not explain a failure in flight
    was_on_ground, sink = s.wow, -s.hdot
    step = model.step
    control = loops.step
    for k in range(1, n_samples):
        next(flying)
        control()
        values = step(k)
        ax, ay, az = values[0], values[1], values[2]
        imu[k] = values[:6]
        if s.wow and not was_on_ground:
            model.check_contact(sink, pilot.ground_allowed)
        was_on_ground, sink = s.wow, -s.hdot
        if ax * ax + ay * ay + az * az > spike2 or k % CHECK_EVERY == 0:
            model.check(values)
            model.check_load(imu[max(k - CHECK_EVERY + 1, 0) : k + 1])
        log[k] = (s.phi, s.theta, s.psi, s.h, s.v, s.wow, *commands())
        if bar is not None and k % 100 == 0:
            bar.update(1)
        if on_sample is not None:
            on_sample(model.t)
    return np.array(imu), np.array(log, dtype=float)


def _package(
    imu: np.ndarray,
    log: np.ndarray,
    model: Model,
    pilot: Pilot,
    duration_s: float,
    from_ground: bool,
) -> tuple[Recording, FlightLog]:
    """`_run`'s arrays as a Recording (head axes: x fwd, y left, z up; SI) and a FlightLog."""
    air = model.air
    t = np.arange(len(imu)) * STEP_S
    omega = np.column_stack([imu[:, 3], -imu[:, 4], -imu[:, 5]])
    f = FT * np.column_stack([imu[:, 0], -imu[:, 1], -imu[:, 2]])
    metadata = {
        "source": f"jsbsim {'route' if isinstance(pilot, RoutePilot) else 'scripted'} pilot "
        "(mca_drake.references.jsbsim)",
        "vehicle": model.vehicle,
        "jsbsim_model": air.model,
        "jsbsim_version": jsbsim.__version__,
        "seed": str(model.seed),
        "duration_s": repr(duration_s),
        "from_ground": str(from_ground).lower(),
        "phases": "; ".join(f"{start:.2f} {name}" for start, name in pilot.phases),
    }
    # the pilot's commands and the aircraft's state (`vehicle_signals`), for predictors
    signals = {name: log[:, 6 + i] for i, name in enumerate(("aileron", "elevator", "rudder"))}
    signals |= {
        "throttle": log[:, 9],
        "brake": log[:, 10],
        "speed": log[:, 4],
        "roll": log[:, 0],
        "pitch": log[:, 1],
        "height": log[:, 3] + air.cg_height_on_ground,
        "on_ground": log[:, 5],
    }
    recording = Recording(t, omega, f, metadata, signals)
    flight_log = FlightLog(
        t=t,
        attitude=log[:, 0:3],
        height_m=log[:, 3] + air.cg_height_on_ground,
        airspeed_mps=log[:, 4],
        on_ground=log[:, 5] > 0.5,
        phases=list(pilot.phases),
    )
    return recording, flight_log
