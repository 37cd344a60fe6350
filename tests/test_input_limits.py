"""Inputs are bounded before they are expanded or allocated, and every refusal is one
short line that names the field or file: YAML alias bombs, empty overrides, numbers beyond
64 bits, messages quoting huge values, control characters."""

from __future__ import annotations

import time

import pytest

from mca_drake.app import cli
from mca_drake.app.cli import MAX_ERROR_CHARS, error_line
from mca_drake.app.scenarios import load_scenario
from mca_drake.input_checks import MAX_YAML_NODES, check_yaml_size, quoted


def _alias_bomb(levels: int = 9) -> str:
    """YAML whose aliases expand to 9^levels strings from a few hundred bytes."""
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [{','.join([f'*a{k - 1}'] * 9)}]")
    return "\n".join(lines) + "\nscenario: !PlantDemoScenario {duration_s: 1}\n"


def test_an_alias_bomb_is_refused_before_it_is_expanded(tmp_path):
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_alias_bomb())
    assert bomb.stat().st_size < 1000
    start = time.perf_counter()
    with pytest.raises(ValueError, match=f"more than {MAX_YAML_NODES} YAML nodes"):
        load_scenario(bomb)
    assert time.perf_counter() - start < 5.0  # expanded, it would take minutes and GBs


def test_a_few_aliases_are_fine():
    check_yaml_size(_alias_bomb(levels=3), "small")  # 9^3 = 729 nodes


def test_an_override_is_checked_as_the_file_is(tmp_path):
    with pytest.raises(ValueError, match=r"override 1 .*YAML nodes"):
        load_scenario("plant_demo", [_alias_bomb()])
    for empty in ("", "   "):
        with pytest.raises(ValueError, match="an override must be a YAML mapping"):
            load_scenario("plant_demo", empty)


def test_a_number_beyond_64_bits_names_its_field():
    with pytest.raises(ValueError, match=r"ClosedLoopScenario\.random_seed must fit in 64 bits"):
        load_scenario("closed_loop_dpc", "{random_seed: 99999999999999999999999}")


def test_quoted_values_and_error_lines_are_short_and_printable():
    assert quoted("x" * 10) == repr("x" * 10)
    assert quoted("x" * 5000).endswith("... (5002 characters)")
    line = error_line(ValueError("bad\x00value\nnext " + "y" * 5000))
    assert "\\x00" in line and "\n" not in line and line.isprintable()
    assert len(line) < MAX_ERROR_CHARS + 40


def test_the_command_prints_a_long_error_cut_to_one_line(capsys):
    huge = "x" * 5000
    assert cli.main(["run", "closed_loop_dpc", "--set", f"{{mca: {{policy: {huge}}}}}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < MAX_ERROR_CHARS + 100
    assert "characters)" in err


@pytest.mark.parametrize(
    ("rate", "match"),
    [(-1.0, r"realtime_rate must be in \[0, 10\]"), (float("nan"), "finite"), (1e9, r"\[0, 10\]")],
)
def test_a_live_pace_that_cannot_run_is_refused(rate, match):
    from mca_drake.app.scenarios import LiveScenario

    with pytest.raises(ValueError, match=match):
        LiveScenario(realtime_rate=rate).validate()
    with pytest.raises(ValueError, match="a robot runs in real time"):
        LiveScenario(realtime_rate=2.0, robot="rsi://127.0.0.1:49152").validate()


def test_the_live_pace_is_applied():
    """At rate 0 the loop does not wait for the wall clock: 2 s of cueing with no sender
    take far less than 2 s, and the summary says at what pace it ran."""
    from mca_drake.app.jobs import run_live_scenario
    from mca_drake.app.scenarios import LiveScenario

    scenario = LiveScenario(
        protocol="csv", port=0, duration_s=2.0, realtime_rate=0.0, mca="washout", output_json=""
    )
    start = time.perf_counter()
    summary = run_live_scenario(scenario)
    assert summary["live"]["realtime_rate"] == 0.0
    assert time.perf_counter() - start < 2.0
