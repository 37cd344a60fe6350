"""The typed scenarios that the YAML files in diagrams/ load into, one per job.

Each scenario is a dataclass with a comment on every field; `load_scenario` reads one with
`pydrake.common.yaml.yaml_load_typed`, so a misspelt key fails loudly and names the class
it belongs to. The MCA of a scenario is a typed config (`mca_drake.cueing.McaConfig`) picked
by its YAML tag, `mca: !NmpcConfig {mode: rti, washout_weight: 0.3}`; a name such as
`mca: nmpc-rti` stands for that MCA's default config. Drake's own configs carry the
simulator (`SimulatorConfig`: real-time rate, publishing) and Meshcat
(`VisualizationConfig`) settings.
(No `from __future__ import annotations` here: the YAML loader needs real type objects.)
"""

import dataclasses
import types
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Optional, Union

import yaml
from pydrake.common.yaml import yaml_dump, yaml_load, yaml_load_typed
from pydrake.systems.analysis import SimulatorConfig
from pydrake.visualization import VisualizationConfig

from mca_drake.comfort import ComfortConfig
from mca_drake.conventions import CONTROL_PERIOD_S
from mca_drake.cueing import (
    MCA_NAMES,
    DpcConfig,
    McaConfig,
    as_mca_config,
    mca_config_from_name,
)
from mca_drake.cueing.dpc import load_policy_arrays, policy_preview_steps
from mca_drake.cueing.optimal import OptimalConfig
from mca_drake.cueing.plausibility import PlausibilityConfig
from mca_drake.cueing.profiles import profile_config
from mca_drake.input_checks import (
    MAX_DURATION_S,
    MAX_YAML_BYTES,
    check_config_numbers,
    check_range,
    check_yaml_size,
    quoted,
)
from mca_drake.live.beamng import BeamNGConfig
from mca_drake.live.controls import ControlsConfig
from mca_drake.live.f1 import F1Config
from mca_drake.live.outsim import OutSimConfig
from mca_drake.live.receiver import allowed_senders
from mca_drake.live.rig_output import RigOutputConfig, where
from mca_drake.live.rsi.driver import RsiDriverConfig
from mca_drake.perception.models import PerceptionConfig
from mca_drake.platforms.files import (
    DEFAULT_PLATFORM,
    PlatformField,
    load_platform,
    packaged_name,
)
from mca_drake.references.drives import DriveSpec
from mca_drake.references.flights import FlightSpec
from mca_drake.references.reference import ReferenceScaling
from mca_drake.resources import scenario_path
from mca_drake.simulation.closed_loop import PLANTS
from mca_drake.studies.closed_loop_dataset import DEFAULT_DATASET_DIR, ClosedLoopDatasetConfig
from mca_drake.studies.evaluation import (
    DEFAULT_MCAS,
    EvaluationCase,
    EvaluationConfig,
    default_cases,
)
from mca_drake.systems.station import StationConfig


@dataclasses.dataclass
class PlantDemoScenario:
    """The analytical plant driven by the built-in demo joint motion (no MCA yet)."""

    # Simulated time, s.
    duration_s: float = 20.0
    # Control period of the plant and of the logged signals, s.
    time_step: float = CONTROL_PERIOD_S
    # The motion platform: a packaged name (`mca-drake platforms`), a platform file, or an
    # inline !SerialRobot {name, urdf, ...} (its urdf relative to the working directory),
    # !Hexapod {...} or !Rig {...} (`mca_drake.platforms.files`).
    platform: PlatformField = DEFAULT_PLATFORM

    def validate(self) -> None:
        """Raises ValueError for values that cannot run."""
        check_config_numbers(self)
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be positive; got {self.duration_s}")
        check_range("PlantDemoScenario", "duration_s", self.duration_s, 0.0, MAX_DURATION_S)
        if not 0 < self.time_step <= 0.1:
            raise ValueError(f"time_step must be in (0, 0.1] s; got {self.time_step}")
        check_platform(self.platform)


def check_platform(platform) -> None:
    """Raises ValueError (FileNotFoundError for a missing file) naming the `platform` field
    unless it describes a platform (`mca_drake.platforms.files.load_platform`)."""
    try:
        load_platform(platform)
    except (ValueError, FileNotFoundError) as err:
        raise type(err)(f"platform: {err}") from err


