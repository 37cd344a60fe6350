"""Batch studies over many closed loops: the evaluation suite, the closed-loop dataset and
Table II; each task is a small config that its worker turns into a diagram."""
