"""Diagram builders and the one closed-loop runner for both plants.

- `builders`: `AddMca`, `MakeAnalyticalClosedLoop`, `MakeMultibodyClosedLoop`,
  `MakePlantDemoDiagram`.
- `closed_loop`: `run_closed_loop` (analytical or multibody plant), `ClosedLoopResult` and
  its summary.
- `plots`: the tracking (Fig. 4) and joint-usage (Fig. 5) plots of a run.
"""
