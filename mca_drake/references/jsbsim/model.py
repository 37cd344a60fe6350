"""The JSBSim model of one flight: set-up, initial trim, the state read each step, the checks.

`Model` owns JSBSim's FGFDMExec and its property nodes: it loads the aircraft, sets the
initial conditions and trims (or settles on the gear), steps the simulation, reads the state
the pilot flies by into `AircraftState` (SI units), writes the pilot's commands through
`Controls`, and checks the state against the sane envelope, raising `FlightError`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from typing import NoReturn

import jsbsim

from mca_drake.references.jsbsim.aircraft import DEG, FT, KT, STEP_S, Airframe, G
from mca_drake.references.jsbsim.config import FlightConfig

MAX_TOUCHDOWN_SINK = 3.0  # m/s; beyond it a touchdown is a crash (about 600 ft/min)

# The properties `Model.read_state` returns, in this order; the first six are the eye-point
# IMU (specific force ft/s^2 and body rates rad/s, JSBSim body axes x fwd, y right, z down).
# The pilot's commands a recording carries (`read_commands`).
_COMMAND_PROPERTIES = (
    "fcs/aileron-cmd-norm",
    "fcs/elevator-cmd-norm",
    "fcs/rudder-cmd-norm",
    "fcs/throttle-cmd-norm[0]",
    "fcs/left-brake-cmd-norm",
)
_STATE_PROPERTIES = (
    "accelerations/a-pilot-x-ft_sec2",
    "accelerations/a-pilot-y-ft_sec2",
    "accelerations/a-pilot-z-ft_sec2",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/vc-kts",
    "position/h-agl-ft",
    "velocities/h-dot-fps",
    "aero/alpha-rad",
    "aero/beta-rad",
    "aero/qbar-psf",
    "gear/wow",
    "velocities/u-fps",
    "aero/stall-hyst-norm",
)


class FlightError(RuntimeError):
    """A flight left the sane envelope (crash, overspeed, overload, NaN); says when and why."""


class QuietLogger(jsbsim.FGLogger):
    """Keeps JSBSim's warnings and errors (for error messages) instead of printing them.

    Attributes:
        messages: the last (up to 20) warnings and errors, whitespace collapsed.
    """

    def __init__(self) -> None:
        super().__init__()
        self._level = jsbsim.LogLevel.BULK
        self._parts: list[str] = []
        self.messages: list[str] = []

    def set_level(self, level) -> None:
        """Starts a message at `level` (a jsbsim.LogLevel)."""
        self._level = level
        self._parts = []

    def file_location(self, filename: str, line: int) -> None:
        """Ignored: where in the model files a message comes from."""

    def message(self, message: str) -> None:
        """Keeps a part of a warning or error; drops the chatter below WARN."""
        if self._level >= jsbsim.LogLevel.WARN:
            self._parts.append(message)

    def format(self, format) -> None:
        """Ignored: terminal colours."""

    def flush(self) -> None:
        """Ends a message: keeps it (if it was a warning or error) among the last 20."""
        if self._parts:
            self.messages.append(" ".join("".join(self._parts).split()))
            del self.messages[:-20]  # the last few are enough to explain a failure
            self._parts = []


@dataclasses.dataclass(slots=True)
class AircraftState:
    """The state the pilot flies by and the checks test; `Model.read_state` updates it."""

    # Body rates, rad/s (JSBSim body axes: x forward, y right, z down).
    p: float = 0.0
    q: float = 0.0
    r: float = 0.0
    # Euler angles, rad: roll (positive right wing down), pitch, true heading.
    phi: float = 0.0
    theta: float = 0.0
    psi: float = 0.0
    # Calibrated airspeed, m/s.
    v: float = 0.0
    # Height of the wheels (about) above ground, m, and its rate, m/s (positive up).
    h: float = 0.0
    hdot: float = 0.0
    # Angle of attack and sideslip, rad.
    alpha: float = 0.0
    beta: float = 0.0
    # Dynamic pressure, lbf/ft^2 (the loop gains are scheduled on it).
    qbar: float = 0.0
    # Weight on wheels.
    wow: bool = False
    # Forward body velocity, m/s (the ground speed on the ground).
    u: float = 0.0
    # JSBSim's stall hysteresis is set (the wing has stalled).
    stalled: bool = False


class Controls:
    """Setters of JSBSim's control commands: normalised deflections, throttles and brakes.

    Args:
        node: the model's property node of a name.
        engines: how many throttles the model has.
    """

    def __init__(self, node: Callable[[str], jsbsim.FGPropertyNode], engines: int) -> None:
        self._aileron = node("fcs/aileron-cmd-norm").set_double_value
        self._elevator = node("fcs/elevator-cmd-norm").set_double_value
        self._rudder = node("fcs/rudder-cmd-norm").set_double_value
        self.set_steer = node("fcs/steer-cmd-norm").set_double_value
        self._throttles = tuple(
            node(f"fcs/throttle-cmd-norm[{i}]").set_double_value for i in range(engines)
        )
        self._brake_left = node("fcs/left-brake-cmd-norm").set_double_value
        self._brake_right = node("fcs/right-brake-cmd-norm").set_double_value
        self.set_flaps = node("fcs/flap-cmd-norm").set_double_value
        self.set_gear = node("gear/gear-cmd-norm").set_double_value
        self.set_speedbrake = node("fcs/speedbrake-cmd-norm").set_double_value

    def set_throttles(self, throttle: float) -> None:
        """Every engine's throttle, 0 (idle) ... 1 (full)."""
        for set_throttle in self._throttles:
            set_throttle(throttle)

    def set_brakes(self, brake: float) -> None:
        """Both wheel brakes, 0 (off) ... 1 (full)."""
        self._brake_left(brake)
        self._brake_right(brake)

    def write(
        self, aileron: float, elevator: float, rudder: float, throttle: float, brake: float
    ) -> None:
        """The pilot's commands of one step (normalised; positive elevator is nose down)."""
        self._aileron(aileron)
        self._elevator(elevator)
        self._rudder(rudder)
        self.set_throttles(throttle)
        self.set_brakes(brake)


