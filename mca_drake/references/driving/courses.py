"""The manoeuvres a driver drives: a course (path and target speed) per manoeuvre.

A `Course` is a path in the road plane (x forward at the start, y left; m), sampled every
`SPACING_M` along its length, with the target speed at every point (m/s). Each manoeuvre
starts with a straight lead-in at its entry speed (the car starts there at that speed) and
ends with a run-out:

- `double_lane_change`: ISO 3888-1's severe lane change: 15 m entry lane, 30 m change
  over, 25 m in the offset lane, 25 m back, 15 m exit lane, the offset lane `offset_m` to
  the left (3.5 m by default, a lane and a half), at a constant speed (80 km/h nominal);
  the transitions are cosine ramps;
- `slalom`: a sine path through cones `spacing_m` apart (18 m in the usual tests) with
  `amplitude_m` either side, at a constant speed;
- `braking`: a straight line, braking from the entry speed to a stop at a constant
  deceleration, then standing;
- `circle`: a circle of `radius_m` driven at a slowly rising speed, from 20 km/h to the
  speed of `max_lateral_m_s2` (ISO 4138's constant-radius method), then held;
- `lap`: laps of a closed centre line (a `track` array, or the built-in `TRACK`), the
  target speed from its curvature (`max_lateral_m_s2`) within acceleration and braking
  limits, as a driver takes a track at a brisk pace;
- `proving_ground`: a long drive of the above in a random order on one road: lane changes
  and slaloms on its straights, bends of random radius, braking zones to a lower speed and
  acceleration back, until the drive's length is reached.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.interpolate import CubicSpline

SPACING_M = 0.1
LEAD_IN_S = 3.0
# Braking into a slower segment of a proving-ground drive, m/s^2.
BETWEEN_SEGMENTS_M_S2 = 3.0
MANOEUVRES = ("double-lane-change", "slalom", "braking", "circle", "lap", "proving-ground")


@dataclasses.dataclass(frozen=True)
class Course:
    """A path and the speed to drive it at.

    Attributes:
        x, y: the path's points, m, shape (N,), `SPACING_M` apart along it.
        speed: the target speed at each point, m/s, shape (N,).
        closed: the path is a loop (a lap): it goes on from its start after its end.
        stop_deceleration: how hard the course's stop brakes, m/s^2 (None: the driver's
            `stop_deceleration`).
    """

    x: np.ndarray
    y: np.ndarray
    speed: np.ndarray
    closed: bool = False
    # The deceleration of the course's stop, m/s^2 (None: the driver's own).
    stop_deceleration: float | None = None

    @property
    def length_m(self) -> float:
        """The path's length, m."""
        return SPACING_M * (self.x.size - 1)


def _straight(length_m: float) -> tuple[np.ndarray, np.ndarray]:
    s = np.arange(0.0, length_m + SPACING_M / 2, SPACING_M)
    return s, np.zeros_like(s)