def _fast_simulator() -> SimulatorConfig:
    # As fast as possible; the diagrams are discrete, so the integrator settings are unused.
    return SimulatorConfig(target_realtime_rate=0.0, publish_every_time_step=False)


@dataclasses.dataclass
class ClosedLoopScenario:
    """Closed-loop motion cueing of one flight, drive or recording on a platform (its
    MultibodyPlant station or the analytical plant)."""

    # The motion cueing algorithm and its settings: !DpcConfig, !NmpcConfig or
    # !WashoutConfig (`mca_drake.cueing`), or a name (`mca_drake.cueing.MCA_NAMES`: dpc,
    # nmpc-rti, nmpc-converged, washout, nmpc-rti-perceived, nmpc-converged-perceived) for
    # its default config, or a name with a profile (`mca_drake.cueing.profiles`:
    # nmpc-rti-ground, washout-ground, dpc-ground) for the profile's.
    mca: McaConfig = dataclasses.field(default_factory=DpcConfig)
    # "multibody" (the platform's MultibodyPlant, inverse dynamics, head IMU) or
    # "analytical".
    plant: str = "multibody"
    # The motion platform: a packaged name (`mca-drake platforms`), a platform file, or an
    # inline !SerialRobot {name, urdf, ...} (its urdf relative to the working directory),
    # !Hexapod {...} or !Rig {...} (`mca_drake.platforms.files`).
    platform: PlatformField = DEFAULT_PLATFORM
    # The vehicle motion to cue: a flight (a recording file or a built-in JSBSim flight),
    # or a built-in drive tagged !DriveSpec (`mca_drake.references.drives`).
    flight: Union[FlightSpec, DriveSpec] = dataclasses.field(default_factory=FlightSpec)  # noqa: UP007 (YAML loader)
    # Simulated time, s.
    duration_s: float = 60.0
    # The simulated robot, its controller and sensors (multibody plant only).
    station: StationConfig = dataclasses.field(default_factory=StationConfig)
    # Drake's simulator settings: target_realtime_rate 1 for live use (multibody only),
    # 0 as fast as possible.
    simulator_config: SimulatorConfig = dataclasses.field(default_factory=_fast_simulator)
    # Watch it in Meshcat with Drake's visualization settings (multibody only; `{}` for
    # Drake's defaults, which also draw the collision layer; `--meshcat` takes
    # `mca_drake.simulation.builders.default_visualization`); null: no Meshcat.
    visualization: Optional[VisualizationConfig] = None  # noqa: UP045 (YAML loader)
    # Seed of the diagram's random sources (the IMU noise of `station`).
    random_seed: int = 0
    # The vestibular model and thresholds of the summary's perceived figures
    # (`mca_drake.perception`).
    perception: PerceptionConfig = dataclasses.field(default_factory=PerceptionConfig)
    # The input plausibility guard in front of the MCA (`mca_drake.cueing.plausibility`:
    # spikes, step bounds, frozen streams); `{enabled: false}` reads the reference as it is.
    plausibility: PlausibilityConfig = dataclasses.field(default_factory=PlausibilityConfig)
    # How the vehicle's motion becomes the reference the MCA cues
    # (`mca_drake.references.reference.ReferenceScaling`): angular_scale and force_scale
    # (default 0.5 each), per-channel limits and limit_mode. The run is still scored against
    # the default scaling, so its PI stays comparable; the summary records the scaling.
    scaling: ReferenceScaling = dataclasses.field(default_factory=ReferenceScaling)
    # The cabin comfort bound between the MCA and the robot (`mca_drake.comfort`: the
    # largest change of the cabin's specific force in one control period; 0: none).
    comfort: ComfortConfig = dataclasses.field(default_factory=ComfortConfig)
    # Folder for summary.json, tracking.png (Fig. 4), perceived.png and joint_usage.png
    # (Fig. 5).
    output_dir: str = "results/closed_loop"
    # The run's time series as CSV, one row per control period
    # (`mca_drake.simulation.trajectory`); "": none.
    trajectory: str = ""

    def __post_init__(self) -> None:
        self.mca = as_mca_config(self.mca, packaged_name(self.platform))

    def validate(self) -> None:
        """Raises ValueError (FileNotFoundError for a missing file) for values that cannot
        run, naming the field."""
        check_config_numbers(self)
        if self.plant not in PLANTS:
            raise ValueError(f"plant must be one of {', '.join(PLANTS)}; got {self.plant!r}")
        check_platform(self.platform)
        check_range(
            "ClosedLoopScenario", "duration_s", self.duration_s, CONTROL_PERIOD_S, MAX_DURATION_S
        )
        realtime = self.simulator_config.target_realtime_rate
        if not realtime >= 0:
            raise ValueError(f"simulator_config.target_realtime_rate must be >= 0; got {realtime}")
        if self.plant == "analytical" and (self.visualization is not None or realtime):
            raise ValueError("visualization and a real-time rate need plant multibody")
        if not 0 <= self.random_seed < 2**32:
            raise ValueError(f"random_seed must be in [0, 2^32); got {self.random_seed}")
        self.mca.validate()
        self.flight.validate()
        self.station.validate()
        self.perception.validate()
        self.plausibility.validate()
        self.scaling.validate()
        self.comfort.validate()


