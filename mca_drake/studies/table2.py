"""The paper's plant-model study (Table II), reproduced, with the exact analytical plant added.

For every state-transition candidate (nssm, node1, node2, exact) and output candidate
(nssm, latent, mixed, exact):

1. train it over the curriculum n_p = 32, 64, 128, 256 on the closed-loop dataset (output
   candidates on the states of a frozen NODE 2, as the paper; the exact output on the exact
   states: together the exact analytical plant);
2. score the best weights of each curriculum step: RMSE on the validation and test sets at
   that n_p (states for state models, outputs for output models);
3. time inference: mean over `timing_calls` calls on single random training segments at
   n_p = 1 and 256 (output candidates include their state model: the whole plant);
4. score generalisation: RMSE on the open-loop dataset (Algorithm 1) at n_p = 256.

Everything lands in `out_dir`: per candidate a checkpoint (resumable), loss log and curve,
and the best weights per n_p; then `table2.md` and `table2.json` with the paper's figures
beside ours. `run_table2(..., resume=True)` continues a killed run where it stopped.
"""

from __future__ import annotations

import dataclasses
import io
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

from mca_drake.atomic_io import (
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    check_writable,
)
from mca_drake.learning.checkpoint import load_state_into
from mca_drake.learning.data import to_tensors
from mca_drake.learning.plant_candidates import (
    make_output_model,
    make_state_model,
    output_objective,
    predict_outputs,
    predict_states,
    rmse,
    state_objective,
)
from mca_drake.learning.trainer import CurriculumTrainer, StageResult, TrainConfig
from mca_drake.segments import (
    DEFAULT_DATASET,
    SOURCE_COLUMNS,
    SegmentDataset,
    package_versions,
    split_of,
)
from mca_drake.studies.parallel import ray_address, run_tasks

# Table II of the paper: RMSE (validation, test) per n_p, iteration time (s) at n_p 1 and
# 256, open-loop RMSE at 256. None: not reported.
PAPER = {
    "state": {
        "nssm": {
            "validation": {32: 1.905, 64: 1.789, 128: 2.100, 256: 2.436},
            "test": {32: 1.919, 64: 1.903, 128: 1.770, 256: 2.519},
            "time": {1: 4.90e-4, 256: 0.063},
            "open_loop": None,
        },
        "node1": {
            "validation": {32: 0.002, 64: 0.003, 128: 0.010, 256: 0.006},
            "test": {32: 0.003, 64: 0.004, 128: 0.005, 256: 0.011},
            "time": {1: 7.73e-4, 256: 0.136},
            "open_loop": None,
        },
        "node2": {
            "validation": {32: 0.001, 64: 0.002, 128: 0.003, 256: 0.004},
            "test": {32: 0.001, 64: 0.002, 128: 0.003, 256: 0.004},
            "time": {1: 2.54e-4, 256: 0.023},
            "open_loop": None,
        },
    },
    "output": {
        "nssm": {
            "validation": {32: 0.320, 64: 0.224, 128: 0.250, 256: 0.198},
            "test": {32: 0.349, 64: 0.229, 128: 0.221, 256: 0.221},
            "time": {1: 5.37e-4, 256: 0.098},
            "open_loop": 20.612,
        },
        "latent": {
            "validation": {32: 0.327, 64: 0.172, 128: 0.157, 256: 0.084},
            "test": {32: 0.368, 64: 0.212, 128: 0.100, 256: 0.095},
            "time": {1: 5.74e-4, 256: 0.099},
            "open_loop": 19.094,
        },
        "mixed": {
            "validation": {32: 0.186, 64: 0.109, 128: 0.143, 256: 0.093},
            "test": {32: 0.232, 64: 0.133, 128: 0.095, 256: 0.111},
            "time": {1: 0.002, 256: 0.368},
            "open_loop": 10.158,
        },
    },
}
LABELS = {
    "nssm": "NSSM",
    "node1": "NODE 1",
    "node2": "NODE 2",
    "latent": "Latent space",
    "mixed": "Mixed analytical",
    "exact": "Exact plant",
}


