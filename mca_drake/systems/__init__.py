"""Drake LeafSystems of the motion-cueing toolbox.

- MotionCueingPlant: the exact joint-space plant of equation (1), discrete at 100 Hz.
- ReferenceSource: plays a motion-cueing reference, with a preview for the NMPC.
"""

from mca_drake.systems.motion_cueing_plant import MotionCueingPlant
from mca_drake.systems.reference_source import ReferenceSource

__all__ = ["MotionCueingPlant", "ReferenceSource"]
