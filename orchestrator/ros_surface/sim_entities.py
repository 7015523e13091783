"""The robot as a simulation_interfaces entity: its state as the run last decided it, and
teleports that enter the run at a tick boundary.

The state comes from the physics node's /odom as the node recorded it (``parts/<node>.rec``,
flushed at every activation before the node reports it done; read when asked, as the live
view reads it): the sample of the last tick every node has finished. Nothing is added to
the transport or to the master's loop. A teleport
(SetEntityState) becomes a /cosim/set_pose message (simulation_interfaces/NamedPose) put
into the run's external arrivals: it enters at the external node's next activation, is
recorded, and the physics node applies it once (plan/interactive.py).
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

from nav_msgs.msg import Odometry
from simulation_interfaces.msg import EntityState, NamedPose, Result
from simulation_interfaces.srv import SetEntityState

from orchestrator.live.live_tail import PartFollower
from orchestrator.ros_surface.simcontrol import RunControl
from plan.interactive import SET_POSE_TOPIC
from plan.scenario import EXTERNAL_NAME, NodePlan, Scenario
from runtime.arrivals import Arrivals
from runtime.cdr.decode import decode

FRAMES = ("", "world", "map", "odom")  # one frame: odometry is ground truth, map = odom
KEEP = 256  # /odom samples kept: more than the pipeline window runs ahead


class RobotEntity:
    """The robot of a scenario's physics node, named after its base body."""

    def __init__(self, scenario: Scenario, physics: NodePlan, control: RunControl,
                 arrivals: Arrivals | None, part: Path):
        self.name = physics.params.base_body
        self.control = control
        self.tick_ns = scenario.tick_ns
        self.period = scenario.schedule.periods[physics.name]
        self.odom_topic = physics.output_names["/odom"]
        self.follower = PartFollower(part, set(physics.outputs))
        self.samples: dict[int, bytes] = {}  # tick -> /odom bytes, the latest KEEP
        self._lock = threading.Lock()
        teleport = physics.spec.remap.get(SET_POSE_TOPIC, SET_POSE_TOPIC)
        takes = any(inp.topic == SET_POSE_TOPIC for inp in physics.inputs)
        self.teleport_topic = (teleport if takes and arrivals is not None
                               and teleport in arrivals.topics else None)
        self.arrivals = arrivals
        self.external_period = scenario.schedule.periods.get(EXTERNAL_NAME, 1)
        self._scenario = scenario
        self._obstacles = None
        self.requests = 0  # teleports asked for: each message differs, so each applies once
        self.spawned_obstacles = list  # () -> the static objects spawned (sim_spawn), if any
        control.reset_listeners.append(self.forget)

    # -- state ------------------------------------------------------------------------------

    def forget(self) -> None:
        """The run was reset (the master's thread): the record starts over."""
        with self._lock:
            self.samples.clear()
            self.follower.offset = 0

    def state(self) -> tuple[EntityState | None, str]:
        """The robot's ground-truth state at the last decided tick (pose and twist in the
        world frame), or None and why not."""
        decided = self.control.decided
        if decided < 0:
            return None, "the run has not finished a tick yet: step or play first"
        wanted = decided - decided % self.period
        with self._lock:
            records = self.follower.read()
            if self.follower.restarted:  # the record started over: a reset
                self.samples.clear()
                self.follower.restarted = False
            for tick, topic, data in records:
                if topic == self.odom_topic:
                    self.samples[tick] = data
            for tick in sorted(self.samples)[:-KEEP]:
                del self.samples[tick]
            older = [tick for tick in self.samples if tick <= wanted]
            data = self.samples[max(older)] if older else None
        if data is None:
            return None, f"no {self.odom_topic} of tick {wanted} or before it was recorded"
        return entity_state(decode(data, Odometry)), ""

    # -- teleport ---------------------------------------------------------------------------

    def set_state(self, request: SetEntityState.Request) -> tuple[int, str]:
        """Check a SetEntityState and put its teleport into the run: (result code, text)."""
        if self.teleport_topic is None:
            why = ("this run replays recorded inputs" if self.arrivals is None else
                   "the scenario is not interactive: set interactive: true")
            return Result.RESULT_FEATURE_UNSUPPORTED, f"cannot set the robot's state: {why}."
        s = request.state
        if s.header.frame_id not in FRAMES:
            return Result.RESULT_OPERATION_FAILED, (
                f"unknown frame {s.header.frame_id!r}: use world (or '', map, odom: the same).")
        moving = [s.twist.linear, s.twist.angular, s.acceleration.linear, s.acceleration.angular]
        if any(v.x or v.y or v.z for v in moving):
            return Result.RESULT_OPERATION_FAILED, (
                "only a state at rest can be set (twist and acceleration zero).")
        p, q = s.pose.position, s.pose.orientation
        values = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
        norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
        if not all(map(math.isfinite, values)) or norm < 1e-6:
            return SetEntityState.Response.INVALID_POSE, (
                "the pose is not finite or its quaternion is zero.")
        problem = self._place_problem(p.x, p.y)
        if problem:
            return SetEntityState.Response.INVALID_POSE, f"the robot cannot stand there: {problem}."
        with self._lock:
            self.requests += 1
            boundary = self.control.boundary
            self.arrivals.put(self.teleport_topic, NamedPose(
                name=self.name, pose=s.pose,
                description=f"SetEntityState request {self.requests} before tick {boundary}"))
        k = -(-boundary // self.external_period) * self.external_period
        return Result.RESULT_OK, (f"the robot is put at ({p.x:g}, {p.y:g}) at rest at tick {k} "
                                  "(the next tick boundary) or, if the run is past it, the next "
                                  "one; x, y and yaw are applied, z, roll and pitch stay level "
                                  "on the floor.")

    def _place_problem(self, x: float, y: float) -> str | None:
        from descriptions.world_geometry import static_obstacles
        from descriptions.worldfile import load_world_model
        from plan.obstacles import place_problem
        from runtime.build import scenario_robots

        if self._obstacles is None:
            self._obstacles = static_obstacles(load_world_model(self._scenario.world))
            (robot,) = scenario_robots(self._scenario)  # the robot model's footprint
            self._radius = robot.footprint_radius
        return place_problem([*self._obstacles, *self.spawned_obstacles()], x, y, self._radius)


def entity_state(odom: Odometry) -> EntityState:
    """An Odometry of ground truth as an EntityState: pose, twist turned into the world
    frame (odometry gives it in the base frame)."""
    state = EntityState()
    state.header.stamp = odom.header.stamp
    state.header.frame_id = "world"
    state.pose = odom.pose.pose
    q = odom.pose.pose.orientation
    lin, ang = odom.twist.twist.linear, odom.twist.twist.angular
    for src, dst in ((lin, state.twist.linear), (ang, state.twist.angular)):
        dst.x, dst.y, dst.z = _rotate((q.w, q.x, q.y, q.z), (src.x, src.y, src.z))
    return state


def _rotate(q: tuple[float, float, float, float], v: tuple[float, float, float]
            ) -> tuple[float, float, float]:
    """v rotated by the unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 q_vec x v; v' = v + w t + q_vec x t
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
            vz + w * tz + x * ty - y * tx)

