"""cosim orchestrator: the run. Entry points (CLI, API, pytest plugin), ``execute``, the
starters (one per node role) and the run rules at the top; the lockstep loop, proxies, ROS 2
surface, live side and outputs in folders."""

from plan.errors import ScenarioError, SimulationError

__all__ = ["ScenarioError", "SimulationError"]
