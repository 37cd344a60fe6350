"""The vehicles: one JSBSim model each, its airframe constants and its flight defaults.

Vehicle names are what users type (`FlightSpec.vehicle`, `--vehicles`): the paper's two
classes keep their names ("light": c172p, "jet": global5000); every other vehicle is named
by its JSBSim model. `VEHICLE_CLASSES` says what each is.

    light      c172p       light single (piston)           take-off to landing
    jet        global5000  business jet                    take-off to landing
    f16        f16         fighter (fly-by-wire)           airborne
    DHC6       DHC6        twin turboprop utility          airborne
    A320       A320        narrow-body airliner            airborne
    787-8      787-8       wide-body airliner              airborne
    t6texan2   t6texan2    turboprop aerobatic trainer     airborne
    T38        T38         supersonic jet trainer          airborne
    MD11       MD11        three-engine wide-body          airborne
    B747       B747        four-engine jumbo               airborne
    A4         A4          attack jet                      airborne
    F4N        F4N         fighter-bomber                  airborne
    T37        T37         subsonic jet trainer            airborne
    f15        f15         air-superiority fighter         airborne

"airborne": the pilot's ground constants (taxi, rotation, flare) were flown only for the
first two; the others' flights start trimmed at the maneuver altitude and fly maneuvers.
JSBSim's piston twins and singles other than the c172p (c310, c182, p51d) and its turboprop
transports (L410, C130) do not trim with their engines as `propulsion/set-running` leaves
them, and the fokker100 reads a FlightGear-only property: they are not in the fleet.

Three groups: TRAINING_VEHICLES (datasets and tuning), UNSEEN_VEHICLES (evaluation case C)
and VALIDATION_VEHICLES, flown to choose between training recipes on aircraft that training
never saw without choosing on case C's (so they are not unseen for evaluation either). The
T37 is a training vehicle of the default policy; the f15 is in none: training datasets may
fly it.
JSBSim's OV10 and Concorde crashed in their first flights with first-guess constants, as did
the F80C in 2 of 26 flights (a steep turn, a stall); the f104 reads a radar property its
files do not define, and the pc7 and f22 do not trim: none of them is in the fleet.

JSBSim's `737` and `pa28` are reserved for unseen-vehicle checks: they are not vehicles here,
and `check_vehicle` refuses them by name.
"""

from __future__ import annotations

import math

from mca_drake.references.jsbsim.aircraft import DEG, FT, KT, Airframe

# Kept for checks on aircraft no tuning or training may see (the project's rule).
RESERVED_MODELS = ("737", "pa28")

VEHICLE_CLASSES = {
    "light": "light single",
    "jet": "business jet",
    "f16": "fighter",
    "DHC6": "twin turboprop utility",
    "A320": "narrow-body airliner",
    "787-8": "wide-body airliner",
    "t6texan2": "turboprop aerobatic trainer",
    "T38": "supersonic jet trainer",
    "MD11": "three-engine wide-body",
    "B747": "four-engine jumbo",
    "A4": "attack jet",
    "F4N": "fighter-bomber",
    "T37": "subsonic jet trainer",
    "f15": "air-superiority fighter",
}
VEHICLES = tuple(VEHICLE_CLASSES)
# The default policy's training flights fly these (the shipped MCA weights were tuned on
# light and jet). The T37 is there because the f16, the only other aerobatic type, flies by
# wire (its turns come coordinated and smooth) and case C's trainers do not. Evaluation
# case C flies UNSEEN_VEHICLES, which neither training nor tuning may fly: an aerobatic
# turboprop trainer, a supersonic jet trainer, a trijet and a jumbo.
TRAINING_VEHICLES = ("light", "jet", "f16", "DHC6", "A320", "787-8", "T37")
UNSEEN_VEHICLES = ("t6texan2", "T38", "MD11", "B747")
# Flown to compare DPC training recipes (development flights of aircraft no training saw);
# neither training nor tuning nor the evaluation suite flies them.
VALIDATION_VEHICLES = ("A4", "F4N")


