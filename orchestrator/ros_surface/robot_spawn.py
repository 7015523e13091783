"""SpawnEntity and DeleteEntity for robots a client brings in (issue 49): the scenario
plans them (``spawnables[].robots``: each a robot of a spawnable description with its name
and goal), so their ``for_each: robot`` nodes are started with the run and dormant. A
SpawnEntity of that description takes the next robot not taken (or the one it names); the
lockstep admits it at the next tick boundary where the world node acts
(``LockstepMaster._admit_robots``: every node told its window, then the edit enters through
the external node, recorded, so ``--replay`` opens the same windows). With none left, the
request gets ``RESULT_OPERATION_FAILED`` and a message that says how many the scenario
plans. A robot once taken out is not brought in again (its window has closed).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from simulation_interfaces.msg import Result
from simulation_interfaces.srv import SpawnEntity

from orchestrator.ros_surface.simcontrol import RunControl
from orchestrator.ros_surface.spawn_resources import Refused, pose_of
from plan.events import EventSpec, WorldObjects, edit_event
from plan.obstacles import place_problem
from plan.robots import BY_CLIENT
from plan.scenario import Scenario

R = SpawnEntity.Response


class RobotRequest:
    """A robot entering (``opens``) or leaving; ``commit(tick)`` puts its edit into the
    run once the lockstep has told every node (``RunControl.request_robot``)."""

    def __init__(self, robot: str, opens: bool, edit: EventSpec,
                 put: Callable[[EventSpec], None]):
        self.robot, self.opens, self.edit, self._put = robot, opens, edit, put

    def commit(self, tick: int) -> None:
        """The lockstep admits it at ``tick``: the edit enters through the external node."""
        self._put(self.edit)


class RobotSlots:
    """The robots clients may bring in, which are taken and which are in the world."""

    def __init__(self, scenario: Scenario, control: RunControl,
                 put: Callable[[EventSpec], None], world: Callable[[], WorldObjects]):
        layout = scenario.robots
        self.slots = [] if layout is None else [r for r in layout.robots
                                                if r.enter_ns == BY_CLIENT]
        self.control, self.put, self.world = control, put, world
        self.taken: set[str] = set()
        self.inside: set[str] = set()

    def spawn(self, request: SpawnEntity.Request) -> tuple[int, str, str] | None:
        """(code, message, name) of a request for a robot the scenario plans, or None: not
        a planned robot's description."""
        uri = request.uri
        if not self.slots or not uri or ("://" in uri and not uri.startswith("file://")):
            return None
        path = Path(uri.removeprefix("file://")).expanduser().resolve()
        mine = [s for s in self.slots if s.description == path]
        if not mine:
            return None
        names = [s.name for s in mine]
        free = [s for s in mine if s.name not in self.taken]
        if not free:
            return (Result.RESULT_OPERATION_FAILED, f"no robot of {path.name} is left to "
                    f"bring in: the scenario plans {len(mine)} ({', '.join(names)}), all "
                    "taken; plan more in spawnables[].robots.", "")
        pick = free[0]
        if request.name and request.name != pick.name:
            named = next((s for s in free if s.name == request.name), None)
            if named is not None:
                pick = named
            elif not request.allow_renaming:
                code = R.NAME_NOT_UNIQUE if request.name in names else R.NAME_INVALID
                return (code, f"{request.name!r} is not a robot of {path.name} left to bring "
                        f"in: one of {', '.join(s.name for s in free)} (the scenario's "
                        "spawnables[].robots), or allow_renaming.", "")
        space = request.entity_namespace.strip("/")
        if space and space != pick.name:
            return (R.NAMESPACE_INVALID, f"entity_namespace {request.entity_namespace!r}: "
                    f"{pick.name} lives under /{pick.name}.", "")
        try:
            pose = pose_of(request.initial_pose)
        except Refused as exc:
            return exc.code, str(exc), ""
        world = self.world()
        radius = max((m.radius for m in world.movers if m.radius), default=0.2)
        problem = place_problem(list(world.obstacles), pose["x"], pose["y"], radius)
        if problem:
            return R.INVALID_POSE, f"{pick.name} cannot enter there: {problem}.", ""
        gx, gy, gyaw = pick.goal
        edit = edit_event({"robot": {"name": pick.name, "start": {
            "x": pose["x"], "y": pose["y"], "yaw": pose["yaw"]},
            "goal": {"x": gx, "y": gy, "yaw": gyaw}}})
        self.taken.add(pick.name)
        self.inside.add(pick.name)
        self.control.cannot_reset = (f"a client brought {pick.name} in, and a robot's window "
                                     "is not undone by a reset")
        self.control.request_robot(RobotRequest(pick.name, True, edit, self.put))
        return (Result.RESULT_OK, f"{pick.name!r} enters with its nodes at the next tick "
                "boundary where physics acts", pick.name)

    def delete(self, entity: str) -> tuple[int, str] | None:
        """(code, message) of a DeleteEntity of a robot a client brought in, or None."""
        if entity not in self.taken:
            return None
        if entity not in self.inside:
            return Result.RESULT_NOT_FOUND, f"{entity!r} was taken out already."
        self.inside.discard(entity)
        self.control.request_robot(RobotRequest(entity, False, edit_event(
            {"delete": entity}), self.put))
        return (Result.RESULT_OK, f"{entity!r} leaves at the next tick boundary where physics "
                "acts; its nodes stop being scheduled")