@dataclasses.dataclass
class SuiteCase:
    """One case of an `EvaluationScenario`, as a scenario file spells it: the fields of
    `mca_drake.studies.evaluation_cases.EvaluationCase` (which see), with lists, e.g.
    `{name: C, seeds: [3000, 3001], vehicles: [t6texan2, T38]}`."""

    # Label in the report ("A" ... "E", or your own).
    name: str = ""
    # The vehicle (an aircraft, or a car for drives) when `vehicles` is empty.
    vehicle: str = ""
    # Flight (or drive) seeds: evaluation seeds, from 1000 on.
    seeds: list[int] = dataclasses.field(default_factory=list)
    # Several vehicles, dealt to the seeds in turn (seed i: vehicles[i % len]).
    vehicles: list[str] = dataclasses.field(default_factory=list)
    # Who flies the flights (`mca_drake.references.flights.PILOTS`).
    pilot: str = "scripted"
    # Drives instead of flights: the manoeuvres, dealt to the seeds in turn.
    manoeuvres: list[str] = dataclasses.field(default_factory=list)

    @classmethod
    def of(cls, case: EvaluationCase) -> "SuiteCase":
        """The scenario's spelling of `case`."""
        return cls(
            case.name,
            case.vehicle,
            list(case.seeds),
            list(case.vehicles),
            case.pilot,
            list(case.manoeuvres),
        )

    def to_case(self) -> EvaluationCase:
        """The study's case."""
        return EvaluationCase(
            self.name,
            self.vehicle,
            tuple(self.seeds),
            vehicles=tuple(self.vehicles),
            pilot=self.pilot,
            manoeuvres=tuple(self.manoeuvres),
        )


@dataclasses.dataclass
class EvaluationScenario:
    """The evaluation suite: every MCA on the cases' flights and drives (default A-E: light
    aircraft, jets, aircraft neither trained nor tuned on, cars, the route pilot)."""

    # MCAs compared (DPC is tested against each other one): configs or names.
    mcas: list[McaConfig] = dataclasses.field(
        default_factory=lambda: [mca_config_from_name(n) for n in DEFAULT_MCAS]
    )
    # The cases, each a set of flights or drives (`SuiteCase`); default: the suite's A-E
    # (`mca_drake.studies.evaluation_cases.default_cases`). A case with no seeds is skipped.
    cases: list[SuiteCase] = dataclasses.field(
        default_factory=lambda: [SuiteCase.of(c) for c in default_cases()]
    )
    # Simulated seconds per flight.
    duration_s: float = EvaluationConfig.duration_s
    # CPUs of the local Ray the runs go to (1: one after the other, in this process).
    workers: int = 1
    # A Ray cluster to run on instead ("auto", "ray://host:10001"); empty: RAY_ADDRESS or
    # a local Ray.
    address: str = ""
    # Folder of the per-run JSON files (resumable), evaluation.md/json and the box plot.
    output_dir: str = "results/evaluation"
    # Each flight's offline-optimal bound too, with these settings, and every MCA's share
    # of the achievable improvement; null: no bound.
    bound: Optional[OptimalConfig] = None  # noqa: UP045 (YAML loader)
    # The motion platform every run cues on: a packaged name (`mca-drake platforms`; its
    # tuned settings are the defaults of the MCAs named), a platform file, or an inline
    # !SerialRobot {...}, !Hexapod {...} or !Rig {...}.
    platform: PlatformField = DEFAULT_PLATFORM

    def __post_init__(self) -> None:
        self.mcas = [as_mca_config(m, packaged_name(self.platform)) for m in self.mcas]

    def validate(self) -> None:
        """Raises ValueError for values that cannot run."""
        names = [case.name for case in self.cases]
        if not all(names) or len(set(names)) != len(names):
            raise ValueError(f"every case needs a name of its own; got {names}")
        if not any(case.seeds for case in self.cases):
            raise ValueError("every case's seeds are empty: nothing to evaluate")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1; got {self.workers}")
        for mca in self.mcas:
            mca.validate()
        self.to_config().validate()

    def to_config(self) -> EvaluationConfig:
        """The `mca_drake.studies.evaluation.EvaluationConfig` of this scenario."""
        cases = [case.to_case() for case in self.cases if case.seeds]
        return EvaluationConfig(
            mcas=tuple(self.mcas),
            cases=tuple(cases),
            duration_s=self.duration_s,
            bound=self.bound,
            platform=self.platform,
        )


