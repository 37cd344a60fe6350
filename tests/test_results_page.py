"""The results page and the README's headline table are generated from the result files
under benchmarks/results: every plot the page links exists, every headline figure equals the
one its result file holds (read here independently), and the README's table is a render."""

from __future__ import annotations

import json
import re
import statistics
import sys
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
START, END = "<!-- headline-table:start -->", "<!-- headline-table:end -->"
# The headline table's row labels and the evaluation suite's MCA names.
ROWS = {
    "DPC": "dpc",
    "NMPC, converged": "nmpc-converged",
    "NMPC, RTI": "nmpc-rti",
    "Washout (tuned)": "washout",
    "NMPC, RTI, perceived objective": "nmpc-rti-perceived",
    "DPC, ground profile": "dpc-ground",
    "NMPC, converged, ground profile": "nmpc-converged-ground",
    "NMPC, RTI, ground profile": "nmpc-rti-ground",
    "NMPC, RTI, perceived objective, ground profile": "nmpc-rti-perceived-ground",
    "Washout (tuned), ground profile": "washout-ground",
}


results_page = load_benchmark("results_page")


def _json(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


def _table_rows(markdown: str) -> dict[str, list[str]]:
    """{first cell: the other cells} of the Markdown table rows (header and rule left out)."""
    rows = {}
    for line in markdown.splitlines():
        if not line.startswith("| ") or line.startswith("|---"):
            continue
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return rows


def test_every_plot_the_page_links_exists():
    page = results_page.render_results_page(RESULTS)
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page)
    assert "evaluation/evaluation.png" in links
    for link in links:
        assert not Path(link).is_absolute()
        assert (RESULTS / link).is_file(), link


def test_page_states_date_and_command_of_every_result_file():
    page = results_page.render_results_page(RESULTS)
    for section in results_page.SECTIONS:
        provenance = _json(section.file)["provenance"]
        assert f"Measured {provenance['date']}" in page
        assert f"`{provenance['command']}`" in page


def test_headline_pis_equal_the_evaluation_suites_medians():
    """Each MCA's row holds its median PI in every case that ran it and "-" in the others;
    an MCA no case ran has no row, and a case that ran nothing has no column."""
    suite = _json("evaluation/evaluation.json")
    rows = _table_rows(results_page.render_headline_table(RESULTS))
    cases = [case for case in suite["cases"].values() if case["mcas"]]
    for label, mca in ROWS.items():
        if not any(mca in case["mcas"] for case in cases):
            assert label not in rows
            continue
        expected = []
        for case in cases:
            m = case["mcas"].get(mca)
            if m is None:
                expected.append("-")
                continue
            cell = f"{statistics.median(m['pi']):.3f}"
            if "perceived_pi" in m:  # the perceived PI's median in brackets
                cell += f" ({statistics.median(m['perceived_pi']):.3f})"
            expected.append(cell)
        assert rows[label][: len(cases)] == expected, label
    for k, case in enumerate(cases):
        zero = {m["pi_zero_motion_median"] for m in case["mcas"].values()}
        assert len(zero) == 1  # every MCA flew the same flights
        cell = f"{zero.pop():.3f}"
        felt = {m.get("perceived_pi_zero_motion_median") for m in case["mcas"].values()}
        assert len(felt) == 1
        if None not in felt:
            cell += f" ({felt.pop():.3f})"
        assert rows["Zero motion"][k] == cell


def test_headline_step_times_equal_the_benchmarks():
    dpc, nmpc = _json("dpc.json"), _json("nmpc.json")
    rows = _table_rows(results_page.render_headline_table(RESULTS))
    runs = [run["step_time_s"]["median"] for run in dpc["dpc"]["runs"]]
    assert rows["DPC"][-1] == f"{statistics.median(runs) * 1e6:.1f} us"
    converged = nmpc["flight"]["shipped/converged"]["median_ms"]
    assert rows["NMPC, converged"][-1] == f"{converged:.2f} ms"
    assert rows["NMPC, RTI"][-1] == f"{nmpc['flight']['shipped/rti']['median_ms']:.2f} ms"


def test_training_recipe_section_sums_the_steps_trainer_times():
    """The page's whole-recipe time is the sum of the steps' trainer wall times the result
    file holds (each read from a policy file), in minutes."""
    recipe = _json("training_recipe.json")
    total = sum(step["training_wall_s"] for step in recipe["steps"].values())
    page = results_page.render_results_page(RESULTS)
    section = page.split("## Training recipe", 1)[1].split("\n## ", 1)[0]
    assert f"Whole recipe: {total / 60:.1f} min" in section
    stage_rows = sum(len(step["stages"]) for step in recipe["steps"].values())
    assert section.count(" s |") == stage_rows


def test_headline_table_names_its_dates_and_command():
    table = results_page.render_headline_table(RESULTS)
    for name in ("evaluation/evaluation.json", "dpc.json", "nmpc.json"):
        assert _json(name)["provenance"]["date"] in table
    assert "python benchmarks/results_page.py --readme README.md" in table


def test_readme_headline_block_is_the_rendered_table():
    readme = (REPO / "README.md").read_text()
    if START not in readme:
        pytest.skip("README.md has no headline-table markers")
    lines = readme.splitlines(keepends=True)
    start = next(i for i, line in enumerate(lines) if line.strip() == START)
    end = next(i for i, line in enumerate(lines) if line.strip() == END)
    block = "".join(lines[start + 1 : end])
    assert block == results_page.render_headline_table(RESULTS), (
        "README.md's headline table differs from the result files: run "
        "python benchmarks/results_page.py --readme README.md"
    )


def test_readme_option_rewrites_only_the_marked_block(tmp_path, monkeypatch):
    readme = tmp_path / "README.md"
    readme.write_text(f"# Title\n\nbefore\n{START}\nstale table\n{END}\nafter\n")
    monkeypatch.setattr(sys, "argv", ["results_page.py", "--readme", str(readme)])
    results_page.main()
    table = results_page.render_headline_table(RESULTS)
    assert readme.read_text() == f"# Title\n\nbefore\n{START}\n{table}{END}\nafter\n"
    results_page.main()  # a second render leaves the file as it is
    assert readme.read_text() == f"# Title\n\nbefore\n{START}\n{table}{END}\nafter\n"


def test_readme_option_refuses_a_file_without_markers(tmp_path, monkeypatch):
    readme = tmp_path / "README.md"
    readme.write_text("# Title\n")
    monkeypatch.setattr(sys, "argv", ["results_page.py", "--readme", str(readme)])
    with pytest.raises(SystemExit, match="headline-table"):
        results_page.main()
    assert readme.read_text() == "# Title\n"


def test_page_option_writes_the_page(tmp_path, monkeypatch):
    page = tmp_path / "results.md"
    monkeypatch.setattr(sys, "argv", ["results_page.py", "--page", str(page)])
    results_page.main()
    assert page.read_text() == results_page.render_results_page(RESULTS)