def _ramp(s: np.ndarray, start: float, length: float) -> np.ndarray:
    """0 before `start`, 1 after `start + length`, a cosine ramp between."""
    u = np.clip((s - start) / length, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def _with_arc_length(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The path (x, y) resampled `SPACING_M` apart along its length."""
    steps = np.hypot(np.diff(x), np.diff(y))
    s = np.concatenate([[0.0], np.cumsum(steps)])
    grid = np.arange(0.0, s[-1], SPACING_M)
    return np.interp(grid, s, x), np.interp(grid, s, y)


def double_lane_change(speed_mps: float, offset_m: float = 3.5) -> Course:
    """ISO 3888-1's double lane change at `speed_mps`, the offset lane `offset_m` left."""
    lead = LEAD_IN_S * speed_mps
    s, _ = _straight(lead + 15.0 + 30.0 + 25.0 + 25.0 + 15.0 + 2.0 * speed_mps)
    y = offset_m * (_ramp(s, lead + 15.0, 30.0) - _ramp(s, lead + 70.0, 25.0))
    x, y = _with_arc_length(s, y)
    return Course(x, y, np.full(x.size, speed_mps))


def slalom(
    speed_mps: float, spacing_m: float = 18.0, amplitude_m: float = 1.5, cones: int = 8
) -> Course:
    """A slalom through `cones` cones `spacing_m` apart, `amplitude_m` either side."""
    lead = LEAD_IN_S * speed_mps
    s, _ = _straight(lead + (cones + 1) * spacing_m + 2.0 * speed_mps)
    phase = np.clip((s - lead) / spacing_m, 0.0, cones + 1)
    # a sine through the cones, faded in and out over the first and last half period
    fade = _ramp(s, lead, spacing_m) * (1.0 - _ramp(s, lead + cones * spacing_m, spacing_m))
    y = amplitude_m * fade * np.sin(np.pi * phase)
    x, y = _with_arc_length(s, y)
    return Course(x, y, np.full(x.size, speed_mps))


def braking(speed_mps: float, deceleration_m_s2: float = 6.0) -> Course:
    """Straight-line braking from `speed_mps` to a stop at `deceleration_m_s2`; the car
    stands after the stop."""
    lead = LEAD_IN_S * speed_mps
    stop = speed_mps**2 / (2.0 * deceleration_m_s2)
    s, y = _straight(lead + stop + 5.0)
    left = np.clip(lead + stop - s, 0.0, None)  # m still to go to the stop
    speed = np.minimum(speed_mps, np.sqrt(2.0 * deceleration_m_s2 * left))
    return Course(s, y, speed, stop_deceleration=deceleration_m_s2)


def circle(radius_m: float, max_lateral_m_s2: float = 6.0, ramp_s: float = 60.0) -> Course:
    """A circle of `radius_m` (turning left), the speed rising from 20 km/h to that of
    `max_lateral_m_s2` lateral acceleration over about `ramp_s` s, then held."""
    start, top = 20.0 / 3.6, np.sqrt(max_lateral_m_s2 * radius_m)
    top = max(top, start)
    laps = (0.5 * (start + top) * ramp_s) / (2.0 * np.pi * radius_m) + 1.0
    lead = LEAD_IN_S * start
    s_lead, _ = _straight(lead)
    angle = np.arange(0.0, 2.0 * np.pi * laps, SPACING_M / radius_m)
    x = np.concatenate([s_lead - lead, radius_m * np.sin(angle)])
    y = np.concatenate([np.zeros_like(s_lead), radius_m * (1.0 - np.cos(angle))])
    x, y = _with_arc_length(x, y)
    s = np.arange(x.size) * SPACING_M
    # speed rising linearly in time: v(s) = sqrt(v0^2 + 2 a (s - lead))
    accel = (top - start) / ramp_s
    speed = np.sqrt(start**2 + 2.0 * accel * np.clip(s - lead, 0.0, None))
    return Course(x, y, np.minimum(speed, top))


def _track() -> np.ndarray:
    """The built-in track's centre line (M, 2), m: a 1.3 km circuit with a long straight,
    a hairpin, a fast sweeper and a chicane."""
    t = np.linspace(0.0, 2.0 * np.pi, 400, endpoint=False)
    r = 180.0 + 60.0 * np.cos(2 * t) + 25.0 * np.sin(3 * t) + 12.0 * np.cos(7 * t)
    return np.column_stack([r * np.cos(t) * 1.2, r * np.sin(t)])


TRACK = _track()


def lap(
    track: np.ndarray | None = None,
    max_lateral_m_s2: float = 7.0,
    max_speed_mps: float = 45.0,
    acceleration_m_s2: float = 3.0,
    braking_m_s2: float = 7.0,
) -> Course:
    """Laps of a closed centre line `track` (M, 2), m (default `TRACK`): the target speed
    the lowest of `max_speed_mps`, the curvature's limit sqrt(a_lat / kappa), and what the
    acceleration and braking limits allow from the corners before and after (forward and
    backward passes around the loop)."""
    track = TRACK if track is None else np.asarray(track, dtype=float)
    if track.ndim != 2 or track.shape[1] != 2 or track.shape[0] < 8:
        raise ValueError(
            f"track must be (M >= 8, 2) points of a closed centre line; got {track.shape}"
        )
    if not np.all(np.isfinite(track)):
        raise ValueError("track holds non-finite points")
    # a periodic cubic spline through the centre line, by its chord length: a smooth path
    # whose curvature is the spline's (a polyline's would sit in spikes at its corners)
    closed = np.vstack([track, track[:1]])
    chord = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    spline = CubicSpline(chord, closed, bc_type="periodic")
    fine = np.linspace(0.0, chord[-1], 20 * closed.shape[0])
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(spline(fine), axis=0).T))])
    u = np.interp(np.arange(0.0, arc[-1], SPACING_M), arc, fine)
    (x, y), (dx, dy), (ddx, ddy) = spline(u).T, spline(u, 1).T, spline(u, 2).T
    kappa = np.abs(dx * ddy - dy * ddx) / np.maximum((dx * dx + dy * dy) ** 1.5, 1e-9)
    # the largest curvature within 5 m either side: a corner's speed is set before it
    wrapped = np.concatenate([kappa[-50:], kappa, kappa[:50]])
    kappa = np.lib.stride_tricks.sliding_window_view(wrapped, 101).max(axis=1)
    speed = np.minimum(max_speed_mps, np.sqrt(max_lateral_m_s2 / np.maximum(kappa, 1e-6)))
    for _ in range(2):  # twice around: the limits carry over the start line
        for i in range(speed.size):  # accelerating out of the corners
            speed[i] = min(speed[i], np.sqrt(speed[i - 1] ** 2 + 2 * acceleration_m_s2 * SPACING_M))
        for i in range(speed.size - 1, -1, -1):  # braking into them
            j = (i + 1) % speed.size
            speed[i] = min(speed[i], np.sqrt(speed[j] ** 2 + 2 * braking_m_s2 * SPACING_M))
    # the start on the straight's axis: rotate so that the path leaves along +x
    heading = np.arctan2(y[1] - y[0], x[1] - x[0])
    c, s = np.cos(-heading), np.sin(-heading)
    x0, y0 = x - x[0], y - y[0]
    return Course(c * x0 - s * y0, s * x0 + c * y0, speed, closed=True)