@dataclasses.dataclass
class DatasetScenario:
    """Closed-loop dataset generation (the training data of the plant models and DPC)."""

    # Vehicle flown by JSBSim (`mca_drake.references.jsbsim.VEHICLES`), or a car that
    # drives (`mca_drake.references.driving.CARS`), when `vehicles` is empty.
    vehicle: str = ClosedLoopDatasetConfig.vehicle
    # Vehicles of a mixed set: flight_seeds[i] flies (or drives) vehicles[i % len(vehicles)].
    vehicles: list[str] = dataclasses.field(default_factory=list)
    # Flight seeds (evaluation uses 1000 on; keep these apart).
    flight_seeds: list[int] = dataclasses.field(
        default_factory=lambda: list(ClosedLoopDatasetConfig().flight_seeds)
    )
    # Length of each flight, s.
    flight_duration_s: float = ClosedLoopDatasetConfig.flight_duration_s
    # Share of the flights flown by a pilot whose style is drawn per flight (each flight's
    # source is drawn from its seed).
    random_style_share: float = ClosedLoopDatasetConfig.random_style_share
    # Share of the flights replaced by synthetic motion in the vehicle's envelope; the rest
    # of the flights are the scripted pilot's.
    synthetic_share: float = ClosedLoopDatasetConfig.synthetic_share
    # Segment length n_p, steps.
    horizon: int = ClosedLoopDatasetConfig.horizon
    # How the flights' motion becomes the reference the MCA cues and the dataset holds
    # (`mca_drake.references.reference.ReferenceScaling`; default 0.5 each, no limits).
    scaling: ReferenceScaling = dataclasses.field(default_factory=ReferenceScaling)
    # MCA that generates the trajectories: a config or a name.
    mca: McaConfig = dataclasses.field(default_factory=lambda: ClosedLoopDatasetConfig().mca)
    # Seed of the shuffle before the 70/20/10 split.
    split_seed: int = ClosedLoopDatasetConfig.split_seed
    # CPUs of the local Ray, one flight each (1: one after the other, in this process).
    workers: int = 1
    # A Ray cluster to run on instead; empty: RAY_ADDRESS or a local Ray.
    address: str = ""
    # Folder of the per-flight files and the merged dataset.npz (resumable).
    output_dir: str = DEFAULT_DATASET_DIR
    # The motion platform the MCA cues on: a packaged name (`mca-drake platforms`), a
    # platform file, or an inline !SerialRobot {...}, !Hexapod {...} or !Rig {...}.
    platform: PlatformField = DEFAULT_PLATFORM

    def __post_init__(self) -> None:
        self.mca = as_mca_config(self.mca, packaged_name(self.platform))

    def validate(self) -> None:
        """Raises ValueError for values that cannot run."""
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1; got {self.workers}")
        check_platform(self.platform)
        self.mca.validate()
        self.to_config().validate()

    def to_config(self) -> ClosedLoopDatasetConfig:
        """The `mca_drake.studies.closed_loop_dataset.ClosedLoopDatasetConfig` of this
        scenario."""
        return ClosedLoopDatasetConfig(
            vehicle=self.vehicle,
            vehicles=tuple(self.vehicles),
            flight_seeds=tuple(self.flight_seeds),
            flight_duration_s=self.flight_duration_s,
            random_style_share=self.random_style_share,
            synthetic_share=self.synthetic_share,
            horizon=self.horizon,
            scaling=self.scaling,
            mca=self.mca,
            split_seed=self.split_seed,
            platform=self.platform,
        )


