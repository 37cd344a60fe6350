"""Motion sickness by subjective vertical conflict (Bos & Bles), for a passenger in 6 DOF.

The theory (Bos & Bles 1998, "Modelling motion sickness and subjective vertical mismatch
detailed for vertical motions", Brain Research Bulletin 47(5)): the nervous system keeps an
estimate of the vertical, both from what the organs sense and from an internal model of
what they should sense; sickness grows with the conflict between the two. The six-degree-of-
freedom form used here is Kamiji et al.'s (2007) with the passenger's internal model of
Wada's public formulation (no efference copy: the occupant does not drive the motion):

    sensed vertical      dv_s/dt = (f - v_s) / tau - w_s x v_s
    sensed rotation      w_s = tau_d tau_a s^2 / ((tau_d s + 1)(tau_a s + 1)) w      (canals)
    internal vertical    dv_i/dt = (f_i - v_i) / tau - w_i x v_i
    internal force       f_i = (K_vc x_vc + K_ac (f - v_s + v_i)) / (1 + K_ac),
                         dx_vc/dt = v_s - v_i
    internal rotation    w_i = K_wc tau_d s / ((1 + K_wc) tau_d s + 1) w_s
    conflict             c = |v_s - v_i|  (m/s^2)
    Hill function        h = (c / b)^n / (1 + (c / b)^n)
    incidence            MSI = P h / (tau_I s + 1)^2   (% who would vomit)

f is the specific force at the head (m/s^2, the gravito-inertial force: (0, 0, 9.81) at
rest, head frame) and w the head's angular velocity (rad/s). The canals, the internal
rotation and the verticals, which rotate with the sensed rates, are integrated together by
the classical Runge-Kutta method with f and w held over each period (the fastest mode is the
verticals', about 1.3 rad/s: the error at 100 Hz is far below the model's own); the
incidence filter, linear, is discretised exactly (`filters.discretize`). The occupant starts
adapted to the first sample's specific force (both verticals on it) with the canals at rest,
so a run that starts at rest starts without conflict.

The MSI's 12-minute time constant means a few minutes of motion predict small incidences;
the conflict's RMS shows the provocation directly. Both are estimates of a population model,
for comparing MCAs on the same flight, not a prediction for a person.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mca_drake.input_checks import as_float_array, same_shapes
from mca_drake.perception.filters import discretize
from mca_drake.perception.models import TransferFunction


@dataclasses.dataclass(frozen=True)
class SicknessParameters:
    """Parameters of the subjective-vertical-conflict model (defaults: Kamiji et al. 2007 and
    Wada's 6-DOF formulation; P and tau_I from Bos & Bles 1998)."""

    tau: float = 2.0  # low-pass time constant of the verticals, s
    tau_d: float = 7.0  # canals' time constant, s
    tau_a: float = 190.0  # canals' adaptation, s
    k_ac: float = 0.5  # internal model's gain on the sensed acceleration
    k_vc: float = 5.0  # internal model's gain on the vertical conflict's integral, 1/s
    k_wc: float = 10.0  # internal model's gain on the sensed rotation
    b: float = 0.5  # conflict at half the Hill function's range, m/s^2
    n: float = 2.0  # Hill exponent
    p_percent: float = 85.0  # the incidence a lasting large conflict tends to, %
    tau_i: float = 720.0  # incidence time constant (second order), s


@dataclasses.dataclass(frozen=True)
class SicknessResult:
    """The model's signals over a run (T samples).

    Attributes:
        conflict: |v_s - v_i|, m/s^2, shape (T,).
        msi_percent: motion sickness incidence, %, shape (T,).
    """

    conflict: np.ndarray
    msi_percent: np.ndarray

    def summary(self) -> dict[str, float]:
        """The figures a run's summary reports: the conflict's RMS and maximum (m/s^2) and
        the incidence at the end and at its highest (%)."""
        return {
            "conflict_rms_m_s2": float(np.sqrt(np.mean(self.conflict**2))),
            "conflict_max_m_s2": float(np.max(self.conflict)),
            "msi_final_percent": float(self.msi_percent[-1]),
            "msi_max_percent": float(np.max(self.msi_percent)),
        }


def subjective_vertical_conflict(
    specific_force,
    angular_velocity,
    time_step: float,
    parameters: SicknessParameters | None = None,
) -> SicknessResult:
    """The conflict and the motion sickness incidence of a passenger over a run.

    Args:
        specific_force: f at the head, m/s^2, shape (T, 3), head frame (gravity included:
            (0, 0, 9.81) at rest).
        angular_velocity: w of the head, rad/s, shape (T, 3), head frame.
        time_step: the sample period, s.
        parameters: the model's parameters (default SicknessParameters()).
    """
    p = parameters or SicknessParameters()
    f = as_float_array("specific_force", specific_force, last_dim=3)
    w = as_float_array("angular_velocity", angular_velocity, last_dim=3)
    same_shapes(specific_force=f, angular_velocity=w)
    if f.ndim != 2 or f.shape[0] < 1:
        raise ValueError(f"specific_force must have shape (T, 3); got {f.shape}")
    conflict = _integrate(f, w, time_step, p)
    hill = (conflict / p.b) ** p.n
    hill = hill / (1.0 + hill)
    incidence = TransferFunction((p.p_percent,), tuple(np.polymul([p.tau_i, 1.0], [p.tau_i, 1.0])))
    msi = discretize(incidence, time_step).run(hill[:, None])[0][:, 0]
    return SicknessResult(conflict=conflict, msi_percent=msi)


def _integrate(f: np.ndarray, w: np.ndarray, h: float, p: SicknessParameters) -> np.ndarray:
    """|v_s - v_i| at every sample (T,), integrating the model's state by the classical
    Runge-Kutta method with f and w (T, 3 each) held over each period. The state: the
    verticals v_s, v_i and the conflict's integral x_vc (3 each), and per axis the canals'
    two high-passes (c_a: tau_a s / (tau_a s + 1), then c_d: tau_d s / (tau_d s + 1)) and the
    internal rotation's (c_i: its time constant (1 + K_wc) tau_d). Plain floats: small
    vectors in numpy cost more in call overhead than in arithmetic."""
    inv_tau, k_ac, k_vc = 1.0 / p.tau, p.k_ac, p.k_vc
    gain = 1.0 / (1.0 + k_ac)
    inv_a, inv_d = 1.0 / p.tau_a, 1.0 / p.tau_d
    inv_i = 1.0 / ((1.0 + p.k_wc) * p.tau_d)
    k_rot = p.k_wc / (1.0 + p.k_wc)

    def derivative(s, fx, fy, fz, wx, wy, wz):
        sx, sy, sz, ix, iy, iz, cx, cy, cz = s[:9]
        # canals: w -> (high-pass tau_a) -> (high-pass tau_d) = w_s; internal: k_rot times
        # w_s high-passed with tau_i
        hx, hy, hz = wx - s[9] * inv_a, wy - s[10] * inv_a, wz - s[11] * inv_a
        ax, ay, az = hx - s[12] * inv_d, hy - s[13] * inv_d, hz - s[14] * inv_d
        jx, jy, jz = ax - s[15] * inv_i, ay - s[16] * inv_i, az - s[17] * inv_i
        bx, by, bz = k_rot * jx, k_rot * jy, k_rot * jz
        # internal force estimate, then the two verticals rotating with their rates
        gx = (k_vc * cx + k_ac * (fx - sx + ix)) * gain
        gy = (k_vc * cy + k_ac * (fy - sy + iy)) * gain
        gz = (k_vc * cz + k_ac * (fz - sz + iz)) * gain
        return (
            (fx - sx) * inv_tau - (ay * sz - az * sy),
            (fy - sy) * inv_tau - (az * sx - ax * sz),
            (fz - sz) * inv_tau - (ax * sy - ay * sx),
            (gx - ix) * inv_tau - (by * iz - bz * iy),
            (gy - iy) * inv_tau - (bz * ix - bx * iz),
            (gz - iz) * inv_tau - (bx * iy - by * ix),
            sx - ix,
            sy - iy,
            sz - iz,
            hx,
            hy,
            hz,
            ax,
            ay,
            az,
            jx,
            jy,
            jz,
        )

    # adapted to the first sample: v_s = v_i = f_0, x_vc such that f_i = v_i, and the
    # canals at rest (a constant rotation would be felt from the start)
    f0 = [float(v) for v in f[0]]
    state = (*f0, *f0, *(v / k_vc for v in f0), *([0.0] * 9))
    conflict = np.empty(f.shape[0])
    rows = np.concatenate([f, w], axis=1).tolist()
    half = 0.5 * h
    for n, inputs in enumerate(rows):
        s = state
        conflict[n] = ((s[0] - s[3]) ** 2 + (s[1] - s[4]) ** 2 + (s[2] - s[5]) ** 2) ** 0.5
        k1 = derivative(s, *inputs)
        k2 = derivative([a + half * b for a, b in zip(s, k1, strict=True)], *inputs)
        k3 = derivative([a + half * b for a, b in zip(s, k2, strict=True)], *inputs)
        k4 = derivative([a + h * b for a, b in zip(s, k3, strict=True)], *inputs)
        state = tuple(
            a + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4, strict=True)
        )
    return conflict
