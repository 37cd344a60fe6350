"""Adversarial references: vehicle motion that no motion simulator can render.

Used to show that an MCA keeps the robot inside its limits whatever it is asked (tests) and
to time MCAs where their constraints are most active (benchmarks).
"""

from __future__ import annotations

import numpy as np

from mca_drake.conventions import CONTROL_PERIOD_S, GRAVITY
from mca_drake.references.recording import Recording
from mca_drake.references.reference import Reference, reference_from_recording

# The kinds, and when the step or spin starts (s).
ADVERSARIAL_KINDS = ("step_fx", "step_fy", "step_fz", "spin_x", "spin_y", "spin_z", "chirp")
ONSET_S = 1.0


def adversarial_reference(kind: str, duration_s: float = 5.0) -> Reference:
    """A reference of `duration_s` (s, at the control period) for one of ADVERSARIAL_KINDS:
    a 3 g step of specific force along one head axis ("step_fx"...), a 3 rad/s spin about one
    ("spin_x"...), both from ONSET_S on, or a 1 g surge chirp from 0.1 to 5 Hz ("chirp").

    Raises:
        ValueError: an unknown kind or a non-positive duration.
    """
    if kind not in ADVERSARIAL_KINDS:
        raise ValueError(f"unknown adversarial reference {kind!r}; valid: {ADVERSARIAL_KINDS}")
    if not duration_s > 0:
        raise ValueError(f"duration_s must be positive; got {duration_s}")
    t = np.arange(0.0, duration_s + 1e-9, CONTROL_PERIOD_S)
    omega = np.zeros((t.size, 3))
    f = np.tile([0.0, 0.0, GRAVITY], (t.size, 1))
    on = t >= ONSET_S
    if kind.startswith("step_f"):
        f[on, "xyz".index(kind[-1])] += 3 * GRAVITY
    elif kind.startswith("spin_"):
        omega[on, "xyz".index(kind[-1])] = 3.0
    else:
        rate = (5.0 - 0.1) / duration_s
        f[:, 0] += GRAVITY * np.sin(2 * np.pi * (0.1 * t + 0.5 * rate * t * t))
    return reference_from_recording(Recording(t, omega, f), name=kind)
