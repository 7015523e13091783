"""cosim orchestrator: scenario checking, schedule, lockstep master, supervision, outputs."""

from plan.errors import ScenarioError, SimulationError

__all__ = ["ScenarioError", "SimulationError"]
