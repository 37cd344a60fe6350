"""Numpy plant output and its exact Jacobians for a horizon of nodes at once (NMPC use).

python benchmarks/bench_kinematics.py [--nodes 64] [--repeats 300]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import describe, print_calibration, time_calls

from mca_drake.platforms.files import DEFAULT_PLATFORM, load_platform
from mca_drake.platforms.kinematics import plant_output, plant_output_jacobians


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--nodes", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()
    print_calibration()
    robot = load_platform(DEFAULT_PLATFORM)
    rng = np.random.default_rng(0)
    n = args.nodes
    q = rng.uniform(robot.q_min, robot.q_max, size=(n, 6))
    qd = rng.uniform(-robot.qd_max, robot.qd_max, size=(n, 6))
    qdd = rng.uniform(-robot.qdd_max, robot.qdd_max, size=(n, 6))
    print(f"numpy plant, {n} horizon nodes at once")
    y_only = time_calls(lambda: plant_output(q, qd, qdd, robot), repeats=args.repeats)
    print(f"  plant_output:                    {describe(y_only)}")
    full = time_calls(lambda: plant_output_jacobians(q, qd, qdd, robot), repeats=args.repeats)
    print(f"  plant_output + Jacobians:        {describe(full)}")
    one = time_calls(lambda: plant_output(q[0], qd[0], qdd[0], robot), repeats=args.repeats)
    print(f"  plant_output, one node:          {describe(one, 'us')}")


if __name__ == "__main__":
    main()
