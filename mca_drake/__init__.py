"""mca-drake: learning-based motion cueing for motion simulators, on Drake.

Layers (imports point down only; tests/test_architecture.py checks it):
    app          typed scenarios (diagrams/*.yaml), jobs and the `mca-drake` command
    studies      batch work over many closed loops: evaluation suite, closed-loop dataset,
                 Table II
    simulation   diagram builders and the one closed-loop runner for both plants
    systems      Drake LeafSystems: plant, reference source, the MCAs, the KR500 station
    learning     torch only: torch plant, plant-model candidates, policy network, trainers,
                 DPC training
    cueing       the MCAs as numpy math with their typed configs (DpcConfig, NmpcConfig,
                 WashoutConfig)
    platforms    what moves the occupant: platform files, serial chains from a URDF, their
                 kinematics and joint usage
    perception   vestibular models, thresholds, sickness
    references   vehicle motion: recordings, JSBSim flights, scaling to references
    core         conventions, safety, metrics, segments, resources, plotting, atomic_io,
                 input_checks
"""

__version__ = "0.1.0"
