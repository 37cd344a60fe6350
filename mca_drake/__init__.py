"""mca-drake: learning-based motion cueing for a KUKA KR500 motion simulator, on Drake.

Modules (data flows one way, top to bottom):
    robot          the KR500 description read from models/kr500.urdf
    kinematics     numpy head-frame kinematics and the plant output y (equation 1)
    torch_plant    the same plant in torch, batched and differentiable
    systems        Drake LeafSystems (MotionCueingPlant, ...)
    diagrams       builders that wire systems into runnable diagrams
    metrics        RMSE, Pearson CC, performance index, Wilcoxon, limit usage
    cli            the `mca-drake` command
"""

__version__ = "0.1.0"
