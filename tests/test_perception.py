"""Vestibular models, perceived scores and sickness, against independent oracles: scipy's
continuous-time simulation of the published transfer functions, closed-form responses,
physics (tilt and acceleration are one otolith input), and an independent integration of the
sickness model's equations."""

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
import torch
from pydrake.systems.framework import DiagramBuilder

from mca_drake.conventions import GRAVITY
from mca_drake.learning.perception import TorchVestibularFilter
from mca_drake.perception import (
    VESTIBULAR_MODELS,
    PerceptionConfig,
    discretize,
    perceive,
    perceived_run,
    subjective_vertical_conflict,
    vestibular_filter,
)
from mca_drake.perception.sickness import SicknessParameters
from mca_drake.platforms.kinematics import plant_output
from mca_drake.systems.vestibular import VestibularModel

H = 0.01
MODELS = sorted(VESTIBULAR_MODELS)


def _lsim(tf, u, t):
    """scipy's continuous simulation of `tf` for the input held between samples."""
    return scipy.signal.lsim((tf.numerator, tf.denominator), u, t, interp=False)[1]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("organ", ["canal", "otolith"])
def test_discrete_models_match_scipy_step_and_sine(model, organ):
    tf = getattr(VESTIBULAR_MODELS[model], organ)
    t = np.arange(6000) * H
    for u in (np.ones_like(t), np.sin(2 * np.pi * 0.3 * t) + 0.5 * np.sin(2 * np.pi * 4 * t)):
        ours = discretize(tf, H).run(u[:, None])[0][:, 0]
        np.testing.assert_allclose(ours, _lsim(tf, u, t), atol=1e-9 * max(1, np.abs(ours).max()))


def test_canal_response_to_a_constant_rotation_fades_with_the_long_time_constant():
    # tau_a tau_L s^2 / ((tau_a s + 1)(tau_L s + 1)) to a unit step of w, in closed form:
    # (tau_a exp(-t / tau_L) - tau_L exp(-t / tau_a)) / (tau_a - tau_L), which undershoots
    tau_l, tau_a = 5.73, 80.0
    t = np.arange(4000) * H
    response = perceive(np.tile([1.0, 0, 0, 0, 0, 0], (t.size, 1)), PerceptionConfig(), H)[:, 0]
    closed = (tau_a * np.exp(-t / tau_l) - tau_l * np.exp(-t / tau_a)) / (tau_a - tau_l)
    late = t >= 0.1  # the 5 ms pole of the full model is gone by then
    np.testing.assert_allclose(response[late], closed[late], atol=2e-3)
    # felt at first, about 1/e of it after tau_L (the adaptation adds a slow tail)
    assert response[10] > 0.95
    assert response[round(tau_l / H)] == pytest.approx(np.exp(-1), abs=0.05)
    assert response[-1] < 0  # the adaptation's after-effect: a rotation the other way


@pytest.mark.parametrize("model", MODELS)
def test_otolith_cannot_tell_a_tilt_from_a_sustained_acceleration(model, robot):
    # A static pitched pose: gravity along the head's x axis, the plant's own output ...
    q = np.zeros(6)
    q[4] = np.radians(10.0)
    tilt = plant_output(q[None], np.zeros((1, 6)), np.zeros((1, 6)), robot)[0]
    assert abs(tilt[3]) > 1.0  # about g sin(10 deg)
    # ... and a level head accelerating along x at the same specific force
    acceleration = np.zeros(6)
    acceleration[3] = tilt[3]
    config = PerceptionConfig(model=model)
    t_steps = 6000
    sustained_tilt = perceive(np.tile(np.r_[0, 0, 0, tilt[3], 0, 0], (t_steps, 1)), config, H)
    sustained_push = perceive(np.tile(acceleration, (t_steps, 1)), config, H)
    np.testing.assert_allclose(sustained_tilt, sustained_push, atol=1e-12)
    # steady state: the otolith's DC gain times the force, in both cases
    gain = VESTIBULAR_MODELS[model].otolith.dc_gain()
    assert sustained_push[-1, 3] == pytest.approx(gain * tilt[3], rel=1e-3)


