"""Drives: a multi-body car driven through standard manoeuvres on rough roads.

`drive(manoeuvre, duration_s, seed)` returns what an IMU at the driver's head reads as a
`Recording`, like a JSBSim flight's (head frame x forward, y left, z up; SI units).

Modules, each depending only on those above it:

    road      ISO 8608 road profiles
    courses   the manoeuvres' paths and target speeds (ISO 3888-1 double lane change,
              slalom, braking, steady-state circle, laps of a track)
    car       CommonRoad's multi-body vehicle model and what an IMU on it reads
    driver    pure-pursuit steering and speed following
    drive     `drive`: the seeded manoeuvre, driven, with the road and the head offset
"""

from __future__ import annotations

from mca_drake.references.driving.car import CARS
from mca_drake.references.driving.courses import MANOEUVRES
from mca_drake.references.driving.drive import DEFAULT_HEAD_OFFSET_M, drive
from mca_drake.references.driving.road import ROAD_CLASSES

__all__ = ["CARS", "DEFAULT_HEAD_OFFSET_M", "MANOEUVRES", "ROAD_CLASSES", "drive"]