@dataclasses.dataclass
class LiveScenario:
    """Live motion cueing of a running flight or racing simulator's UDP telemetry
    (`mca-drake live`), optionally driving a KUKA robot over RSI."""

    # Telemetry protocol: fgnetfdm, xplane, csv, beamng (BeamNG.drive MotionSim), outsim
    # (Live for Speed) or f1 (EA Sports F1 23/24).
    protocol: str = "fgnetfdm"
    # X-Plane's version, 11 or 12 (protocol xplane only; 0 otherwise).
    xplane_version: int = 0
    # FGNetFDM: the unit (s) of the packets' time, as JSBSim's <time resolution="..."/> sets
    # it; 0: the packets carry none (arrival times).
    fgnetfdm_time_resolution_s: float = 0.0
    # BeamNG MotionSim: the signs of its angles and angular rates (protocol beamng).
    beamng: BeamNGConfig = dataclasses.field(default_factory=BeamNGConfig)
    # Live for Speed: the cfg.txt OutSim Opts the packets follow (protocol outsim).
    outsim: OutSimConfig = dataclasses.field(default_factory=OutSimConfig)
    # F1 games: the UDP format year and the signs of the motion values (protocol f1).
    f1: F1Config = dataclasses.field(default_factory=F1Config)
    # Address to listen on (loopback by default) and UDP port (0: any free one).
    host: str = "127.0.0.1"
    port: int = 5500
    # The telemetry senders allowed to move the robot: "HOST" or "HOST:PORT" (IPv4); empty:
    # the first sender is locked in. Datagrams from anyone else are counted and ignored.
    allowed_senders: list[str] = dataclasses.field(default_factory=list)
    # Seconds of live cueing.
    duration_s: float = 600.0
    # The motion cueing algorithm (a typed config or a name, as in ClosedLoopScenario).
    mca: McaConfig = dataclasses.field(default_factory=DpcConfig)
    # "analytical" or "multibody" (the KR500 station).
    plant: str = "analytical"
    # rsi://HOST:PORT: drive a KUKA robot over RSI, the driver listening there for the
    # controller's state packets (analytical plant); "": no robot.
    robot: str = ""
    # The robot's RSI interpolation cycle, ms (4 or 12).
    rsi_cycle_ms: int = 4
    # The RSI driver's settings: the controller's address, its IPOC unit, the robot's home
    # pose in axis angles (home_deg, deg) and axis signs, the external axes' (a rail's E1,
    # mm: external_home, external_signs), the tolerances of the home check, the XML tags
    # (docs/guides/rsi.md gives the KR500's). `robot` and `rsi_cycle_ms` set its listening
    # address and cycle.
    rsi: RsiDriverConfig = dataclasses.field(default_factory=RsiDriverConfig)
    # Pace of the loop against the wall clock: 1 is real time (live telemetry, a robot); 0
    # steps as fast as it can (a replayed stream); at most 10 (MAX_LIVE_REALTIME_RATE).
    realtime_rate: float = 1.0
    # The input plausibility guard in front of the MCA (`mca_drake.cueing.plausibility`:
    # spikes, step bounds, a paused game's frozen stream faded out and back).
    plausibility: PlausibilityConfig = dataclasses.field(default_factory=PlausibilityConfig)
    # How the vehicle's motion becomes the reference the MCA cues
    # (`mca_drake.references.reference.ReferenceScaling`): angular_scale and force_scale
    # (default 0.5 each), per-channel limits and limit_mode. The run is still scored against
    # the default scaling, so its PI stays comparable; the summary records the scaling.
    scaling: ReferenceScaling = dataclasses.field(default_factory=ReferenceScaling)
    # The cabin comfort bound between the MCA and the robot (`mca_drake.comfort`: the
    # largest change of the cabin's specific force in one control period; 0: none).
    comfort: ComfortConfig = dataclasses.field(default_factory=ComfortConfig)
    # The operator's controls while the run goes on (`mca_drake.live.controls`): the first
    # intensity and gains, the ramp every change follows, the UDP control port and who may
    # use it, the keyboard and the operator page in Meshcat.
    controls: ControlsConfig = dataclasses.field(default_factory=ControlsConfig)
    # The rig's own output (`mca_drake.live.rig_output`): the actuator positions every
    # control period to udp://HOST:PORT or serial://PATH?baud=N, in ASCII, a template or a
    # binary layout; url "": none.
    rig: RigOutputConfig = dataclasses.field(default_factory=RigOutputConfig)
    # udp://HOST:PORT for the head's pose relative to home every control period, for VR
    # motion compensation (`mca_drake.live.pose_stream`); "": none.
    pose_stream: str = ""
    # The result summary with its live (and rsi) block; "": none.
    output_json: str = "results/live/summary.json"
    # The run's time series as CSV, one row per control period, with the supervisor's
    # health (`mca_drake.simulation.trajectory`); "": none.
    trajectory: str = ""
    # The motion platform cued: a packaged name (`mca-drake platforms`), a platform file,
    # or an inline !SerialRobot {...}, !Hexapod {...} or !Rig {...}.
    platform: PlatformField = DEFAULT_PLATFORM

    def __post_init__(self) -> None:
        self.mca = as_mca_config(self.mca, packaged_name(self.platform))

    def validate(self) -> None:
        """Raises ValueError for values that cannot run, naming the field."""
        check_config_numbers(self)
        if self.plant not in PLANTS:
            raise ValueError(f"plant must be one of {', '.join(PLANTS)}; got {self.plant!r}")
        check_range("LiveScenario", "duration_s", self.duration_s, CONTROL_PERIOD_S, MAX_DURATION_S)
        check_platform(self.platform)
        if self.rsi_cycle_ms not in (4, 12):
            raise ValueError(f"rsi_cycle_ms must be 4 or 12; got {self.rsi_cycle_ms}")
        try:
            allowed_senders(self.allowed_senders)
        except ValueError as err:
            raise ValueError(f"LiveScenario.allowed_senders: {err}") from None
        check_range(
            "LiveScenario", "realtime_rate", self.realtime_rate, 0.0, MAX_LIVE_REALTIME_RATE
        )
        try:
            self.rsi.validate()
        except ValueError as err:
            raise ValueError(f"LiveScenario.rsi: {err}") from None
        self.plausibility.validate()
        self.scaling.validate()
        self.comfort.validate()
        for name in ("beamng", "outsim", "f1", "controls"):
            try:
                getattr(self, name).validate()
            except ValueError as err:
                raise ValueError(f"LiveScenario.{name}: {err}") from None
        if self.pose_stream and where(self.pose_stream)[0] != "udp":
            raise ValueError("LiveScenario.pose_stream goes to udp://HOST:PORT")
        if self.rig.url:
            try:
                self.rig.validate(load_platform(self.platform).num_joints)
            except ValueError as err:
                raise ValueError(f"LiveScenario.rig: {err}") from None
        if self.robot and self.realtime_rate != 1.0:
            raise ValueError(
                f"a robot runs in real time: realtime_rate 1, not {self.realtime_rate}"
            )
        if self.robot and self.plant != "analytical":
            raise ValueError("a robot over RSI follows the analytical plant: plant analytical")
        if self.robot:
            # the driver moves the robot's axes A1-A6 and, for joints beyond them, external
            # axes E1..: the platform must fit one controller, with the settings' lengths
            robot = load_platform(self.platform)
            try:
                self.rsi.axis_map(robot.joint_kinds, robot.home)
            except ValueError as err:
                raise ValueError(f"platform {robot.name!r} over RSI: {err}") from None
        if getattr(self.mca, "preview_steps", 0) and not getattr(self.mca, "predictor", ""):
            raise ValueError(
                "live telemetry has no future: the NMPC's preview_steps must be 0, or come "
                "from a predictor (nmpc-rti-predictive)"
            )
        self.mca.validate()
        if isinstance(self.mca, DpcConfig):
            _, metadata = load_policy_arrays(
                self.mca.policy_path(load_platform(self.platform).name)
            )
            if policy_preview_steps(metadata) and not self.mca.predictor:
                raise ValueError(
                    "live telemetry has no future: the DPC policy reads a reference preview; "
                    "name a predictor to forecast it (dpc-predictive)"
                )