@dataclasses.dataclass
class Table2Config:
    """What the study trains and scores; defaults: the paper's full size."""

    # Closed-loop dataset (a merged file of `mca-drake dataset closed-loop`; one without
    # split labels is split 70:20:10 with `split_seed`). Its n_p must be >= the horizons.
    closed_loop_dataset: str = DEFAULT_DATASET
    # Open-loop dataset (`mca-drake dataset open-loop`), scored at its own n_p.
    open_loop_dataset: str = "datasets/open_loop.npz"
    state_models: tuple[str, ...] = ("nssm", "node1", "node2", "exact")
    output_models: tuple[str, ...] = ("nssm", "latent", "mixed", "exact")
    # Frozen state model under the learned output candidates (the paper: NODE 2).
    output_state_model: str = "node2"
    train: TrainConfig = dataclasses.field(default_factory=TrainConfig)
    # Inference calls per timing (the paper: 1000), and the horizons timed.
    timing_calls: int = 1000
    timing_horizons: tuple[int, ...] = (1, 256)
    # Seed of every weight initialisation (all generators are seeded with it).
    seed: int = 0
    split_seed: int = 0


def quick_config(closed_loop_dataset: str, open_loop_dataset: str) -> Table2Config:
    """A few-minute version for tests and smoke runs: short horizons, few epochs."""
    return Table2Config(
        closed_loop_dataset=closed_loop_dataset,
        open_loop_dataset=open_loop_dataset,
        train=TrainConfig(horizons=(8, 16, 32), max_epochs=4, batch_size=64),
        timing_calls=20,
        timing_horizons=(1, 32),
    )


def _splits(path: str, split_seed: int) -> dict[str, SegmentDataset]:
    data = SegmentDataset.load(path)
    columns = data.metadata.get("source_columns", [])
    if list(columns) == list(SOURCE_COLUMNS) and "split_names" in data.metadata:
        return split_of(data)
    train, validation, test = data.split((0.7, 0.2, 0.1), seed=split_seed)
    return {"train": train, "validation": validation, "test": test}


def _time_inference(predict, data: SegmentDataset, horizons, calls: int, seed: int) -> dict:
    """Mean seconds per call of `predict(batch)` on single random segments, per horizon."""
    rng = np.random.default_rng(seed)
    times = {}
    for n in horizons:
        # n steps predicted need n + 1 samples of the segment (the first is the condition).
        tensors = to_tensors(data, min(n + 1, data.horizon))
        picks = rng.integers(0, len(tensors), size=calls)
        with torch.no_grad():
            predict(tensors.batch(torch.as_tensor(picks[:1])))  # warm-up
            start = time.perf_counter()
            for i in picks:
                predict(tensors.batch(torch.as_tensor([int(i)])))
            times[n] = (time.perf_counter() - start) / calls
    return times


def _stage_saver(folder: Path, name: str):
    def save(stage: StageResult, model: torch.nn.Module) -> None:
        buffer = io.BytesIO()
        torch.save(model.state_dict(), buffer)
        atomic_write_bytes(folder / f"{name}_n{stage.horizon}.pt", buffer.getvalue())

    return save


def _candidate(kind: str, name: str, config: Table2Config):
    torch.manual_seed(config.seed)
    if kind == "state":
        return make_state_model(name), None
    state_name = "exact" if name == "exact" else config.output_state_model
    return make_output_model(name), make_state_model(state_name)