def test_numpy_torch_and_drake_system_agree():
    rng = np.random.default_rng(4)
    signals = rng.normal(size=(300, 6)) * [0.2, 0.2, 0.2, 1.0, 1.0, 1.0]
    for model in MODELS:
        config = PerceptionConfig(model=model)
        expected = perceive(signals, config, H)
        torch_filter = TorchVestibularFilter(config, H)
        got = torch_filter(torch.tensor(signals[None])).numpy()[0]
        np.testing.assert_allclose(got, expected, atol=1e-12)
        # from a given state too: the free response plus the forced one
        x0 = rng.normal(size=torch_filter.num_states)
        with_state = torch_filter(torch.tensor(signals[None]), torch.tensor(x0[None])).numpy()
        numpy_filter = vestibular_filter(config, H)
        np.testing.assert_allclose(with_state[0], numpy_filter.run(signals, x0)[0], atol=1e-12)

        builder = DiagramBuilder()
        system = builder.AddSystem(VestibularModel(config, H))
        builder.ExportInput(system.get_input_port(0), "signals")
        diagram = builder.Build()
        context = diagram.CreateDefaultContext()
        sub = system.GetMyContextFromRoot(context)
        perceived = np.empty_like(signals)
        for n, u in enumerate(signals):
            diagram.get_input_port(0).FixValue(context, u)
            perceived[n] = system.GetOutputPort("perceived").Eval(sub)
            state = system.EvalUniquePeriodicDiscreteUpdate(sub)
            sub.SetDiscreteState(state)
        np.testing.assert_allclose(perceived, expected, atol=1e-12)


def test_torch_filter_of_long_signals_steps_through_the_recursion():
    from mca_drake.learning.perception import MAX_CONVOLUTION_LENGTH

    rng = np.random.default_rng(7)
    T = MAX_CONVOLUTION_LENGTH + 88
    signals = rng.normal(size=(2, T, 6))
    x0 = rng.normal(size=(2, vestibular_filter().num_states))
    got = TorchVestibularFilter()(torch.tensor(signals), torch.tensor(x0)).numpy()
    for row in range(2):
        expected = vestibular_filter().run(signals[row], x0[row])[0]
        np.testing.assert_allclose(got[row], expected, atol=1e-10)


def test_torch_filter_is_differentiable():
    signals = torch.zeros(2, 50, 6, dtype=torch.float64, requires_grad=True)
    TorchVestibularFilter()(signals)[:, -1, 3].sum().backward()
    # the last perceived f_x depends on earlier f_x only (channels are independent)
    assert signals.grad[:, :, 3].abs().sum() > 0
    assert signals.grad[:, :, [0, 1, 2, 4, 5]].abs().sum() == 0


def test_felt_output_applies_the_thresholds():
    config = PerceptionConfig()
    system = VestibularModel(config, H)
    context = system.CreateDefaultContext()  # at rest: the state is zero
    system.get_input_port(0).FixValue(context, np.zeros(6))
    assert np.all(system.GetOutputPort("felt").Eval(context) == 0.0)
    # a state whose perceived output is just above one threshold and below the others
    f = vestibular_filter(config, H)
    target = 0.5 * config.thresholds
    target[3] = 1.5 * config.thresholds[3]
    x = np.linalg.lstsq(f.C, target, rcond=None)[0]
    context.SetDiscreteState(x)
    felt = system.GetOutputPort("felt").Eval(context)
    np.testing.assert_allclose(system.GetOutputPort("perceived").Eval(context), target, atol=1e-12)
    assert felt[3] == pytest.approx(target[3]) and np.count_nonzero(felt) == 1


def test_perceived_scores_of_perfect_and_absent_motion():
    rng = np.random.default_rng(0)
    t = np.arange(2000) * H
    reference = 0.3 * np.sin(np.outer(t, rng.uniform(0.5, 3, 6)))
    perfect = perceived_run(reference, reference, H)
    assert perfect.score.pi == pytest.approx(-6.0)
    assert np.all(perfect.false_cue_share == 0)
    assert perfect.summary()["sickness"]["simulator"] == pytest.approx(
        perfect.summary()["sickness"]["reference"]
    )
    still = perceived_run(reference, np.zeros_like(reference), H)
    assert still.score.pi == pytest.approx(still.zero_motion.pi)
    # no motion is a false cue wherever the perceived reference exceeds the threshold
    expected = (np.abs(perceive(reference)) > PerceptionConfig().thresholds).mean(0)
    np.testing.assert_allclose(still.false_cue_share, expected)
    assert still.sickness.summary()["conflict_max_m_s2"] == pytest.approx(0.0, abs=1e-12)