# Fastest live pace accepted: past 10x real time the loop's own step is the limit anyway.
MAX_LIVE_REALTIME_RATE = 10.0

# typing.Union, not `|`: Drake's YAML loader reads the members' tags from it.
Scenario = Union[  # noqa: UP007
    PlantDemoScenario, ClosedLoopScenario, EvaluationScenario, DatasetScenario, LiveScenario
]


@dataclasses.dataclass
class ScenarioFile:
    """What a diagrams/*.yaml file holds: one job, tagged with its type, e.g.
    `scenario: !ClosedLoopScenario {mca: !DpcConfig {}, duration_s: 600}`."""

    # The job to run and its settings.
    scenario: Scenario = dataclasses.field(default_factory=PlantDemoScenario)


def _union_members(schema) -> tuple:
    """The members of a Union or Optional type (without None); () for any other type."""
    if typing.get_origin(schema) in (Union, types.UnionType):
        return tuple(t for t in typing.get_args(schema) if t is not type(None))
    return ()


def _field_types(schema) -> dict | None:
    """{field name: type} of a dataclass or of a Drake config class (`__fields__`), else
    None."""
    if dataclasses.is_dataclass(schema):
        return typing.get_type_hints(schema)
    fields = getattr(schema, "__fields__", None)
    if isinstance(fields, tuple) and all(hasattr(f, "name") for f in fields):
        return {f.name: f.type for f in fields}
    return None


