"""Writes the shipped DPC policies' reference ranges (mca_drake/data/policy_reference_ranges.json).

    .venv/bin/python scripts/policy_reference_ranges.py [--cache-dir results/training_flights]
        [--policies default_policy,light_policy,transport_policy,ground_policy]

Each shipped policy was last trained on a dataset of the training guide (its metadata's
`dataset`), on the flights of the vehicles its `dpc_config.vehicles` names (all where it
names none), from initial weights that learned every flight of the flight dataset: its
range covers both. This flies or drives those flights again (the dataset's seeds, the scripted
pilot, 5 minutes each: `references.drives.training_spec`, as `mca-drake dataset
closed-loop` does; of the drives, the first six) and writes each policy's `ReferenceRange`
(mirrored, as training mirrored half its windows). Flights are cached (`--cache-dir`): a
killed run resumes. A drive takes minutes, a flight seconds. A policy whose file carries its
own range (`train-policy` records it) is written with that range, the one its runs read
(`reference_range.policy_reference_range`), so that the platforms' moved copies, which
carry none, read the same. `--policies` writes only the ranges of those policies (one
trained again), keeping the file's others.
"""

from __future__ import annotations

import argparse
import datetime
import json
from pathlib import Path

from mca_drake.atomic_io import atomic_write_json
from mca_drake.cueing.dpc import load_policy_arrays, shipped_policy_path
from mca_drake.cueing.reference_range import SHIPPED_RANGES_FILE, reference_range
from mca_drake.references.drives import motion_reference, training_spec
from mca_drake.resources import data_dir
from mca_drake.studies.closed_loop_dataset import ClosedLoopDatasetConfig

# The flights of each dataset the shipped policies were trained on (docs/guides/training.md:
# `mca-drake dataset closed-loop` with these vehicles and seeds, joined).
DATASET_FLIGHTS = {
    "datasets/mixed_t37/dataset.npz": (
        (("light", "jet", "f16", "DHC6", "A320", "787-8"), range(100, 118)),
        (("light",), range(130, 138)),
        (("T37",), range(150, 156)),
    ),
    # the first six of its 18 drives, two per car (lap and proving ground each): a drive
    # takes minutes to simulate, and every drive runs the same two courses
    "datasets/drives/dataset.npz": ((("bmw-320i", "ford-escort", "vw-vanagon"), range(200, 206)),),
}
# The dataset every shipped policy's initial weights learned (the recipe's step 1 on it).
INITIAL_DATASET = "datasets/mixed_t37/dataset.npz"
# The policies whose ranges are written (a platform's moved policies read the KR500's).
POLICIES = ("default_policy", "light_policy", "transport_policy", "ground_policy")
DURATION_S = 300.0


def dataset_flights(dataset: str) -> list[tuple[str, int]]:
    """(vehicle, seed) of every flight of `dataset`, as `ClosedLoopDatasetConfig` deals them."""
    flights = []
    for vehicles, seeds in DATASET_FLIGHTS[dataset]:
        config = ClosedLoopDatasetConfig(vehicles=vehicles, flight_seeds=tuple(seeds))
        flights += config.flights()
    return flights


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cache-dir", default="results/training_flights")
    parser.add_argument("--policies", default=",".join(POLICIES))
    args = parser.parse_args()
    cache = Path(args.cache_dir)
    chosen = args.policies.split(",")
    unknown = sorted(set(chosen) - set(POLICIES))
    if unknown:
        raise SystemExit(f"--policies: {', '.join(unknown)} not among {', '.join(POLICIES)}")
    path = data_dir() / SHIPPED_RANGES_FILE
    kept = json.loads(path.read_text())["policies"] if path.is_file() else {}
    records = {name: kept[name] for name in POLICIES if name not in chosen and name in kept}
    for name in chosen:
        _, metadata = load_policy_arrays(shipped_policy_path(name))
        if "reference_range" in metadata:
            records[name] = metadata["reference_range"]
            print(f"{name}: the range its file carries", flush=True)
            continue
        dataset = metadata["dataset"]
        vehicles = metadata.get("dpc_config", {}).get("vehicles") or ()
        flights = [(v, s) for v, s in dataset_flights(dataset) if not vehicles or v in vehicles]
        if metadata.get("dpc_config", {}).get("initial_policy"):
            # fine-tuned from weights that learned every flight of the flight dataset (the
            # recipe's step 1 or 2, or the default policy): those flights are its too
            flights += [f for f in dataset_flights(INITIAL_DATASET) if f not in flights]
        references = []
        for vehicle, seed in flights:
            spec = training_spec(vehicle, seed)
            references.append(motion_reference(spec, DURATION_S, cache_dir=cache).y)
            print(f"{name}: {vehicle} {seed}", flush=True)
        kinds = ", ".join(sorted({v for v, _ in flights}))
        drives = dataset.endswith("drives/dataset.npz")
        source = f"{len(flights)} training flights and drives ({kinds}), mirrored"
        if drives:
            source += f"; of {dataset}'s drives the first six"
        records[name] = reference_range(references, mirrored=True, source=source).record()
    atomic_write_json(
        path,
        {
            "command": "python scripts/policy_reference_ranges.py",
            "date": datetime.date.today().isoformat(),
            "duration_s": DURATION_S,
            "policies": {name: records[name] for name in POLICIES if name in records},
        },
    )


if __name__ == "__main__":
    main()