def _svc_reference(f, w, h, p: SicknessParameters):
    """The sickness model's conflict by scipy's adaptive integrator on one state vector
    (canals and internal rotation included), inputs held over each period."""

    def rhs(_, s, fk, wk):
        v_s, v_i, x_vc = s[0:3], s[3:6], s[6:9]
        c1, c2, i1 = s[9:12], s[12:15], s[15:18]
        # canals tau_d tau_a s^2 / ((tau_d s + 1)(tau_a s + 1)) as two high-passes in series
        w_hp1 = wk - c1 / p.tau_a  # first: tau_a s / (tau_a s + 1)
        w_s = w_hp1 - c2 / p.tau_d
        # internal rotation K tau_d s / ((1 + K) tau_d s + 1) = K / (1 + K) high-passed
        tau_i = (1 + p.k_wc) * p.tau_d
        w_hp2 = w_s - i1 / tau_i
        w_i = p.k_wc / (1 + p.k_wc) * w_hp2
        f_i = (p.k_vc * x_vc + p.k_ac * (fk - v_s + v_i)) / (1 + p.k_ac)
        return np.concatenate(
            [
                (fk - v_s) / p.tau - np.cross(w_s, v_s),
                (f_i - v_i) / p.tau - np.cross(w_i, v_i),
                v_s - v_i,
                w_hp1,
                w_s,
                w_hp2,
            ]
        )

    s = np.concatenate([f[0], f[0], f[0] / p.k_vc, np.zeros(9)])
    conflict = []
    for fk, wk in zip(f, w, strict=True):
        conflict.append(np.linalg.norm(s[0:3] - s[3:6]))
        s = scipy.integrate.solve_ivp(
            rhs, (0, h), s, args=(fk, wk), rtol=1e-10, atol=1e-12, method="DOP853"
        ).y[:, -1]
    return np.array(conflict)


def test_sickness_conflict_matches_an_independent_integration():
    t = np.arange(800) * H
    w = np.column_stack([0.3 * np.sin(1.3 * t), 0.2 * np.cos(0.7 * t), 0.4 * np.sin(0.5 * t)])
    f = np.column_stack([2 * np.sin(0.9 * t), np.cos(1.1 * t), GRAVITY + np.sin(2.0 * t)])
    p = SicknessParameters()
    ours = subjective_vertical_conflict(f, w, H, p).conflict
    np.testing.assert_allclose(ours, _svc_reference(f, w, H, p), atol=1e-6)


def test_sickness_physics():
    t = np.arange(60000) * H  # 10 min
    rest = np.tile([0.0, 0.0, GRAVITY], (t.size, 1))
    # at rest, and turning about the vertical, the verticals agree: no conflict
    still = subjective_vertical_conflict(rest, np.zeros_like(rest), H)
    assert np.max(still.conflict) < 1e-12 and np.max(still.msi_percent) < 1e-12
    yaw = np.tile([0.0, 0.0, 0.5], (t.size, 1))
    assert np.max(subjective_vertical_conflict(rest, yaw, H).conflict) < 1e-9

    # vertical oscillation of 1 m/s^2: the incidence peaks near 0.2 Hz (Bos & Bles), and
    # grows toward P h with the second-order lag of tau_I
    def heave(frequency):
        f = rest.copy()
        f[:, 2] += np.sin(2 * np.pi * frequency * t)
        return subjective_vertical_conflict(f, np.zeros_like(f), H).msi_percent[-1]

    low, mid, high = heave(0.02), heave(0.2), heave(2.0)
    assert mid > 2 * low and mid > 2 * high
    # a sustained tilt: conflict rises, then fades as both verticals settle on it
    tilt = np.tile([GRAVITY * np.sin(0.2), 0.0, GRAVITY * np.cos(0.2)], (t.size, 1))
    tilt[:100] = rest[:100]
    result = subjective_vertical_conflict(tilt, np.zeros_like(tilt), H)
    assert result.conflict.max() > 0.1 and result.conflict[-1] < 1e-3 * result.conflict.max()


def test_msi_follows_the_second_order_lag_of_a_constant_conflict():
    # the incidence is P h through 1 / (tau_I s + 1)^2: scipy's simulation of that filter
    # on the model's own Hill function of the conflict
    t = np.arange(20000) * H
    f = np.tile([0.0, 0.0, GRAVITY], (t.size, 1))
    f[:, 0] = 3.0 * np.sin(2 * np.pi * 0.2 * t)
    p = SicknessParameters()
    result = subjective_vertical_conflict(f, np.zeros_like(f), H, p)
    hill = (result.conflict / p.b) ** p.n
    hill = hill / (1 + hill)
    tf = ([p.p_percent], np.polymul([p.tau_i, 1], [p.tau_i, 1]))
    expected = scipy.signal.lsim(tf, hill, t, interp=False)[1]
    np.testing.assert_allclose(result.msi_percent, expected, atol=1e-9)


def test_bad_input_is_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="unknown vestibular model"):
        PerceptionConfig(model="young").validate()
    with pytest.raises(ValueError, match="rotation_thresholds"):
        PerceptionConfig(rotation_thresholds=[0.1, 0.1]).validate()
    with pytest.raises(ValueError, match="signals"):
        perceive(np.zeros((10, 5)))
    with pytest.raises(ValueError, match="non-finite"):
        perceive(np.full((10, 6), np.nan))
    with pytest.raises(ValueError, match="shapes must match"):
        perceived_run(np.zeros((10, 6)), np.zeros((11, 6)), H)
    with pytest.raises(ValueError, match="time_step"):
        vestibular_filter(time_step=0.0)