def run_table2(
    config: Table2Config,
    out_dir: str | Path,
    *,
    resume: bool = False,
    progress: bool = True,
    workers: int = 1,
    address: str | None = None,
) -> dict:
    """Trains and scores every candidate; writes table2.md/json in `out_dir`; returns the
    JSON dictionary. With `resume`, finished candidates are read back and a killed one
    continues from its checkpoint.

    Args:
        workers: candidates trained at once, on a local Ray with this many CPUs (each with
            one torch thread; the inference times of the table then share the machine);
            1 trains them here, one after the other.
        address: a Ray cluster to train on (default RAY_ADDRESS, else a local Ray).
    """
    # absolute: a cluster's workers write here from folders of their own
    out = check_writable(Path(out_dir).resolve(), folder=True)
    started = time.perf_counter()
    splits = _splits(config.closed_loop_dataset, config.split_seed)
    open_loop = SegmentDataset.load(config.open_loop_dataset)
    jobs = [("state", n) for n in config.state_models] + [
        ("output", n) for n in config.output_models
    ]
    parallel = workers > 1 or ray_address(address) is not None
    todo = [
        (config, kind, name, str(out), resume, progress and not parallel, parallel)
        for kind, name in jobs
        if not (resume and _result_path(out, kind, name).is_file())
    ]
    run_tasks(
        _run_candidate,
        todo,
        workers=workers,
        address=address,
        total=len(jobs),
        description="Table II candidates",
        unit="candidate",
        progress=progress and parallel,
    )
    rows: dict[str, dict] = {"state": {}, "output": {}}
    for kind, name in jobs:
        rows[kind][name] = json.loads(_result_path(out, kind, name).read_text())
    device = config.train.resolved_device()
    report = {
        "rows": rows,
        "paper": json.loads(json.dumps(PAPER)),
        "config": json.loads(json.dumps(dataclasses.asdict(config))),
        "datasets": {k: len(v) for k, v in splits.items()} | {"open_loop": len(open_loop)},
        "open_loop_horizon": open_loop.horizon,
        "device": str(device),
        "machine": platform.processor() or platform.machine(),
        "torch_threads": torch.get_num_threads(),
        "wall_s": time.perf_counter() - started,
        # Training time summed over candidates, across resumed runs (wall_s is this run's).
        "train_wall_s": sum(r.get("train_wall_s", 0.0) for k in rows.values() for r in k.values()),
        "versions": package_versions(),
    }
    atomic_write_json(out / "table2.json", report)
    atomic_write_text(out / "table2.md", table2_markdown(report))
    return report


def _cell(ours, paper, fmt: str) -> str:
    # Figures that the fixed format would print as zero (the exact plant) keep 2 digits.
    tiny = ours is not None and 0 < abs(ours) < 5e-5
    text = "-" if ours is None else format(ours, ".1e" if tiny else fmt)
    return text if paper is None else f"{text} ({format(paper, fmt)})"


