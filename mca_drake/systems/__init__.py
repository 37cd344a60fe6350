"""Drake LeafSystems of the motion-cueing toolbox (numpy and Drake only, never torch).

- MotionCueingPlant: the exact joint-space plant of equation (1), discrete at 100 Hz.
- ReferenceSource: plays a motion-cueing reference, with a preview for the NMPC.
- NmpcController, DpcPolicy, ClassicalWashout (their modules): the MCAs, each configured
  by its config of `mca_drake.cueing`.
- station: `AddStation`, a serial platform's MultibodyPlant (the KR500's in the default
  scenario) with inverse-dynamics control and a head IMU; meshcat_traces: live strip charts
  in Meshcat.
"""

from mca_drake.systems.motion_cueing_plant import MotionCueingPlant
from mca_drake.systems.reference_source import ReferenceSource

__all__ = ["MotionCueingPlant", "ReferenceSource"]