def _airborne(
    model: str,
    engines: int,
    *,
    stall_kt: float,
    never_exceed_kt: float,
    climb_rate: float,
    pitch_deg: tuple[float, float],
    heading_bank_deg: float,
    stall_alpha: float,
    qbar_ref_psf: float,
    gains: tuple[float, float, float],
    rates_deg: tuple[float, float, float],
    max_load_factor: float,
    retractable_gear: bool,
    piston: bool = False,
    agile: bool = False,
) -> Airframe:
    """An airframe flown airborne only: the constants of the maneuvers as given (speeds kt,
    climb and descent rate m/s, pitch limits (max, min) deg, gains (roll rate, pitch rate,
    yaw), rate limits (roll, roll aggressive, pitch) deg/s); the ground-only ones (taxi,
    rotation, flare, approach) are placeholders that no airborne flight reads."""
    return Airframe(
        model=model,
        engines=engines,
        rotate_speed=1.1 * stall_kt * KT,
        climb_speed=1.5 * stall_kt * KT,
        approach_speed=1.3 * stall_kt * KT,
        taxi_speed=5.0,
        stall_speed=stall_kt * KT,
        never_exceed_speed=never_exceed_kt * KT,
        climb_rate=climb_rate,
        descent_rate=climb_rate,
        rotate_pitch=8 * DEG,
        max_pitch=pitch_deg[0] * DEG,
        min_pitch=pitch_deg[1] * DEG,
        heading_bank=heading_bank_deg * DEG,
        stall_alpha=stall_alpha,
        recovery_pitch_change=-8 * DEG,
        recovered_alpha=0.6 * stall_alpha,
        full_stall=False,
        approach_height=300.0,
        flare_height=10.0,
        cg_height_on_ground=0.0,
        ground_pitch=0.0,
        touchdown_pitch=5 * DEG,
        takeoff_flaps=0.0,
        landing_flaps=0.0,
        flaps_up_speed=0.0,  # flaps stay up
        retractable_gear=retractable_gear,
        nosewheel_steering=False,
        qbar_ref_psf=qbar_ref_psf,
        roll_rate_gain=gains[0],
        pitch_rate_gain=gains[1],
        yaw_gain=gains[2],
        roll_rate_max=rates_deg[0] * DEG,
        roll_rate_aggressive=rates_deg[1] * DEG,
        pitch_rate_max=rates_deg[2] * DEG,
        max_load_factor=max_load_factor,
        idle_throttle=0.0,
        rollout_s=60.0,
        piston=piston,
        agile=agile,
        ground_ops=False,
    )


def _airliner(
    model: str,
    engines: int,
    *,
    stall_kt: float,
    never_exceed_kt: float,
    rates_deg: tuple[float, float, float],
    climb_rate: float = 12.0,
    max_load_factor: float = 4.0,
) -> Airframe:
    """An airborne-only transport jet: the jet's (global5000's) pitch limits, bank, gains and
    dynamic-pressure reference, with the type's speeds and rate limits (`_airborne`)."""
    return _airborne(
        model,
        engines,
        stall_kt=stall_kt,
        never_exceed_kt=never_exceed_kt,
        climb_rate=climb_rate,
        pitch_deg=(20, -10),
        heading_bank_deg=25,
        stall_alpha=0.19,
        qbar_ref_psf=200.0,
        gains=(1.4, 2.0, 3.0),
        rates_deg=rates_deg,
        max_load_factor=max_load_factor,
        retractable_gear=True,
    )


def _fast_jet(
    model: str, engines: int, *, stall_kt: float, never_exceed_kt: float, qbar_ref_psf: float
) -> Airframe:
    """An airborne-only jet trainer or fighter without fly-by-wire: the T38's pitch limits,
    bank, gains, rate limits, climb rate and load factor, with the type's speeds and
    dynamic-pressure reference (`_airborne`)."""
    return _airborne(
        model,
        engines,
        stall_kt=stall_kt,
        never_exceed_kt=never_exceed_kt,
        climb_rate=20.0,
        pitch_deg=(30, -20),
        heading_bank_deg=30,
        stall_alpha=0.3,
        qbar_ref_psf=qbar_ref_psf,
        gains=(0.8, 1.2, 2.0),
        rates_deg=(40, 80, 12),
        max_load_factor=7.0,
        retractable_gear=True,
        agile=True,
    )


