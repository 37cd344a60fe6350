"""The one closed-loop runner: its summary (zero-motion PI, the config that ran), the seed of
the IMU noise, and MCA systems that keep no run-time state on `self`."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mca_drake.conventions import GRAVITY
from mca_drake.cueing import NmpcConfig, WashoutConfig
from mca_drake.perception import perceive, subjective_vertical_conflict
from mca_drake.platforms.files import load_platform
from mca_drake.platforms.kinematics import head_pose
from mca_drake.references.recording import Recording
from mca_drake.references.reference import Reference, reference_from_recording
from mca_drake.simulation.builders import MakeAnalyticalClosedLoop
from mca_drake.simulation.closed_loop import run_closed_loop
from mca_drake.systems.station import StationConfig

KR500 = load_platform("kr500")


@pytest.fixture(scope="module")
def reference() -> Reference:
    """A 3 s synthetic recording with motion on every channel: a surge pulse, a heave
    and a sway sine, and angular-rate sines (no JSBSim needed)."""
    t = np.arange(0.0, 3.0 + 1e-9, 0.01)
    omega = 0.1 * np.sin(2 * np.pi * np.outer(t, [0.3, 0.4, 0.5]))
    f = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    f[(t > 0.5) & (t < 1.5), 0] = 2.0
    f[:, 1] = 0.5 * np.sin(2 * np.pi * 0.6 * t)
    f[:, 2] += 0.5 * np.sin(2 * np.pi * 0.7 * t)
    return reference_from_recording(Recording(t, omega, f), name="pulse")


def test_summary_records_zero_motion_pi_and_the_config(reference, robot):
    config = NmpcConfig(mode="rti", washout_weight=0.3)
    result = run_closed_loop(
        mca=config, reference=reference, duration_s=2.0, progress=False, robot=KR500
    )
    s = result.summary
    # Oracle: not moving renders y = 0, so each channel's RMSE is the reference's RMS and
    # its CC is 0 (a constant signal co-varies with nothing).
    r = result.reference
    assert np.all(np.ptp(r, axis=0) > 0)
    rms = np.sqrt(np.mean(r**2, axis=0))
    assert s["pi_zero_motion"] == pytest.approx(rms.sum(), abs=1e-12)
    assert s["pi"] < s["pi_zero_motion"]  # NMPC beats standing still
    assert s["mca"] == "nmpc-rti"
    assert s["mca_config"]["type"] == "NmpcConfig"
    assert s["mca_config"]["washout_weight"] == 0.3
    assert s["mca_config"]["output_weights"] == NmpcConfig().output_weights
    # the perceived block: the same figures on the vestibular model's outputs of the run's
    # signals, the simulator's vertical specific force with gravity along the tilted head
    perceived = s["perceived"]
    target, achieved = perceive(r), perceive(result.outputs)
    np.testing.assert_allclose(perceived["rmse"], np.sqrt(np.mean((achieved - target) ** 2, 0)))
    zero = np.sqrt(np.mean(target**2, 0)).sum()
    assert perceived["pi_zero_motion"] == pytest.approx(zero, abs=1e-12)
    assert perceived["pi"] < perceived["pi_zero_motion"]
    tilt = head_pose(result.states[:, :6], robot)[:, 2, 2]
    sickness = subjective_vertical_conflict(
        np.column_stack([result.outputs[:, 3:5], result.outputs[:, 5] + GRAVITY * tilt]),
        result.outputs[:, :3],
        0.01,
    )
    assert perceived["sickness"]["simulator"] == pytest.approx(sickness.summary())


def test_random_seed_reaches_the_imu_noise(reference):
    station = StationConfig(accelerometer_noise_std=0.05, gyroscope_noise_std=0.01)

    def outputs(seed):
        return run_closed_loop(
            mca="washout",
            reference=reference,
            plant="multibody",
            duration_s=0.3,
            station=station,
            random_seed=seed,
            progress=False,
            robot=KR500,
        )

    a, b, c = outputs(1), outputs(1), outputs(2)
    np.testing.assert_array_equal(a.outputs, b.outputs)
    assert not np.allclose(a.outputs, c.outputs)
    assert a.summary["random_seed"] == 1


def test_bad_plant_and_plant_settings_fail_clearly(reference):
    with pytest.raises(ValueError, match="unknown plant 'mujoco'"):
        run_closed_loop(mca="dpc", reference=reference, plant="mujoco", progress=False, robot=KR500)
    with pytest.raises(ValueError, match="need plant 'multibody'"):
        run_closed_loop(
            mca="dpc", reference=reference, station=StationConfig(), progress=False, robot=KR500
        )
    with pytest.raises(ValueError, match="differs from the control period"):
        run_closed_loop(
            mca=NmpcConfig(time_step=0.02), reference=reference, progress=False, robot=KR500
        )


def test_washout_keeps_its_scratch_per_context(reference):
    """ClassicalWashout's plant context and IK parameters live in each context: running one
    context leaves another's untouched, and a cloned context carries on exactly like the
    original."""
    diagram, handles = MakeAnalyticalClosedLoop(reference, WashoutConfig(), robot=KR500)
    washout = handles["mca"]
    plant = washout._plant
    first, second = Simulator(diagram), Simulator(diagram)
    second.AdvanceTo(0.05)
    theirs = washout._scratch_entry.Eval(washout.GetMyContextFromRoot(second.get_context()))
    their_positions = plant.GetPositions(theirs.plant_context).copy()
    first.AdvanceTo(1.0)
    mine = washout._scratch_entry.Eval(washout.GetMyContextFromRoot(first.get_context()))
    assert mine is not theirs
    assert not np.array_equal(plant.GetPositions(mine.plant_context), their_positions)
    np.testing.assert_array_equal(plant.GetPositions(theirs.plant_context), their_positions)

    root = first.get_context()
    clone = Simulator(diagram, root.Clone())
    first.AdvanceTo(2.0)
    clone.AdvanceTo(2.0)
    # The commands and states (not the statistics: they hold wall-clock step times) of
    # the last second; the clone's log also holds the sample its own initialisation
    # published at 1 s.
    for log in ("command_log", "state_log"):
        mine = handles[log].FindLog(root).data()[:, -100:]
        theirs = handles[log].FindLog(clone.get_context()).data()[:, -100:]
        np.testing.assert_array_equal(mine, theirs)
    assert np.abs(handles["command_log"].FindLog(root).data()[:, -100:]).max() > 1e-3