class Model:
    """One JSBSim aircraft: FGFDMExec, its property nodes, the clock, the sanity checks.

    Args:
        vehicle: the vehicle's name (`fleet.VEHICLES`; quoted by FlightError).
        seed: the flight's seed (quoted by FlightError).
        air: the vehicle's airframe constants (JSBSim model name, limits).
        logger: receives JSBSim's messages; the last one is quoted by FlightError.
        turbulence_seed: seed of JSBSim's turbulence generator.

    Attributes:
        t: simulation time, s (0 at the first recorded sample).
        phase: what the flight is doing (the maneuver), quoted by FlightError.
        state: the state read at the last step.
        controls: the command setters.
    """

    def __init__(
        self,
        vehicle: str,
        seed: int,
        air: Airframe,
        logger: QuietLogger,
        turbulence_seed: int,
        output_directive: str | None = None,
    ) -> None:
        self.vehicle = vehicle
        self.seed = seed
        self.air = air
        self.logger = logger
        self.t = 0.0
        self.phase = "initialisation"
        self.state = AircraftState()
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        if not fdm.load_model(air.model):
            raise RuntimeError(f"JSBSim could not load model {air.model}")
        # Some models (global5000) declare a CSV output that JSBSim would write next to its
        # aircraft files; send every declared output to the null device.
        n = 0
        while fdm.set_output_filename(n, os.devnull):
            n += 1
        fdm.disable_output()
        if output_directive is not None:
            # An extra output (e.g. FlightGear packets over UDP for a live demo); enabling it
            # re-enables the declared ones too, but those write to the null device.
            if not fdm.set_output_directive(str(output_directive)):
                raise RuntimeError(f"JSBSim could not load output directive {output_directive}")
            fdm.enable_output()
        fdm.set_dt(STEP_S)
        fdm["simulation/randomseed"] = turbulence_seed
        self.fdm = fdm
        pm = fdm.get_property_manager()

        def node(name: str) -> jsbsim.FGPropertyNode:
            found = pm.get_node(name)
            if found is None:
                raise RuntimeError(f"JSBSim model {air.model} has no property {name}")
            return found

        self._getters = tuple(node(name).get_double_value for name in _STATE_PROPERTIES)
        self.controls = Controls(node, air.engines)
        self._commands = tuple(node(name).get_double_value for name in _COMMAND_PROPERTIES)
        self._nose_wow = node("gear/unit[0]/WOW").get_double_value  # unit 0: nose gear
        self._severity = node("atmosphere/turbulence/milspec/severity")
        self._wind_20ft = node("atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps")
        # Structure contacts (wing tips, skids): touching the ground with them is a crash.
        reactions = fdm.get_ground_reactions()
        self._structure = tuple(
            (name, node(f"contact/unit[{i}]/WOW").get_double_value)
            for i in range(reactions.get_num_gear_units())
            for name in [f"contact/unit[{i}]"]
            if pm.hasNode(f"contact/unit[{i}]/WOW")
        )

    # ------------------------------------------------------------------- set-up and stepping

    def initialise(self, config: FlightConfig, heading: float, from_ground: bool) -> float:
        """Initial conditions, engines running, trim (airborne) or settled on the gear.

        Args:
            config: the resolved flight config (wind, turbulence, maneuver altitude, speed).
            heading: initial true heading, rad.
            from_ground: parked on the ground (else trimmed level at the maneuver altitude
                and cruise speed).

        Returns:
            the throttle (0 ... 1) it is left at: idle on the ground, the trim's in the air.
        """
        fdm, air, controls = self.fdm, self.air, self.controls
        fdm["atmosphere/turb-type"] = 3  # MIL-F-8785C (Dryden), JSBSim's "milspec"
        self.set_wind_20ft(config.wind_speed_20ft_mps)
        self.set_turbulence(0)  # calm while trimming and settling
        fdm["ic/psi-true-rad"] = heading
        fdm["ic/terrain-elevation-ft"] = 0.0
        if from_ground:
            fdm["ic/h-agl-ft"] = air.cg_height_on_ground / FT + 0.2
            fdm["ic/vc-kts"] = 0.0
            fdm["ic/theta-rad"] = 0.0
        else:
            fdm["ic/h-agl-ft"] = config.maneuver_altitude_m / FT
            fdm["ic/vc-kts"] = config.cruise_speed_mps / KT
            fdm["ic/gamma-deg"] = 0.0
        if not fdm.run_ic():
            self.fail("JSBSim rejected the initial conditions")
        fdm["propulsion/set-running"] = -1
        if air.piston:
            for i in range(air.engines):
                fdm[f"fcs/mixture-cmd-norm[{i}]"] = 1.0
        if from_ground:
            # Parked: idle, brakes set; settle on the gear (not recorded).
            controls.set_brakes(1.0)
            controls.set_gear(1.0)
            controls.set_throttles(air.idle_throttle)
            for _ in range(300):
                fdm.run()
            throttle = air.idle_throttle
        else:
            controls.set_gear(0.0 if air.retractable_gear else 1.0)
            fdm["gear/gear-pos-norm"] = 0.0 if air.retractable_gear else 1.0
            try:
                fdm["simulation/do_simple_trim"] = 1
            except jsbsim.TrimFailureError as error:
                self.fail(f"JSBSim could not trim at the start ({error})")
            throttle = fdm["fcs/throttle-cmd-norm"]
            for _ in range(100):  # let the trimmed state settle
                fdm.run()
        self.set_turbulence(config.turbulence_severity)
        return throttle

    def step(self, k: int) -> tuple[float, ...]:
        """Runs JSBSim one step to sample `k` (t = k * STEP_S s); `read_state`'s values."""
        self.fdm.run()
        # From the sample index, not summed: t stays on the 0.01 s grid.
        self.t = k * STEP_S
        return self.read_state()

    def read_state(self) -> tuple[float, ...]:
        """Updates `state` from JSBSim; the raw values of `_STATE_PROPERTIES` (JSBSim units)."""
        values = tuple(g() for g in self._getters)
        s = self.state
        (
            _ax,
            _ay,
            _az,
            s.p,
            s.q,
            s.r,
            s.phi,
            s.theta,
            s.psi,
            vc_kts,
            h_agl_ft,
            hdot_fps,
            s.alpha,
            s.beta,
            s.qbar,
            wow,
            u_fps,
            hyst,
        ) = values
        s.v = vc_kts * KT
        s.h = h_agl_ft * FT - self.air.cg_height_on_ground  # wheels (about) above ground
        s.hdot = hdot_fps * FT
        s.wow = wow > 0.5
        s.u = u_fps * FT
        s.stalled = hyst > 0.5
        return values

    def read_commands(self) -> tuple[float, float, float, float, float]:
        """The pilot's commands as `vehicle_signals` counts them: aileron (positive rolls
        right), elevator (positive pitches the nose up), rudder (positive yaws the nose
        right), throttle (the first engine's) and brake (the left wheel's), normalised."""
        aileron, elevator, rudder, throttle, brake = (g() for g in self._commands)
        # JSBSim's elevator command is positive nose down, its rudder's positive nose left
        return aileron, -elevator, -rudder, throttle, brake

    def nose_on_ground(self) -> bool:
        """Weight on the nose wheel."""
        return self._nose_wow() > 0.5

    def set_turbulence(self, severity: int) -> None:
        """MIL-F-8785C turbulence from now on: probability-of-exceedance index 0 ... 7."""
        self._severity.set_double_value(severity)

    def set_wind_20ft(self, speed_mps: float) -> None:
        """Wind speed 20 ft above ground that sets the low-altitude turbulence, m/s."""
        self._wind_20ft.set_double_value(speed_mps / FT)

    # ------------------------------------------------------------------------------ checks

    def fail(self, what: str) -> NoReturn:
        """Raises FlightError: vehicle, seed, time, phase, `what`, and JSBSim's last warning."""
        recent = f"; JSBSim said: {self.logger.messages[-1]}" if self.logger.messages else ""
        raise FlightError(
            f"{self.vehicle} flight (seed {self.seed}) failed at t = {self.t:.2f} s during "
            f"'{self.phase}': {what}{recent}"
        )

    def check(self, values: tuple[float, ...]) -> None:
        """Sanity checks of the state (`values`: `read_state`'s); raises FlightError."""
        if not all(math.isfinite(x) for x in values):
            self.fail("non-finite state (NaN or inf) from JSBSim")
        air, s = self.air, self.state
        if s.h < -1.0:
            self.fail(f"below ground (wheels {s.h:.1f} m)")
        for name, touching in self._structure:
            if touching() > 0.5:
                self.fail(f"structure {name} touched the ground (crash)")
        if s.v > air.never_exceed_speed:
            self.fail(f"overspeed: {s.v / KT:.0f} kt > {air.never_exceed_speed / KT:.0f} kt")
        if not s.wow and (abs(s.phi) > 100 * DEG or abs(s.theta) > 60 * DEG):
            self.fail(f"loss of control: roll {s.phi / DEG:.0f} deg, pitch {s.theta / DEG:.0f} deg")

    def check_contact(self, sink: float, allowed: bool) -> None:
        """The wheels just touched the ground at `sink` m/s; `allowed`: take-off or landing."""
        if not allowed:
            self.fail(
                f"hit the ground at {sink:.1f} m/s sink and {self.state.v / KT:.0f} kt outside "
                "take-off and landing"
            )
        if sink > MAX_TOUCHDOWN_SINK:
            self.fail(f"hard landing: touched down at {sink:.1f} m/s sink")

    def check_load(self, samples: list[tuple[float, ...]]) -> None:
        """Mean load factor |f| / g of the IMU samples (ft/s^2 rows) against the limit."""
        mean = sum(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) for a in samples)
        load = mean / len(samples) * FT / G
        peak = max(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) for a in samples) * FT / G
        limit = self.air.max_load_factor
        if load > limit or peak > 3.0 * limit:
            self.fail(
                f"load factor {load:.1f} g over {len(samples) * STEP_S:.2f} s (peak {peak:.1f} g)"
                f" > {limit:g} g"
            )