def proving_ground(rng: np.random.Generator, duration_s: float) -> Course:
    """A road of `duration_s` s or more of driving, drawn from `rng`: segments one after the
    other, each on the road's centre line (given by its curvature along its length) with a
    lateral offset and a target speed of its own:

    - straight with an ISO 3888-1 lane change (3-3.8 m) at 60-90 km/h;
    - straight with a slalom (cones 18-24 m apart, up to 6 m/s^2) at 40-60 km/h;
    - a bend of 40-150 m radius and 45-180 degrees either way, entered through 20 m
      clothoids, at the speed of 3-5 m/s^2;
    - a braking zone from the speed before it to 30-60 % of it at 3-7 m/s^2, then
      accelerating back at 2-3 m/s^2 on a straight.

    The target speed between segments falls at most at `BETWEEN_SEGMENTS_M_S2` (braking
    into the slower one before it starts)."""
    kappa, offset, speed, braking = [], [], [], []  # per SPACING_M of road
    cruise = rng.uniform(60.0, 90.0) / 3.6

    def straight(length, v, lateral=None, decel=BETWEEN_SEGMENTS_M_S2):
        n = int(length / SPACING_M) if np.isscalar(v) else np.asarray(v).size
        kappa.append(np.zeros(n))
        offset.append(np.zeros(n) if lateral is None else lateral(np.arange(n) * SPACING_M))
        speed.append(np.full(n, v) if np.isscalar(v) else v)
        braking.append(np.full(n, decel))

    straight(LEAD_IN_S * cruise + 20.0, cruise)
    driven = 0.0
    while driven < duration_s:
        kind = rng.choice(["lane-change", "slalom", "bend", "bend", "braking"])
        if kind == "lane-change":
            v = rng.uniform(60.0, 90.0) / 3.6
            shift = rng.uniform(3.0, 3.8) * rng.choice([-1.0, 1.0])
            length = 15.0 + 30.0 + 25.0 + 25.0 + 15.0
            straight(
                length, v, lambda s, a=shift: a * (_ramp(s, 15.0, 30.0) - _ramp(s, 70.0, 25.0))
            )
        elif kind == "slalom":
            v, spacing = rng.uniform(40.0, 60.0) / 3.6, rng.uniform(18.0, 24.0)
            amplitude = min(rng.uniform(0.6, 1.2), 6.0 / (np.pi * v / spacing) ** 2)
            cones = int(rng.integers(5, 9))
            length = (cones + 1) * spacing

            def weave(s, a=amplitude, d=spacing, c=cones):
                fade = _ramp(s, 0.0, d) * (1.0 - _ramp(s, c * d, d))
                return a * fade * np.sin(np.pi * s / d)

            straight(length, v, weave)
        elif kind == "bend":
            radius = rng.uniform(40.0, 150.0)
            turn = np.radians(rng.uniform(45.0, 180.0)) * rng.choice([-1.0, 1.0])
            v = min(np.sqrt(rng.uniform(3.0, 5.0) * radius), 30.0)
            spiral = 20.0  # m of clothoid either side
            arc = max(abs(turn) * radius - spiral, 1.0)
            n_spiral, n_arc = int(spiral / SPACING_M), int(arc / SPACING_M)
            k = np.sign(turn) / radius
            kappa.append(
                np.concatenate(
                    [np.linspace(0, k, n_spiral), np.full(n_arc, k), np.linspace(k, 0, n_spiral)]
                )
            )
            n = 2 * n_spiral + n_arc
            offset.append(np.zeros(n))
            speed.append(np.full(n, v))
            braking.append(np.full(n, BETWEEN_SEGMENTS_M_S2))
        else:
            before = float(speed[-1][-1])
            slow = before * rng.uniform(0.3, 0.6)
            decel, accel = rng.uniform(3.0, 7.0), rng.uniform(2.0, 3.0)
            down = (before**2 - slow**2) / (2 * decel)
            up = (cruise**2 - slow**2) / (2 * accel)
            s = np.arange(int((down + 10.0 + up) / SPACING_M)) * SPACING_M
            v = np.where(
                s < down,
                np.sqrt(np.maximum(before**2 - 2 * decel * s, slow**2)),
                np.sqrt(
                    np.minimum(slow**2 + 2 * accel * np.maximum(s - down - 10.0, 0.0), cruise**2)
                ),
            )
            straight(s[-1] + SPACING_M, v, decel=decel)
        straight(30.0, float(speed[-1][-1]))  # a short straight between segments
        driven = SPACING_M * sum(a.size for a in speed) / max(cruise, 1.0)
    kappa, offset, speed, braking = (np.concatenate(a) for a in (kappa, offset, speed, braking))
    # the road: heading and position from the curvature, then the lateral offsets
    heading = np.concatenate([[0.0], np.cumsum(kappa[:-1]) * SPACING_M])
    x = np.concatenate([[0.0], np.cumsum(np.cos(heading[:-1])) * SPACING_M])
    y = np.concatenate([[0.0], np.cumsum(np.sin(heading[:-1])) * SPACING_M])
    x, y = x - offset * np.sin(heading), y + offset * np.cos(heading)
    x, y = _with_arc_length(x, y)
    s_road = np.arange(speed.size) * SPACING_M
    along = np.arange(x.size) * SPACING_M
    target = np.interp(along, s_road, speed)
    decel = np.interp(along, s_road, braking)
    # brake into a slower segment before it starts: the target asks for no more braking
    # than the segment's (a braking zone's own, else BETWEEN_SEGMENTS_M_S2; a backward pass)
    for i in range(target.size - 2, -1, -1):
        target[i] = min(target[i], np.sqrt(target[i + 1] ** 2 + 2 * decel[i] * SPACING_M))
    return Course(x, y, target)