AIRFRAMES = {
    "light": Airframe(
        model="c172p",
        engines=1,
        rotate_speed=55 * KT,
        climb_speed=75 * KT,
        approach_speed=65 * KT,
        taxi_speed=5.0,
        stall_speed=48 * KT,
        never_exceed_speed=163 * KT,
        climb_rate=3.5,
        descent_rate=4.0,
        rotate_pitch=8 * DEG,
        max_pitch=22 * DEG,
        min_pitch=-15 * DEG,
        heading_bank=25 * DEG,
        stall_alpha=0.27,
        recovery_pitch_change=-10 * DEG,
        recovered_alpha=0.15,
        full_stall=True,
        approach_height=150.0,
        flare_height=6.0,
        cg_height_on_ground=4.35 * FT,
        ground_pitch=2.4 * DEG,
        touchdown_pitch=7 * DEG,
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=1.0,
        flaps_up_speed=65 * KT,
        retractable_gear=False,
        nosewheel_steering=True,
        qbar_ref_psf=30.0,
        roll_rate_gain=1.0,
        pitch_rate_gain=1.5,
        yaw_gain=3.0,
        roll_rate_max=20 * DEG,
        roll_rate_aggressive=50 * DEG,
        pitch_rate_max=12 * DEG,
        max_load_factor=6.0,
        idle_throttle=0.0,
        rollout_s=35.0,
        piston=True,
        agile=True,
        ground_ops=True,
    ),
    "jet": Airframe(
        model="global5000",
        engines=2,
        rotate_speed=150 * KT,
        climb_speed=250 * KT,
        approach_speed=130 * KT,
        taxi_speed=8.0,
        stall_speed=150 * KT,
        never_exceed_speed=360 * KT,
        climb_rate=12.0,
        descent_rate=12.0,
        rotate_pitch=10 * DEG,
        max_pitch=20 * DEG,
        min_pitch=-12 * DEG,
        heading_bank=20 * DEG,
        stall_alpha=0.19,
        recovery_pitch_change=-4 * DEG,
        recovered_alpha=0.13,
        full_stall=False,
        approach_height=300.0,
        flare_height=20.0,
        cg_height_on_ground=8.79 * FT,
        ground_pitch=0.3 * DEG,
        touchdown_pitch=6 * DEG,
        # The model's flaps add 0.05 lift coefficient per degree (1.5 at 30 deg): with full
        # flaps it would approach at a negative angle of attack, so 20 deg is enough.
        takeoff_flaps=1.0 / 3.0,
        landing_flaps=2.0 / 3.0,
        flaps_up_speed=180 * KT,
        retractable_gear=True,
        nosewheel_steering=False,
        qbar_ref_psf=200.0,
        roll_rate_gain=1.4,
        pitch_rate_gain=2.0,
        yaw_gain=3.0,
        roll_rate_max=8 * DEG,
        roll_rate_aggressive=15 * DEG,
        pitch_rate_max=5 * DEG,
        max_load_factor=4.0,
        idle_throttle=0.0,
        rollout_s=50.0,
        ground_ops=True,
    ),
    # Airborne only (see the module docstring); first guesses from the types' handbooks,
    # then flown: `benchmarks/bench_flight.py` flies every vehicle over several seeds.
    "f16": _airborne(
        "f16",
        1,
        stall_kt=130,
        never_exceed_kt=700,
        climb_rate=20.0,
        pitch_deg=(30, -20),
        heading_bank_deg=30,
        stall_alpha=0.33,
        qbar_ref_psf=340.0,
        gains=(0.5, 1.0, 1.0),
        rates_deg=(45, 90, 15),
        max_load_factor=9.0,
        retractable_gear=True,
        agile=True,
    ),
    "DHC6": _airborne(
        "DHC6",
        2,
        stall_kt=60,
        never_exceed_kt=170,
        climb_rate=6.0,
        pitch_deg=(15, -12),
        heading_bank_deg=25,
        stall_alpha=0.24,
        qbar_ref_psf=55.0,
        gains=(1.0, 1.5, 3.0),
        rates_deg=(15, 35, 10),
        max_load_factor=5.0,
        retractable_gear=False,
        agile=True,
    ),
    "A320": _airliner("A320", 2, stall_kt=140, never_exceed_kt=350, rates_deg=(8, 15, 5)),
    "787-8": _airliner("787-8", 2, stall_kt=150, never_exceed_kt=360, rates_deg=(7, 12, 4)),
    "t6texan2": _airborne(
        "t6texan2",
        1,
        stall_kt=80,
        never_exceed_kt=316,
        climb_rate=10.0,
        pitch_deg=(25, -20),
        heading_bank_deg=30,
        stall_alpha=0.26,
        qbar_ref_psf=120.0,
        gains=(1.0, 1.5, 3.0),
        rates_deg=(30, 70, 12),
        max_load_factor=7.0,
        retractable_gear=True,
        agile=True,
    ),
    "T38": _fast_jet("T38", 2, stall_kt=150, never_exceed_kt=700, qbar_ref_psf=340.0),
    "MD11": _airliner(
        "MD11", 3, stall_kt=150, never_exceed_kt=365, rates_deg=(7, 12, 4), max_load_factor=3.8
    ),
    "B747": _airliner(
        "B747",
        4,
        stall_kt=150,
        never_exceed_kt=365,
        rates_deg=(6, 10, 4),
        climb_rate=10.0,
        max_load_factor=3.8,
    ),
    "A4": _fast_jet("A4", 1, stall_kt=120, never_exceed_kt=580, qbar_ref_psf=300.0),
    "F4N": _fast_jet("F4N", 2, stall_kt=140, never_exceed_kt=700, qbar_ref_psf=340.0),
    "T37": _fast_jet("T37", 2, stall_kt=85, never_exceed_kt=440, qbar_ref_psf=200.0),
    "f15": _fast_jet("f15", 2, stall_kt=130, never_exceed_kt=700, qbar_ref_psf=340.0),
}


