"""MCA profiles: the ground profile's settings load by name everywhere an MCA name goes,
and name the MCA in summaries."""

from __future__ import annotations

import pytest
import yaml

from mca_drake.app.scenarios import load_scenario
from mca_drake.cueing import (
    MCA_NAMES,
    DpcConfig,
    NmpcConfig,
    WashoutConfig,
    mca_config_from_name,
    mca_name,
)
from mca_drake.cueing.dpc import shipped_policy_path
from mca_drake.cueing.profiles import load_profile, profile_path, split_profile
from mca_drake.resources import PROFILES


def _file_values(section: str) -> dict:
    """The profile file's settings of one MCA, read with PyYAML (not the loader under
    test)."""
    return yaml.safe_load(profile_path("ground").read_text())[section]


@pytest.mark.parametrize("name", MCA_NAMES)
def test_every_mca_name_takes_the_ground_profile(name):
    config = mca_config_from_name(f"{name}-ground")
    assert config.profile == "ground"
    assert mca_name(config) == f"{name}-ground"
    assert type(config) is type(mca_config_from_name(name))
    config.validate()


def test_the_ground_profiles_settings_are_the_files():
    washout = mca_config_from_name("washout-ground")
    for field, value in _file_values("washout").items():
        assert getattr(washout, field) == pytest.approx(value), field
    nmpc_values = _file_values("nmpc")
    assert nmpc_values, "the profile tunes the NMPC's weights"
    for name in ("nmpc-rti", "nmpc-converged-perceived"):
        nmpc = mca_config_from_name(f"{name}-ground")
        for field, value in nmpc_values.items():
            assert getattr(nmpc, field) == pytest.approx(value), (name, field)
    converged = mca_config_from_name("nmpc-converged-perceived-ground")
    assert (converged.mode, converged.objective) == ("converged", "perceived")
    # the profile differs from the flight defaults where it was tuned
    assert any(getattr(washout, f) != getattr(WashoutConfig(), f) for f in _file_values("washout"))


def test_the_ground_dpc_runs_the_ground_policy():
    config = mca_config_from_name("dpc-ground")
    assert config == DpcConfig(profile="ground")
    assert config.policy_path("kr500") == shipped_policy_path("ground_policy")
    assert DpcConfig().policy_path("kr500") != config.policy_path("kr500")
    # a policy file given outright wins over the profile's
    other = shipped_policy_path("policy_v6")
    assert DpcConfig(policy=str(other), profile="ground").policy_path("kr500") == other


def test_names_and_profiles_that_do_not_exist_are_refused():
    with pytest.raises(ValueError, match="unknown MCA 'wash-ground'"):
        mca_config_from_name("wash-ground")
    with pytest.raises(ValueError, match="unknown MCA 'washout-moon'"):
        mca_config_from_name("washout-moon")
    for config in (
        NmpcConfig(profile="moon"),
        WashoutConfig(profile="moon"),
        DpcConfig(profile="moon"),
    ):
        with pytest.raises(ValueError, match="unknown MCA profile 'moon'"):
            config.validate()
    assert split_profile("nmpc-rti-perceived-ground") == ("nmpc-rti-perceived", "ground")
    assert split_profile("nmpc-rti-perceived") == ("nmpc-rti-perceived", "")
    assert PROFILES == ("ground",)


def test_a_scenario_selects_a_profile_by_name(tmp_path):
    path = tmp_path / "drive.yaml"
    path.write_text(
        "scenario: !ClosedLoopScenario\n"
        "  mca: washout-ground\n"
        "  plant: analytical\n"
        "  flight: !DriveSpec {manoeuvre: braking, seed: 5}\n"
        "  duration_s: 2.0\n"
    )
    scenario = load_scenario(path)
    assert scenario.mca == load_profile("ground").washout
    assert mca_name(scenario.mca) == "washout-ground"
    path.write_text(path.read_text().replace("washout-ground", "washout-moon"))
    with pytest.raises(ValueError, match="mca: unknown MCA 'washout-moon'"):
        load_scenario(path)


@pytest.mark.parametrize(
    "text, match",
    [
        ("nmpc: {input_weigth: 0.1}", "'input_weigth' is not a NmpcConfig field"),
        ("nmpc: {input_weight: fast}", "nmpc.input_weight"),
        ("washout: {tilt_limit: true}", "washout.tilt_limit"),
        ("nmpc: {output_weights: 3.0}", "nmpc.output_weights"),
        ("nmpc: {output_weights: [1, 2, 3]}", "six non-negative"),
        ("aircraft: {}", "sections nmpc and washout"),
        ("nmpc: [1, 2]", "mapping of NmpcConfig fields"),
    ],
)
def test_a_profile_file_with_bad_settings_is_refused(tmp_path, monkeypatch, text, match):
    from mca_drake.cueing import profiles  # the module whose file lookup is redirected

    path = tmp_path / "ground.yaml"
    path.write_text(text)
    monkeypatch.setattr(profiles, "profile_path", lambda profile: path)
    with pytest.raises(ValueError, match=match):
        load_profile("ground")


def test_a_profile_file_may_give_integers_for_real_numbers(tmp_path, monkeypatch):
    from mca_drake.cueing import profiles  # the module whose file lookup is redirected

    path = tmp_path / "ground.yaml"
    path.write_text("nmpc: {output_weights: [1, 2, 3, 4, 5, 6], input_weight: 1}\n")
    monkeypatch.setattr(profiles, "profile_path", lambda profile: path)
    settings = load_profile("ground")
    assert settings.nmpc.output_weights == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    assert settings.nmpc.input_weight == 1.0 and isinstance(settings.nmpc.input_weight, float)
    assert settings.washout == WashoutConfig(profile="ground")
