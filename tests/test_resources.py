"""The files the package carries: found from the checkout here, inside the wheel when
installed; scenarios named by file or by their packaged name."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from mca_drake.cueing.dpc import shipped_policy_path
from mca_drake.cueing.predictor import PACKAGED_LEARNED_PREDICTOR, PACKAGED_LINEAR_PREDICTOR
from mca_drake.platforms.files import model_path, packaged_platforms
from mca_drake.resources import (
    PROFILES,
    SHIPPED_POLICIES,
    packaged_folder,
    packaged_scenarios,
    scenario_path,
)

REPO = Path(__file__).resolve().parent.parent


def test_the_checkout_folders_are_the_sources():
    assert packaged_folder("models") == REPO / "models"
    assert model_path("kr500.urdf") == REPO / "models" / "kr500.urdf"
    assert set(packaged_scenarios()) == {p.stem for p in (REPO / "diagrams").glob("*.yaml")}


def test_a_scenario_is_found_by_file_or_by_packaged_name(tmp_path, monkeypatch):
    own = tmp_path / "mine.yaml"
    own.write_text("scenario: !PlantDemoScenario {}\n")
    assert scenario_path(own) == own
    monkeypatch.chdir(tmp_path)  # away from the checkout
    expected = REPO / "diagrams" / "live_rsi.yaml"
    for name in ("live_rsi", "live_rsi.yaml", "diagrams/live_rsi.yaml"):
        assert scenario_path(name) == expected, name


def test_an_unknown_scenario_lists_the_packaged_ones(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"packaged scenarios: .*closed_loop_dpc"):
        scenario_path(tmp_path / "nope.yaml")
    with pytest.raises(FileNotFoundError, match="is a directory"):
        scenario_path(tmp_path)


def test_bad_names_are_refused():
    with pytest.raises(ValueError, match="valid: models, diagrams"):
        packaged_folder("notebooks")
    with pytest.raises(ValueError, match="valid: default_policy, policy_v6, ground_policy"):
        shipped_policy_path("policy_v9")
    assert [shipped_policy_path(n).name for n in SHIPPED_POLICIES] == [
        "default_policy.npz",
        "policy_v6.npz",
        "ground_policy.npz",
        "light_policy.npz",
        "transport_policy.npz",
        "predictive_policy.npz",
        "ground_predictive_policy.npz",
        "light_predictive_policy.npz",
        "transport_predictive_policy.npz",
        *(
            f"{platform}_{name}.npz"
            for platform in ("kr500-rail", "fanuc-m900ib700")
            for name in ("default_policy", "light_policy", "transport_policy", "ground_policy")
        ),
        "hexapod_default_policy.npz",
        "hexapod_ground_policy.npz",
        "rig-2dof_default_policy.npz",
        "rig-3dof_default_policy.npz",
    ]


def test_the_wheel_carries_the_models_the_scenarios_the_policies_and_profiles(tmp_path):
    """The wheel, built from this checkout, holds copies of models/ (the platforms' URDFs and
    platform files) and diagrams/ where
    `resources` looks in an installed package, the shipped policies, the packaged linear
    and learned predictors, the profiles' and the packaged platforms' settings, and no other
    data."""
    source = tmp_path / "source"  # a copy: the build writes build/ into its source
    source.mkdir()
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy2(REPO / name, source / name)
    for name in ("mca_drake", "models", "diagrams"):
        shutil.copytree(REPO / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
    command = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q"]
    subprocess.run([*command, str(source), "-w", str(tmp_path)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("mca_drake-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    data = {n for n in names if n.startswith("mca_drake/data/")}
    expected = {
        f"mca_drake/data/models/{p.name}"
        for p in (REPO / "models").iterdir()
        if p.suffix in (".urdf", ".yaml")
    }
    assert {"kr500.urdf", "kr500.yaml", "kr500_rail.urdf", "kr500-rail.yaml"} <= {
        n.rsplit("/", 1)[1] for n in expected
    }
    expected |= {f"mca_drake/data/diagrams/{p.name}" for p in (REPO / "diagrams").glob("*.yaml")}
    expected |= {f"mca_drake/data/{n}.npz" for n in SHIPPED_POLICIES}
    # the predictive MCAs' packaged forecasts (`cueing.predictor`)
    expected |= {
        f"mca_drake/data/{name}" for name in (PACKAGED_LINEAR_PREDICTOR, PACKAGED_LEARNED_PREDICTOR)
    }
    expected |= {f"mca_drake/data/profiles/{n}.yaml" for n in PROFILES}
    # the packaged platforms' tuned settings (`cueing.profiles.load_platform_settings`)
    settings = {"hexapod", "rig-2dof", "rig-3dof"}
    assert settings <= set(packaged_platforms())
    expected |= {f"mca_drake/data/platforms/{n}.yaml" for n in settings}
    # the shipped policies' training ranges (`cueing.reference_range`)
    expected.add("mca_drake/data/policy_reference_ranges.json")
    assert data == expected
    assert "mca_drake/live/rsi/driver.py" in names and "mca_drake/app/cli/__main__.py" in names
