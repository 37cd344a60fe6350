"""Open-loop excitation dataset (Algorithm 1) at the paper's size: wall time per run.

python benchmarks/bench_excitation.py [--runs 3]
"""

from __future__ import annotations

import argparse
import time

from common import describe, print_calibration

from mca_drake.platforms.excitation import ExcitationConfig, generate_excitation_dataset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    print_calibration()
    samples, dataset = [], None
    for seed in range(args.runs):
        start = time.perf_counter()
        dataset = generate_excitation_dataset(ExcitationConfig(seed=seed), progress=False)
        samples.append(time.perf_counter() - start)
        print(f"  seed {seed}: {len(dataset)} segments, {samples[-1]:.2f} s")
    meta = dataset.metadata
    print(
        f"paper size (5 signals x 21 joint ranges x 100 runs x 20 s = "
        f"{meta['simulated_steps']:,} plant steps): {describe(samples, 's')}"
    )


if __name__ == "__main__":
    main()
