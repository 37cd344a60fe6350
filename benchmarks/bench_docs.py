"""The documentation site: its build time, the images on each page, and how long the tests
that run the docs' examples take.

    python benchmarks/bench_docs.py [--builds 3] [--no-commands] [--json PATH]

Builds the site `--builds` times (strict, into a temporary folder; the first also counts
every page's images), runs tests/test_docs.py once (the Python examples, the shown runs and
the coverage checks, as CI's default job runs them), then tests/test_docs_commands.py (every
shell example's `mca-drake` lines, shrunk; a `slow` test) with each page's seconds. Figures
are wall times on this machine, with its calibration.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import default_result_path, print_calibration, result_header

from mca_drake.atomic_io import atomic_write_json

REPO = Path(__file__).resolve().parents[1]
# Built pages that are not the docs' own: MkDocs' search and 404 pages, the API reference
# (generated docstrings) and the decision records (short texts by design).
NOT_COUNTED = ("search/", "404.html", "reference/api/", "decisions/")


def build(out: Path) -> float:
    """Seconds of one strict build of the site into `out`."""
    start = time.perf_counter()
    subprocess.run(
        ["bash", str(REPO / "scripts/build_docs.sh"), "-d", str(out)],
        cwd=REPO,
        check=True,
        capture_output=True,
    )
    return time.perf_counter() - start


def images_per_page(site: Path) -> dict[str, int]:
    """{page: number of <img> in its article} of a built site, pages of NOT_COUNTED aside."""
    counts = {}
    for page in sorted(site.rglob("index.html")):
        name = page.relative_to(site).parent.as_posix()
        name = "index" if name == "." else name
        if (name + "/").startswith(NOT_COUNTED) or name.startswith(NOT_COUNTED):
            continue
        html = page.read_text()
        article = html[html.find("<article") : html.find("</article>")]
        counts[name] = len(re.findall(r"<img\b", article))
    return counts


def run_tests(arguments: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    """Wall seconds and the process of one pytest run in the repository."""
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *arguments],
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    return time.perf_counter() - start, done


def last_line(done: subprocess.CompletedProcess) -> str:
    """pytest's summary line."""
    return done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""


def page_seconds(durations: str) -> dict[str, float]:
    """{page: seconds} from pytest's `--durations=0` table of the shell examples' test."""
    test = "test_a_pages_command_lines_run_shrunk"
    found = re.findall(rf"([0-9.]+)s call\s+\S+{test}\[(.+?)\]", durations)
    return {page: float(seconds) for seconds, page in found}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--builds", type=int, default=3)
    parser.add_argument("--json", default=default_result_path("docs.json"))
    parser.add_argument(
        "--no-commands", action="store_true", help="skip the shell examples (minutes)"
    )
    args = parser.parse_args()
    calibration = print_calibration()
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.builds):
            times.append(build(Path(tmp) / f"site{i}"))
            print(f"build {i + 1}: {times[-1]:.1f} s", flush=True)
        images = images_per_page(Path(tmp) / "site0")
    tests_s, tests = run_tests(["tests/test_docs.py"])
    print(f"tests/test_docs.py: {tests_s:.0f} s ({last_line(tests)})", flush=True)
    commands = None
    if not args.no_commands:
        commands_s, done = run_tests(["-m", "slow", "--durations=0", "tests/test_docs_commands.py"])
        pages = page_seconds(done.stdout)
        commands = {
            "wall_s": commands_s,
            "passed": done.returncode == 0,
            "summary": last_line(done),
            "page_s": pages,
            "page_s_median": statistics.median(pages.values()) if pages else None,
        }
        print(f"tests/test_docs_commands.py: {commands_s:.0f} s ({last_line(done)})")
    without = [page for page, n in images.items() if n == 0]
    result = {
        "provenance": result_header(calibration),
        "build_s": {
            "median": statistics.median(times),
            "min": min(times),
            "max": max(times),
            "builds": len(times),
        },
        "images_per_page": images,
        "pages": len(images),
        "pages_without_images": without,
        "images_total": sum(images.values()),
        "docs_tests": {
            "wall_s": tests_s,
            "passed": tests.returncode == 0,
            "summary": last_line(tests),
        },
        # every shell example's `mca-drake` lines, shrunk (a slow test; None: skipped)
        "shell_examples": commands,
    }
    atomic_write_json(args.json, result)
    print(
        f"build median {result['build_s']['median']:.1f} s ({min(times):.1f}-{max(times):.1f}); "
        f"{result['images_total']} images on {len(images)} pages, {len(without)} without: "
        f"{', '.join(without) or 'none'}"
    )
    passed = tests.returncode == 0 and (commands is None or commands["passed"])
    return 0 if passed else 1


if __name__ == "__main__":
    raise SystemExit(main())