def table2_markdown(report: dict) -> str:
    """Table II as markdown: our figure with the paper's in parentheses."""
    rows, paper = report["rows"], report["paper"]
    columns = [("state", n) for n in rows["state"]] + [("output", n) for n in rows["output"]]
    head = ["Metric", "n_p"] + [
        f"{'State' if k == 'state' else 'Output'}: {LABELS[n]}" for k, n in columns
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def paper_of(kind, name, key, n=None):
        entry = paper.get(kind, {}).get(name)
        if entry is None or entry.get(key) is None:
            return None
        return entry[key] if n is None else entry[key].get(str(n))

    for key, label in (("validation", "RMSE validation"), ("test", "RMSE test")):
        for n in next(iter(rows["state"].values() or rows["output"].values()))[key]:
            cells = [
                _cell(rows[k][c][key].get(n), paper_of(k, c, key, n), ".4f") for k, c in columns
            ]
            lines.append(f"| {label} | {n} | " + " | ".join(cells) + " |")
    any_row = next(iter(rows["state"].values() or rows["output"].values()))
    for n in any_row["time"]:
        cells = [_cell(rows[k][c]["time"][n], paper_of(k, c, "time", n), ".3g") for k, c in columns]
        lines.append(f"| Iteration time [s] | {n} | " + " | ".join(cells) + " |")
    cells = [_cell(rows[k][c]["open_loop"], paper_of(k, c, "open_loop"), ".4f") for k, c in columns]
    lines.append(f"| RMSE open-loop | {report['open_loop_horizon']} | " + " | ".join(cells) + " |")
    train = [f"{rows[k][c]['train_wall_s'] / 60:.1f}" for k, c in columns]
    lines.append("| Training wall time [min] | all | " + " | ".join(train) + " |")
    sizes = ", ".join(f"{k} {v}" for k, v in report["datasets"].items())
    lines += [
        "",
        "Ours, with the paper's figure in parentheses. RMSE of states (state models; rad and "
        "rad/s together) or outputs (output models; rad/s and m/s^2 together) over every "
        "predicted step. Learned output models run on NODE 2 states; the exact plant on exact "
        "states. Iteration time: mean of single-segment inference calls.",
        f"Segments: {sizes}. Device: {report['device']}, {report['torch_threads']} torch "
        f"threads. Training wall time summed over candidates (across resumed runs): "
        f"{report.get('train_wall_s', 0.0) / 60:.1f} min; this run, scoring included: "
        f"{report['wall_s'] / 60:.1f} min.",
    ]
    return "\n".join(lines) + "\n"


def _result_path(out: Path, kind: str, name: str) -> Path:
    # Not f"{tag}.json": that name is the checkpoint's metadata beside f"{tag}.pt", and a
    # killed candidate would be read back as finished.
    return Path(out) / f"{kind}_{name}_result.json"


def _run_candidate(
    config: Table2Config,
    kind: str,
    name: str,
    out_dir: str,
    resume: bool,
    progress: bool,
    single_thread: bool,
) -> None:
    """Trains and scores one candidate; writes its result file (a task of `run_table2`)."""
    if single_thread:  # tasks share the machine: one torch thread each
        torch.set_num_threads(1)
    out = Path(out_dir)
    splits = _splits(config.closed_loop_dataset, config.split_seed)
    open_loop = SegmentDataset.load(config.open_loop_dataset)
    horizons = config.train.horizons
    device = config.train.resolved_device()
    tag = f"{kind}_{name}"
    result_path = _result_path(out, kind, name)
    model, state_model = _candidate(kind, name, config)
    if state_model is not None:
        state_model = state_model.to(device)
    objective = state_objective if kind == "state" else output_objective(state_model)
    train_wall = 0.0
    if model.learnable:
        trainer = CurriculumTrainer(
            model,
            objective,
            config.train,
            out / f"{tag}.pt",
            {"model": name, "kind": kind, "dataset": config.closed_loop_dataset},
            stage_callbacks=[_stage_saver(out, tag)],
        )
        if progress:
            print(f"training {kind} model {LABELS[name]}")
        fit = trainer.fit(splits["train"], splits["validation"], resume=resume, progress=progress)
        train_wall = fit.wall_s
    model = model.to(device)

    def score(data: SegmentDataset, n: int, model=model, state_model=state_model, kind=kind):
        tensors = to_tensors(data, n, device=device)
        if kind == "state":
            return rmse(tensors, state_model=model)
        return rmse(tensors, state_model=state_model, output_model=model)

    row = {"validation": {}, "test": {}, "train_wall_s": train_wall}
    for n in horizons:
        if model.learnable:
            state = torch.load(out / f"{tag}_n{n}.pt", map_location=device, weights_only=True)
            load_state_into(model, state, f"{tag}_n{n}.pt")
        model.eval()
        row["validation"][n] = score(splits["validation"], n)
        row["test"][n] = score(splits["test"], n)
    model, state_model = model.cpu(), state_model.cpu() if state_model is not None else None
    if kind == "state":
        predict = lambda b, m=model: predict_states(m, b)  # noqa: E731
    else:
        predict = lambda b, m=model, s=state_model: predict_outputs(m, s, b)  # noqa: E731
    row["time"] = _time_inference(
        predict, splits["train"], config.timing_horizons, config.timing_calls, config.seed
    )
    model, state_model = model.to(device), state_model.to(device) if state_model else None
    row["open_loop"] = score(open_loop, open_loop.horizon)
    row = json.loads(json.dumps(row))  # int keys become strings, as when read back
    atomic_write_json(result_path, row)
