"""The operator page in a real browser: headless Chromium opens Meshcat while a live run
goes on, drags the intensity slider and clicks the emergency stop with the mouse."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
from headless_browser import HeadlessChromium, find_chromium
from test_live_loop import live_with_sender, stream_process

from mca_drake.conventions import CONTROL_PERIOD_S as H
from mca_drake.live.control_inputs import slider_name
from mca_drake.live.controls import ControlsConfig

pytestmark = pytest.mark.skipif(
    find_chromium() is None, reason="needs Chromium (apt install chromium) for the browser test"
)


def rectangle(browser: HeadlessChromium, element: str) -> dict:
    """The page rectangle (CSS pixels) of the element a JavaScript expression names."""
    return json.loads(browser.evaluate(f"JSON.stringify(({element}).getBoundingClientRect())"))


def centre(box: dict) -> tuple[float, float]:
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def operate(browser: HeadlessChromium, done: dict) -> None:
    """Waits for the run's controls on the page, opens the panel, drags the intensity
    slider to 0.3, waits 1.5 s and clicks the emergency stop; notes when it did what."""
    try:
        controller = "viewer.gui_controllers"
        browser.wait_for(
            f"typeof viewer !== 'undefined' && {controller}['EMERGENCY STOP'] !== undefined"
        )
        browser.click(
            *centre(rectangle(browser, "viewer.gui.domElement.querySelector('.close-button')"))
        )
        slider = rectangle(
            browser,
            f"{controller}['{slider_name('intensity')}'].domElement.querySelector('.slider')",
        )
        y = slider["y"] + slider["height"] / 2
        right, target = slider["x"] + slider["width"] - 1, slider["x"] + 0.3 * slider["width"]
        browser.click(right, y, drag_to=(target, y))
        done["dragged"] = time.perf_counter()
        time.sleep(1.5)
        stop = f"{controller}['EMERGENCY STOP'].domElement.parentElement.parentElement"
        browser.click(*centre(rectangle(browser, stop)))
        done["stopped"] = time.perf_counter()
    except Exception as error:  # reported by the test, not lost in the thread
        done["error"] = repr(error)


def test_the_operator_page_turns_the_intensity_down_smoothly_and_stops_the_robot(tmp_path):
    from pydrake.geometry import Meshcat, MeshcatParams

    meshcat = Meshcat(MeshcatParams(host="localhost"))
    browser = HeadlessChromium(meshcat.web_url())
    done: dict = {}
    operator = threading.Thread(target=operate, args=(browser, done), daemon=True)
    trajectory = tmp_path / "run.csv"
    ramp_s = 1.0
    try:
        operator.start()
        summary = live_with_sender(
            stream_process,
            7.0,  # outlasts the loop, whose clock starts after the sender's
            "dpc",
            6.0,
            controls=ControlsConfig(ramp_s=ramp_s),
            meshcat=meshcat,
            trajectory=str(trajectory),
        )
        operator.join(timeout=30)
    finally:
        browser.close()
    assert "error" not in done and "stopped" in done, done
    controls = summary["controls"]
    assert controls["sources"] == ["meshcat"]
    intensities = [e for e in controls["log"] if e["command"].startswith("intensity")]
    assert intensities and all(e["source"] == "meshcat" for e in intensities)
    assert float(intensities[-1]["command"].split()[1]) == pytest.approx(0.3, abs=0.05)
    estop = controls["estop"]
    assert estop["source"] == "meshcat" and estop["time_to_rest_s"] is not None
    assert summary["violations"] == {"q": 0, "qd": 0, "qdd": 0}
    rows = np.genfromtxt(trajectory, delimiter=",", names=True, dtype=None, encoding="ascii")
    intensity = rows["intensity"].astype(float)
    # the slider's drag reached the reference as a ramp, and so did the stop's fade
    assert np.max(np.abs(np.diff(intensity))) <= H / ramp_s + 1e-9
    before_stop = rows["t"] < estop["t_s"]
    assert np.min(intensity[before_stop]) == pytest.approx(0.3, abs=0.05)
    # (the command is read after its period's command has gone out: estop from the next)
    assert intensity[-1] == 0.0 and set(rows["mode"][rows["t"] > estop["t_s"]]) == {"estop"}
    qd = np.column_stack([rows[name] for name in rows.dtype.names if name.startswith("qd_")])
    at_rest = rows["t"] >= estop["t_s"] + estop["time_to_rest_s"] + 2 * H
    assert at_rest.sum() > 20 and np.all(np.abs(qd[at_rest]) < 1e-3)
