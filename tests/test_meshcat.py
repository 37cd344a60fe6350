"""Meshcat: the closed loop is served and a real browser renders the robot.

The honest test is a headless Chromium screenshot of the page: it must not be blank and
must show the robot's orange links (URDF material "robot", rgb 0.96 0.49 0.0)."""

import os
import shutil
import subprocess
import tempfile
import urllib.request

import numpy as np
import pytest
from pydrake.geometry import StartMeshcat
from pydrake.systems.analysis import Simulator

from mca_drake.platforms.files import load_platform
from mca_drake.references.jsbsim import fly
from mca_drake.references.reference import reference_from_recording
from mca_drake.simulation.builders import MakeMultibodyClosedLoop

KR500 = load_platform("kr500")


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("MCA_DRAKE_REQUIRE_CHROMIUM"):
        pytest.fail("Chromium is required here (scripts/install_browser.sh) but missing")
    pytest.skip("no Chromium: run scripts/install_browser.sh (apt-get install chromium)")


@pytest.fixture(scope="module")
def served_closed_loop():
    meshcat = StartMeshcat()
    reference = reference_from_recording(fly("light", 5.0, 1000), name="light 1000")
    diagram, handles = MakeMultibodyClosedLoop(reference, "dpc", meshcat=meshcat, robot=KR500)
    simulator = Simulator(diagram)
    handles["station"].SetInitialState(simulator.get_mutable_context())
    simulator.AdvanceTo(2.0)
    yield meshcat, handles
    meshcat.Delete()


def test_meshcat_page_is_served(served_closed_loop):
    meshcat, _ = served_closed_loop
    with urllib.request.urlopen(meshcat.web_url(), timeout=10) as response:
        assert response.status == 200
        assert b"meshcat" in response.read().lower()
    # the traces system drew its strip charts
    assert meshcat.HasPath("traces/measured_0") and meshcat.HasPath("traces/target_5")


def test_headless_chromium_renders_the_robot(served_closed_loop, tmp_path):
    from PIL import Image

    browser = _chromium()
    meshcat, _ = served_closed_loop
    shot = tmp_path / "meshcat.png"
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tempfile.mkdtemp()}",
        "--window-size=1200,800",
        "--virtual-time-budget=8000",
        f"--screenshot={shot}",
    ]
    subprocess.run([browser, *flags, meshcat.web_url()], capture_output=True, timeout=180)
    assert shot.is_file(), "Chromium wrote no screenshot"
    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    assert pixels.std() > 10.0, "the screenshot is blank"
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    orange = (r > 170) & (g > 60) & (g < 170) & (b < 70)
    assert orange.mean() > 5e-4, "no robot-orange pixels: the robot was not rendered"