def _at(where: str) -> str:
    return f"{where}: " if where else ""


def _prepare(schema, raw, current, where: str):
    """Checks untyped YAML `raw` against `schema` before Drake loads it, so that a mistake
    fails naming the field and its class, and resolves the shorthands of a union field:

    - an MCA given by name (`mca: nmpc-rti`) becomes that MCA's default config, tagged;
    - a tagged value replaces the field with a config of that class, every field not given
      at its default (`mca: !NmpcConfig {washout_weight: 0.1}`);
    - an untagged mapping changes fields of the `current` value and keeps its class (an
      override `{mca: {washout_weight: 0.1}}` of an NmpcConfig stays that NmpcConfig);
      without a current value it is the union's default type where it has one
      (`_UNTAGGED_DEFAULTS`: a `flight:` mapping is a FlightSpec).

    Returns the prepared raw value. Raises ValueError.
    """
    members = _union_members(schema)
    if len(members) == 1:  # Optional[X]: X or null
        return raw if raw is None else _prepare(members[0], raw, current, where)
    if members:
        return _prepare_union(members, raw, current, where)
    if typing.get_origin(schema) is list:
        if not isinstance(raw, list):
            return raw  # Drake's loader names the type it expected
        (item,) = typing.get_args(schema)
        return [_prepare(item, v, None, f"{where}[{i}]") for i, v in enumerate(raw)]
    fields = _field_types(schema)
    if fields is None:
        return raw
    if raw is None:
        raise ValueError(f"{_at(where)}a {schema.__name__} is required, not null")
    if not isinstance(raw, dict):
        return raw
    unknown = [k for k in raw if k not in fields]
    if unknown:
        raise ValueError(
            f"{_at(where)}unknown field {', '.join(map(repr, unknown))} of "
            f"{schema.__name__}; valid: {', '.join(fields)}{_FIELD_HINTS.get(schema, '')}"
        )
    return {
        k: _prepare(
            fields[k],
            v,
            getattr(current, k) if current is not None else None,
            f"{where}.{k}" if where else k,
        )
        for k, v in raw.items()
    }


# Said with an unknown field of these classes: where their fields went.
_FIELD_HINTS = {
    EvaluationScenario: (
        " (the suite's cases are one list, `cases: [{name: A, vehicle: light, seeds: "
        "[1000, 1001]}, {name: C, vehicles: [t6texan2, T38], seeds: [3000]}, ...]`: "
        "diagrams/evaluation.yaml)"
    )
}


# The type an untagged mapping of a union field is, where nothing else says: a flight
# field's mapping names a flight (a drive is tagged !DriveSpec).
_UNTAGGED_DEFAULTS = {frozenset({FlightSpec, DriveSpec}): FlightSpec}


