"""Drake LeafSystems of the motion-cueing toolbox.

- MotionCueingPlant: the exact joint-space plant of equation (1), discrete at 100 Hz.
"""

from mca_drake.systems.motion_cueing_plant import MotionCueingPlant

__all__ = ["MotionCueingPlant"]