def _defaults(
    max_bank_deg: float, altitude_m: tuple[float, float, float], cruise_kt: float
) -> dict:
    """`FlightConfig` knobs: light turbulence with moderate patches, the bank limit (deg),
    the maneuver, lowest and highest altitude above ground (m) and the cruise speed (kt)."""
    maneuver, lowest, highest = altitude_m
    return dict(
        turbulence_severity=2,
        turbulence_patch_severity=3,
        max_bank_rad=max_bank_deg * DEG,
        maneuver_altitude_m=maneuver,
        min_altitude_m=lowest,
        max_altitude_m=highest,
        cruise_speed_mps=cruise_kt * KT,
    )


_TRANSPORT = _defaults(45, (2000.0, 1500.0, 3500.0), 250)
# Default knobs of `FlightConfig` per vehicle (field name: value; angles rad, heights above
# ground m, speeds m/s calibrated).
VEHICLE_DEFAULTS = {
    "light": _defaults(60, (600.0, 400.0, 1200.0), 100),
    "jet": _TRANSPORT,
    "f16": _defaults(75, (2000.0, 1500.0, 4000.0), 350),
    "DHC6": _defaults(50, (800.0, 500.0, 1500.0), 130),
    "A320": _TRANSPORT,
    "787-8": _TRANSPORT,
    "t6texan2": _defaults(70, (1500.0, 1000.0, 3000.0), 200),
    "T38": _defaults(55, (2000.0, 1500.0, 4000.0), 350),
    "MD11": _TRANSPORT,
    "B747": _TRANSPORT,
    "A4": _defaults(60, (2000.0, 1500.0, 4000.0), 300),
    "F4N": _defaults(60, (2000.0, 1500.0, 4000.0), 350),
    "T37": _defaults(60, (1500.0, 1000.0, 3000.0), 250),
    "f15": _defaults(60, (2000.0, 1500.0, 4000.0), 350),
}

JSBSIM_MODELS = {vehicle: air.model for vehicle, air in AIRFRAMES.items()}
# Flights at least this long (s) take off and land by default; shorter ones start airborne.
# Taxi, take-off, climb, descent, approach and roll-out take about 8 minutes in the light
# aircraft (to 600 m) and 9 in the jet (to 2000 m); the rest is maneuvers. Airborne-only
# vehicles never start on the ground.
_FULL_FLIGHT_S = {"light": 600.0, "jet": 720.0}
FULL_FLIGHT_MIN_DURATION_S = {
    vehicle: _FULL_FLIGHT_S[vehicle] if air.ground_ops else math.inf
    for vehicle, air in AIRFRAMES.items()
}
assert set(AIRFRAMES) == set(VEHICLES) == set(VEHICLE_DEFAULTS)
assert set(TRAINING_VEHICLES) | set(UNSEEN_VEHICLES) <= set(VEHICLES)
assert not set(TRAINING_VEHICLES) & set(UNSEEN_VEHICLES)
assert not set(VALIDATION_VEHICLES) & (set(TRAINING_VEHICLES) | set(UNSEEN_VEHICLES))


def check_vehicle(vehicle: str) -> str:
    """`vehicle` itself if it is one of VEHICLES; else ValueError listing the valid ones (and
    saying so when it names an aircraft reserved for unseen-vehicle checks)."""
    if vehicle in RESERVED_MODELS:
        raise ValueError(
            f"'{vehicle}' is reserved for unseen-vehicle checks and is never flown here; "
            f"valid vehicles: {', '.join(VEHICLES)}"
        )
    if vehicle not in AIRFRAMES:
        raise ValueError(f"unknown vehicle '{vehicle}'; valid: {', '.join(VEHICLES)}")
    return vehicle


def check_training_vehicle(vehicle: str) -> str:
    """`check_vehicle`, and ValueError for the aircraft kept for evaluation case C
    (UNSEEN_VEHICLES) or for choosing between recipes (VALIDATION_VEHICLES): tuning and
    training data never fly them."""
    check_vehicle(vehicle)
    kept_for = {v: "evaluation case C" for v in UNSEEN_VEHICLES}
    kept_for.update({v: "choosing between training recipes" for v in VALIDATION_VEHICLES})
    if vehicle in kept_for:
        raise ValueError(
            f"'{vehicle}' is kept for {kept_for[vehicle]} (aircraft never trained or tuned "
            f"on); training and tuning fly: {', '.join(TRAINING_VEHICLES)}"
        )
    return vehicle
