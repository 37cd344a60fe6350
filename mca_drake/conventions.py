"""Names that several layers share, defined once (the README's "Conventions").

SI units everywhere. The world frame W is z up; the head frame H is x forward, y left, z up.
"""

from __future__ import annotations

import numpy as np

# Output channels of the plant y and of a reference, in this order (equation 1): angular
# velocity of H (rad/s), specific force along x and y of H and the kinematic vertical
# acceleration (m/s^2).
CHANNELS = ("w_x", "w_y", "w_z", "f_x", "f_y", "a_z")
# Their count: the size of y and of a reference sample, whatever the platform's joint count.
NUM_CHANNELS = len(CHANNELS)

# The channels' signs in the vehicle's mirror image about its x-z plane (left and right
# swapped): roll and yaw rates and the lateral force change sign, the rest keep it. The KR500
# has the same symmetry (its platform file's `mirror_joint_signs`).
MIRROR_CHANNEL_SIGNS = (-1.0, 1.0, -1.0, 1.0, -1.0, 1.0)

# Standard gravity, m/s^2, and the gravity vector in W.
GRAVITY = 9.81
GRAVITY_W = np.array([0.0, 0.0, -GRAVITY])

# Built-in flights with seeds from here on are evaluation flights: never trained or tuned on.
FIRST_EVALUATION_SEED = 1000

# Control period of the MCAs, the plant and the references, s (100 Hz).
CONTROL_PERIOD_S = 0.01

# Layout of every MCA system's `statistics` output port: the wall-clock time of the last
# control step (s) and running counts of solver failures, safety-clamp interventions and QPs
# solved. An MCA without a solver reports 0 for those.
MCA_STATISTICS = ("step_time_s", "solver_failures", "safety_interventions", "qp_iterations")
