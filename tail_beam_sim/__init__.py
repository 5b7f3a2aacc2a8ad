"""tail_beam_sim: physics core and simulator of an instrumented top-coal-caving tail beam.

The core (everything but the ``node``/``ros_*`` modules) imports no ROS package, so it serves
the ROS nodes, the offline ``tail-beam`` command line and the benchmarks alike.
"""

from tail_beam_sim.errors import InputError
from tail_beam_sim.physics.scene import Impact, Scene
from tail_beam_sim.physics.simulate import SimulationResult, simulate

__all__ = ["InputError", "Impact", "Scene", "SimulationResult", "simulate"]
