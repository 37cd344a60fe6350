"""Torch plant rollout, forward + backward, batch 256 x 256 steps, on 1 and 2 threads.

python benchmarks/bench_torch_plant.py [--batch 256] [--steps 256] [--repeats 20]
"""

from __future__ import annotations

import argparse

import torch
from common import describe, print_calibration, time_calls

from mca_drake.learning.torch_plant import TorchPlant
from mca_drake.platforms.files import load_platform

KR500 = load_platform("kr500")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--steps", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    print_calibration()
    print(f"torch {torch.__version__}, rollout batch {args.batch} x {args.steps} steps")
    for dtype in (torch.float32, torch.float64):
        for threads in args.threads:
            torch.set_num_threads(threads)
            forward_backward, forward_only = rollout_calls(args.batch, args.steps, dtype)
            fb = time_calls(forward_backward, repeats=args.repeats)
            fo = time_calls(forward_only, repeats=args.repeats)
            name = str(dtype).removeprefix("torch.")
            print(f"  {name}, {threads} thread(s): forward+backward {describe(fb)}")
            print(f"  {name}, {threads} thread(s): forward only     {describe(fo)}")


def rollout_calls(batch: int, steps: int, dtype: torch.dtype):
    """(forward+backward, forward-only) closures over one random rollout problem."""
    plant = TorchPlant(KR500, dtype=dtype, check_inputs=False)
    gen = torch.Generator().manual_seed(0)
    x0 = 0.3 * torch.randn(batch, 12, generator=gen, dtype=dtype)
    U = (0.5 * torch.randn(batch, steps, 6, generator=gen, dtype=dtype)).requires_grad_()

    def forward_backward():
        _, Y = plant(x0, U)
        (Y**2).mean().backward()
        U.grad = None

    def forward_only():
        with torch.no_grad():
            plant(x0, U)

    return forward_backward, forward_only


if __name__ == "__main__":
    main()