def _prepare_union(members: tuple, raw, current, where: str):
    """`_prepare` for a union field (the MCA, the platform, or a file's scenario)."""
    is_mca = set(members) == set(typing.get_args(McaConfig))
    if str in members and isinstance(raw, str):  # a name (the platform's)
        return raw
    by_tag = {f"!{t.__name__}": t for t in members if t is not str}
    expected = f"a tagged value ({', '.join(by_tag)})"
    if str in members:
        expected = f"a name or {expected}"
    if is_mca:
        expected += f" or an MCA name ({', '.join(MCA_NAMES)}, or one with a profile suffix)"
    if isinstance(raw, str) and is_mca:
        try:
            config = mca_config_from_name(raw)
        except ValueError as error:
            raise ValueError(f"{_at(where)}{error}") from None
        return {"_tag": f"!{type(config).__name__}", **dataclasses.asdict(config)}
    if raw is None and not is_mca:
        names = " or ".join(t.__name__ for t in members)
        raise ValueError(f"{_at(where)}a {names} is required, not null")
    if not isinstance(raw, dict):
        raise ValueError(f"{_at(where)}give {expected}; got {raw!r}")
    tag = raw.get("_tag")
    body = {k: v for k, v in raw.items() if k != "_tag"}
    if tag is None:
        kind = type(current)
        if kind not in members:
            kind = _UNTAGGED_DEFAULTS.get(frozenset(members), kind)
        if kind not in members:
            raise ValueError(f"{_at(where)}give {expected}: the type is not known here")
        return {"_tag": f"!{kind.__name__}", **_prepare(kind, body, current, where)}
    if tag not in by_tag:
        raise ValueError(f"{_at(where)}unknown type {tag}; valid: {', '.join(by_tag)}")
    kind = by_tag[tag]
    body = _prepare(kind, body, None, where)
    if is_mca:
        # a fresh config of that class, or of its profile's settings (`profile: ground`):
        # every field not given at its default, or at the profile's
        try:
            base = profile_config(kind, body["profile"]) if body.get("profile") else kind()
        except ValueError as error:
            raise ValueError(f"{_at(where)}{error}") from None
        body = {**dataclasses.asdict(base), **body}
    return {"_tag": tag, **body}


def load_scenario(path: str | Path, overrides: str | Sequence[str] | None = None) -> Scenario:
    """Loads the `scenario` of a YAML file, with optional text overrides.

    Args:
        path: the YAML file, or the name of a scenario the package carries
            (`mca_drake.resources.packaged_scenarios`: "closed_loop_dpc", "live_rsi", ...).
        overrides: optional YAML text (or several, applied in order) on top of the file's
            scenario, for quick changes: '{scenario: {duration_s: 5}}' or just
            '{duration_s: 5}'; an MCA is replaced with its tag,
            `{mca: !NmpcConfig {mode: rti, washout_weight: 0.1}}`, or its fields changed
            without one, `{mca: {washout_weight: 0.1}}`.

    Raises:
        FileNotFoundError: no such file and no packaged scenario of that name.
        ValueError: unknown field (named with its class), a value of the wrong type, or a
            value out of range.
    """
    path = scenario_path(path)
    if path.stat().st_size > MAX_YAML_BYTES:
        raise ValueError(f"{path}: over {MAX_YAML_BYTES} bytes, too large for a scenario")
    text = path.read_text(encoding="utf-8", errors="replace")
    check_yaml_size(text, str(path))
    for number, override in enumerate(
        [overrides] if isinstance(overrides, str) else overrides or ()
    ):
        check_yaml_size(override, f"override {number + 1} ({quoted(override)})")
    try:
        raw_file = _prepare(ScenarioFile, yaml_load(data=text), None, "")
        scenario = yaml_load_typed(schema=ScenarioFile, data=yaml_dump(raw_file)).scenario
        for override in [overrides] if isinstance(overrides, str) else overrides or ():
            # an empty override is no mapping (Drake's loader fails on it without a word)
            raw = yaml_load(data=override) if override.strip() else None
            if not isinstance(raw, dict):
                raise ValueError(f"an override must be a YAML mapping; got {quoted(override)}")
            if set(raw) == {"scenario"}:
                raw = raw["scenario"]
            # Applied to the loaded scenario's own type, so a tagged file needs no tag here.
            raw = _prepare(type(scenario), raw, scenario, "")
            scenario = yaml_load_typed(
                schema=type(scenario), data=yaml_dump(raw), defaults=scenario
            )
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML: {err}".replace("\n", " ")) from err
    except (RuntimeError, ValueError, TypeError, AssertionError) as err:
        raise ValueError(f"{path}: {err}") from err
    try:
        scenario.validate()
    except (ValueError, FileNotFoundError) as err:
        raise ValueError(f"{path}: {err}") from err
    return scenario
