"""The control node: a small Nav2-style navigator over ground-truth odometry and a 2D scan.

- Global planner: A* over a grid of the world's static geometry (the MJCF file the physics
  node loads, distances measured to the obstacles' true footprints), with a lethal radius
  around obstacles and a cost that decays with distance, so paths keep to the middle of
  free space; where no way keeps the lethal radius, one that keeps robot_radius +
  safety_margin (``nodes.control.global_planner``). Recoveries add what the scan saw and the map
  did not know to the map before replanning.
- Local planner: regulated pure pursuit (rotate in place towards the path when facing
  away; slow down on sharp curvature, near the goal, and before scan points on the arc).
  When what blocks the arc is something the map does not know (another robot, a person),
  it steps aside: of a fan of arcs at the same speed, the one whose clear stretch gets
  nearest the pursuit target (the rightmost among equals); the plan is kept, nothing is
  replanned. Head-on, where no arc of the fan gets nearer, it slows and creeps as before.
  Where scan points within the safety margin block the arc (a narrow passage), creep at
  min_speed keeping tight_margin, on the pursuit arc or the clear arc nearest its target.
- Goal checker: position tolerance, then turn in place to the goal heading; once reached
  the goal stays reached and the node publishes zero velocity until it gets a new goal.
- Progress checker and recovery: if the robot moves less than ``progress_distance`` within
  ``progress_window`` seconds it backs up (when the scan behind is clear) and replans.
- When no plan exists the robot stands still, the node notes why (``StepNode.note``: the
  start or goal inside an obstacle's inflated zone, or the obstacles that close the way)
  and tries again every ``RETRY_S`` seconds; a goal from /goal_pose (NavigateToPose) is
  given up instead, as Nav2 aborts it: the node stops until a new goal. At load time a goal
  its map cannot reach is a warning (``world_warnings``).

Inputs: /odom and /scan (same_tick), optional /goal_pose (geometry_msgs/PoseStamped in odom:
a pose that differs from the current goal replaces it, reached or not; a zero quaternion
means stop: no goal, zero velocity until the next one; an empty frame_id, what an external
source holds before anything arrived, changes nothing). Outputs: /cmd_vel
(geometry_msgs/Twist, or TwistStamped in ``base_frame`` with ``enable_stamped_cmd_vel``,
Nav2's parameter of the same name: Jazzy's Nav2 publishes Twist by default, Kilted's
TwistStamped), /plan (frame odom). Its metrics tell a NavigateToPose server how the current
goal goes (``metrics``).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Path
from pydantic import BaseModel, ConfigDict, Field

from descriptions.robot_model import RobotModel
from descriptions.robot_needs import missing_sensor
from descriptions.robot_reader import RobotNames
from nodes.contract import StepNode, Tick, constant_message
from nodes.control import follow as f
from nodes.control.crowd import Crowd
from nodes.control.diagnose import connected, explain_no_path
from nodes.control.global_planner import Planner, path_message
from nodes.physics.world import body_id, load_model, named_id, robots_of
from plan.poses import pose_of
from plan.rot3 import mat_t_mul, mat_t_vec
from plan.timeutil import NS_PER_S

IDLE, ACTIVE, REACHED, FAILED = 0.0, 1.0, 2.0, 3.0  # metric nav_state
RETRY_S = 2.0  # s between plans while none exists (a failed plan searches the whole map)
ESCAPE_REACH = 0.2  # m of arc a creeping escape must find clear
ESCAPE_TURN = 0.25  # its sharpest arc turns at this fraction of max_turn at min_speed
SIDESTEP_ARCS = 11  # arcs in the fan a robot blocked by something unmapped chooses from
SIDESTEP_CURVATURE = 3.0  # 1/m: the fan's sharpest arc (at most max_turn at the speed)
SIDESTEP_GAIN = 0.05  # m nearer the target than the blocked arc gets, to step aside


class ControlParams(BaseModel):
    """Navigator settings; one block for every world (nothing here is tuned per world)."""

    model_config = ConfigDict(extra="forbid")
    base_body: str | None = Field(None, description="the robot's base body; default: the "
                                  "robot model's (descriptions.robot_reader)")
    laser_site: str | None = Field(None, description="the lidar's site; default: the robot "
                                   "model's")
    frame_id: str = Field("odom", description="the odometry frame (a swarm robot's prefixed)")
    base_frame: str | None = Field(None, description="frame of a stamped /cmd_vel; default: "
                                   "the robot model's base link")
    enable_stamped_cmd_vel: bool = Field(False, description="publish /cmd_vel as TwistStamped")
    robot_radius: float = Field(0.23, gt=0, description="m, circumscribed footprint; a URDF "
                                "robot's default: its footprint from its collision geometry")
    safety_margin: float = Field(0.04, ge=0, description="m added to the radius on the scan")
    tight_margin: float = Field(0.01, ge=0, description="m added to the radius on the scan "
                                "when creeping at min_speed where safety_margin blocks")
    resolution: float = Field(0.05, gt=0, description="m per map cell")
    lethal_distance: float = Field(0.30, gt=0, description="m, plan never closer to obstacles")
    cost_distance: float = Field(0.8, gt=0, description="m, extra cost closer than this")
    cost_weight: float = Field(6.0, ge=0)
    max_speed: float = Field(0.5, gt=0, description="m/s")
    min_speed: float = Field(0.06, gt=0, description="m/s while approaching the goal")
    max_turn: float = Field(1.5, gt=0, description="rad/s")
    lookahead: float = Field(0.6, gt=0, description="m")
    min_turn_radius: float = Field(0.7, gt=0, description="m, slower on sharper curves")
    rotate_threshold: float = Field(0.9, gt=0, description="rad, turn in place beyond this")
    turn_gain: float = Field(2.0, gt=0)
    approach_gain: float = Field(0.8, gt=0, description="v <= gain * distance to goal")
    stop_time: float = Field(0.8, gt=0, description="s, v <= free arc length / stop_time")
    horizon: float = Field(1.0, gt=0, description="m of arc checked against the scan")
    progress_window: float = Field(8.0, gt=0, description="s")
    progress_distance: float = Field(0.2, gt=0, description="m")
    backup_distance: float = Field(0.3, ge=0, description="m")
    backup_speed: float = Field(0.15, gt=0, description="m/s")
    crowd_range: float = Field(4.0, gt=0, description="m: with /cosim/world_state, the other "
                               "robots within this range count (nodes.control.crowd)")
    crowd_horizon: float = Field(2.0, gt=0, description="s: ORCA's time horizon among robots")
    crowd_static_horizon: float = Field(0.8, gt=0, description="s: ORCA's time horizon for "
                                        "static scan points")
    crowd_margin: float = Field(0.08, ge=0, description="m added to each robot's radius "
                                "among robots (what a differential drive cannot follow)")
    crowd_report_s: float = Field(20.0, gt=0, description="s held by the same robot before "
                                  "a note says by whom and where")


class ControlNode(StepNode):
    """Global A* plan, regulated pure pursuit, goal checking and recovery."""

    Params = ControlParams
    needs_world = True
    shares_inputs = True
    runtime_params = frozenset({
        "max_speed", "min_speed", "max_turn", "lookahead", "min_turn_radius",
        "rotate_threshold", "turn_gain", "approach_gain", "stop_time", "horizon",
        "tight_margin", "progress_window", "progress_distance", "backup_distance",
        "backup_speed"})  # read at every step; the map and planner's are fixed at set-up
    type_keys = {"/cmd_vel": "params.enable_stamped_cmd_vel"}

    @classmethod
    def outputs(cls, params: ControlParams) -> dict[str, type]:
        """Velocity command (Twist or TwistStamped) and the current global plan."""
        return {"/cmd_vel": TwistStamped if params.enable_stamped_cmd_vel else Twist,
                "/plan": Path}

    @classmethod
    def world_problems(cls, params: ControlParams, model, goal) -> list[tuple[str, str, str]]:
        """The goal is inside the world, clear of every obstacle by the robot's radius."""
        from descriptions.world_geometry import static_obstacles
        from plan.obstacles import place_problem

        if goal is None:
            return []
        problem = place_problem(static_obstacles(model), goal["x"], goal["y"],
                                params.robot_radius)
        if problem:
            return [("goal", f"the goal {problem}.",
                     "a goal inside the world where the robot fits clear of obstacles.")]
        return []

    @classmethod
    def world_warnings(cls, params: ControlParams, model, goal, start
                       ) -> list[tuple[str, str]]:
        """The goal cannot be reached on the static map from the start (from the robot's
        place in the world when no node sets a start): why, naming the obstacles."""
        if goal is None:
            return []
        if start is None:
            data = mujoco.MjData(model)
            mujoco.mj_kinematics(model, data)
            base = params.base_body or RobotNames().base_body
            start = dict(zip("xy", data.xpos[body_id(model, base), :2].tolist(), strict=True))
        planner = Planner(model, params)
        here, there = (start["x"], start["y"]), (goal["x"], goal["y"])
        if connected(planner, here, there):
            return []
        return [("goal", f"the controller's map has no way to the goal: "
                 f"{explain_no_path(planner, here, there)}")]

    @classmethod
    def accepted_inputs(cls, params: ControlParams) -> set[str]:
        """Odometry, the scan, an optional goal and the optional world state (the other
        robots of a swarm: ``nodes.control.crowd``)."""
        return {"/odom", "/scan", "/goal_pose", "/cosim/world_state"}

    @classmethod
    def description_names(cls, params: ControlParams) -> dict[str, Any]:
        """The base body and the lidar's site, where the parameters name them."""
        names = {"base_body": params.base_body, "laser_site": params.laser_site}
        return {key: value for key, value in names.items() if value is not None}

    @classmethod
    def robot_problems(cls, params: ControlParams, robot: RobotModel, model: Any
                       ) -> list[tuple[str, str, str]]:
        """The controller reads the lidar's mount off the robot: the robot needs one."""
        site = params.laser_site or RobotNames().laser_site
        return missing_sensor(robot, "lidar", "", site, "params.laser_site")

    def setup(self) -> None:
        """Build the map, read the laser mount from the world and take the scenario goal."""
        self.params = self._with_robot(self.params)
        p = self.params
        model = load_model(self.config.world, self.config.layout)
        layout = self.config.layout  # a robot that enters later: its mount in the world with it
        mounted = model if layout is None else load_model(self.config.world, layout.everyone)
        self.laser = _laser_mount(mounted, p.base_body, p.laser_site)
        self.planner = Planner(model, p)
        g = self.config.goal
        if g is None:
            raise ValueError("the control node needs the scenario's goal (x, y, yaw, ...)")
        self.goal = (float(g["x"]), float(g["y"]), float(g.get("yaw", 0.0)))
        self.pos_tol = float(g.get("position_tolerance", 0.25))
        self.yaw_tol = float(g.get("yaw_tolerance", 3.2))
        self.path: np.ndarray | None = None
        self.plan_msg = Path()
        self.plan_msg.header.frame_id = p.frame_id
        self.index = 0
        self.turning = False
        self.xy_reached = False
        self.reached_ns: int | None = None
        self.recovery: dict[str, Any] | None = None
        self.checkpoint: tuple[float, float, int] | None = None
        self.last_xy: tuple[float, float] | None = None
        self.path_length = 0.0
        self.min_clearance = math.inf
        self.points = np.zeros((0, 2))
        self.recoveries = 0
        self.retry_ns = 0  # no plan before this time (after a failed one)
        self.why_no_path: str | None = None  # the last failure's explanation, noted once
        self.active = True  # False after a stop request: no goal
        self.failed = False  # no path to a goal from outside: stopped until a new goal
        self.outside = False  # the goal came from /goal_pose
        self.pose: tuple[float, float, float] | None = None
        self.tail = np.zeros(0)  # path length from each plan point to its end
        self.crowd: Crowd | None = None  # made at the first /cosim/world_state

    def _with_robot(self, params: ControlParams) -> ControlParams:
        """The parameters with the robot's names as its model gives them: its base body,
        lidar site and base frame, the odometry frame in its namespace."""
        robots = robots_of(self.config, self.description_names(params))
        if len(robots) != 1:
            raise ValueError(f"the control node drives one robot; world {self.config.world} "
                             f"has {len(robots)}")
        robot = robots[0]
        lidar = robot.sensor("lidar")
        if lidar is None:
            raise ValueError(f"the robot of world {self.config.world} has no lidar site "
                             f"{params.laser_site or RobotNames().laser_site!r}")
        update = {
            "base_body": robot.base, "laser_site": lidar.mujoco_name,
            "frame_id": robot.frame_prefix + params.frame_id,
            "base_frame": robot.base_link if params.base_frame is None
            else robot.frame_prefix + params.base_frame}
        if robot.described and "robot_radius" not in params.model_fields_set:
            update["robot_radius"] = robot.footprint_radius  # a URDF's, from its collisions
        return params.model_copy(update=update)

    def set_params(self, params: ControlParams) -> None:
        """Take changed parameters; the robot's names stay as its model gives them."""
        self.params = params.model_copy(update={key: getattr(self.params, key) for key in
                                                ("base_body", "laser_site", "frame_id",
                                                 "base_frame")})

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """One control cycle: read odom and scan, then decide the velocity command."""
        odom = inputs.get("/odom")
        if odom is None:
            raise ValueError("the control node needs /odom at every activation (same_tick)")
        pose = self.pose = _pose(odom)
        world = inputs.get("/cosim/world_state")
        if world is not None and self.config.layout is not None:
            if self.crowd is None:
                self.crowd = Crowd.of(self.config, self.params, self.planner)
            self.crowd.update(world, tick.time_ns)
        self._account(pose, inputs.get("/scan"))
        self._maybe_new_goal(inputs.get("/goal_pose"), pose)
        v, w = self._decide(tick, pose)
        twist = Twist()
        twist.linear.x, twist.angular.z = float(v), float(w)
        cmd = twist
        if self.params.enable_stamped_cmd_vel:  # stamped with the tick's time by the runtime
            cmd = TwistStamped(twist=twist)
            cmd.header.frame_id = self.params.base_frame
        # the plan changes only when replanned (a new message): encoded once, then stamped
        return {"/cmd_vel": cmd, "/plan": constant_message(self.plan_msg)}

    # -- bookkeeping ------------------------------------------------------------------------

    def _account(self, pose: tuple[float, float, float], scan: Any) -> None:
        if self.last_xy is not None:
            self.path_length += math.hypot(pose[0] - self.last_xy[0], pose[1] - self.last_xy[1])
        self.last_xy = pose[:2]
        if scan is None:
            return
        ranges = np.frombuffer(scan.ranges, dtype=np.float32).astype(np.float64)
        valid = ranges[np.isfinite(ranges) & (ranges >= scan.range_min)
                       & (ranges <= scan.range_max)]
        if valid.size:
            self.min_clearance = min(self.min_clearance, float(valid.min()))
        self.points = f.scan_points(ranges, scan.angle_min, scan.angle_increment,
                                    scan.range_min, self.laser, pose)

    def _maybe_new_goal(self, msg: Any, pose: tuple[float, float, float]) -> None:
        # An external source holds a default message (no frame) until a goal arrives, then
        # publishes the latest one at every activation: only a change is a request.
        if msg is None or not msg.header.frame_id:
            return
        q = msg.pose.orientation
        if q.x == q.y == q.z == q.w == 0.0:  # stop
            if self.active:
                self.active, self.path, self.recovery = False, None, None
                self.plan_msg = path_message(None, self.params.frame_id, 0.0)
            return
        new = pose_of(msg.pose)
        if self.active and max(abs(a - b) for a, b in zip(new, self.goal, strict=True)) <= 1e-9:
            return
        self.goal, self.active, self.outside = new, True, True
        self.xy_reached, self.reached_ns, self.recovery = False, None, None
        self._replan(pose)
        self.failed = self.path is None  # no plan for a NavigateToPose goal: give up

    def _replan(self, pose: tuple[float, float, float], now_ns: int = 0) -> None:
        self.path = self.planner.plan(pose[:2], self.goal[:2])
        self.index = 0
        self.plan_msg = path_message(self.path, self.params.frame_id, self.goal[2])
        if self.path is not None:
            seg = np.hypot(np.diff(self.path[:, 0]), np.diff(self.path[:, 1]))
            self.tail = np.append(np.cumsum(seg[::-1])[::-1], 0.0)
            self.why_no_path = None
            return
        self.retry_ns = now_ns + round(RETRY_S * NS_PER_S)
        why = explain_no_path(self.planner, pose[:2], self.goal[:2])
        if why != self.why_no_path:
            self.note(f"{why} Standing still; trying again every {RETRY_S:g} s.")
            self.why_no_path = why

    # -- behaviour --------------------------------------------------------------------------

    def _decide(self, tick: Tick, pose: tuple[float, float, float]) -> tuple[float, float]:
        p = self.params
        if self.reached_ns is not None or not self.active or self.failed:
            return 0.0, 0.0
        dist = math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
        if not self.xy_reached and dist < 0.5 * self.pos_tol:
            self.xy_reached = True
        if self.xy_reached:
            err = f.wrap(self.goal[2] - pose[2])
            # Aim for half the heading tolerance so the stop lands well inside it.
            if abs(err) <= 0.5 * self.yaw_tol and dist <= self.pos_tol:
                self.reached_ns = tick.time_ns
                return 0.0, 0.0
            return 0.0, _turn(p.turn_gain * err, p.max_turn)
        if self.path is None and tick.time_ns >= self.retry_ns:
            self._replan(pose, tick.time_ns)
            if self.path is None and self.outside:  # a NavigateToPose goal: give up
                self.failed = True
                return 0.0, 0.0
        if self.recovery is not None:
            return self._recover(tick, pose)
        if self._stuck(tick, pose):
            self.recovery = {"start": pose[:2], "since": tick.time_ns}
            self.recoveries += 1
            return self._recover(tick, pose)
        if self.path is None or len(self.path) == 0:
            return 0.0, 0.0
        return self._pursue(pose, dist)

    def _pursue(self, pose: tuple[float, float, float], dist: float) -> tuple[float, float]:
        p = self.params
        self.index, target = f.lookahead_point(self.path, self.index, pose, p.lookahead)
        if self.crowd is not None and self.crowd.others.known:
            steered = self.crowd.steer(pose, target, dist, self.path, self.index, self.points,
                                       self.config.period_ns / NS_PER_S)
            if steered is not None:
                self.checkpoint = None  # robots hold it up: no recovery from them
                for text in self.crowd.notes():
                    self.note(text)
                if self.crowd.replan:  # robots parked at their goals in the way: round them
                    self.crowd.replan = False
                    self.planner.mark(self.crowd.parked_points())
                    self._replan(pose, self.crowd.now_ns)
                    return 0.0, 0.0
                return steered
        dx, dy = target[0] - pose[0], target[1] - pose[1]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        alpha = math.atan2(ly, lx)
        if abs(alpha) > p.rotate_threshold or (self.turning and abs(alpha) > 0.25):
            self.turning = True
            return 0.0, _turn(p.turn_gain * alpha, p.max_turn)
        self.turning = False
        curv = 2.0 * ly / max(lx * lx + ly * ly, 1e-6)
        v = p.max_speed
        if abs(curv) > 1.0 / p.min_turn_radius:
            v *= 1.0 / (abs(curv) * p.min_turn_radius)
        v = min(v, max(p.min_speed, p.approach_gain * dist))
        radius = p.robot_radius + p.safety_margin
        free = f.arc_clearance(self.points, pose, v, v * curv, p.horizon, radius)
        if free < p.horizon:
            curv, free = self._sidestep(pose, target, v, curv, free, radius)
        v = min(v, free / p.stop_time)
        if v < 0.02:
            return self._squeeze(pose, target, curv)
        return v, float(np.clip(v * curv, -p.max_turn, p.max_turn))

    def _sidestep(self, pose: tuple[float, float, float], target: np.ndarray, v: float,
                  curv: float, free: float, radius: float) -> tuple[float, float]:
        """(curvature, clear length) to drive: the pursuit arc's, unless only points the
        map does not explain block it; then the arc of the fan that gets nearest the target
        (by at least SIDESTEP_GAIN more than the blocked one), the rightmost among equals."""
        p = self.params
        unmapped = self._unmapped(self.points)
        if not unmapped.any():
            return curv, free
        if f.arc_clearance(self.points[~unmapped], pose, v, v * curv, p.horizon,
                           radius) < p.horizon:
            return curv, free  # the map's own obstacles block it: pursuit handles those
        here = math.hypot(target[0] - pose[0], target[1] - pose[1])

        def gain(k: float, reach: float) -> float:
            x, y = f.arc_end(pose, k, reach)
            return here - math.hypot(target[0] - x, target[1] - y)

        best_k, best_reach = curv, free
        best = gain(curv, free) + SIDESTEP_GAIN
        sharpest = min(SIDESTEP_CURVATURE, p.max_turn / v)
        fan = np.linspace(-sharpest, sharpest, SIDESTEP_ARCS).tolist()
        reaches = f.arc_clearances(self.points, pose, v, [v * k for k in fan], p.horizon, radius)
        for k, reach in zip(fan, reaches, strict=True):
            score = gain(k, reach)
            if score > best:
                best, best_k, best_reach = score, k, reach
        return best_k, best_reach

    def _unmapped(self, points: np.ndarray) -> np.ndarray:
        """Which scan points the static map does not explain (farther than two cells from
        its obstacles, as a recovery marks them)."""
        g = self.planner.grid
        nx, ny = self.planner.static_dist.shape
        i = np.clip(np.floor((points[:, 0] - g.origin[0]) / g.res).astype(np.int64), 0, nx - 1)
        j = np.clip(np.floor((points[:, 1] - g.origin[1]) / g.res).astype(np.int64), 0, ny - 1)
        return self.planner.static_dist[i, j] > 2 * g.res

    def _squeeze(self, pose: tuple[float, float, float], target: np.ndarray, curv: float
                 ) -> tuple[float, float]:
        """Blocked at the safety margin (a narrow passage the plan goes through): creep at
        min_speed with the tight margin, on the pursuit arc or else the clear arc that ends
        nearest the target; stand still when every arc is blocked."""
        p = self.params
        v, radius = p.min_speed, p.robot_radius + p.tight_margin
        free = f.arc_clearance(self.points, pose, v, v * curv, p.horizon, radius)
        if free / p.stop_time < 0.02:
            curv = f.escape_arc(self.points, pose, target, v, radius, ESCAPE_REACH,
                                ESCAPE_TURN * p.max_turn / p.min_speed)
            if curv is None:
                return 0.0, 0.0
            free = ESCAPE_REACH
        v = max(min(v, free / p.stop_time), 0.02)
        return v, float(np.clip(v * curv, -p.max_turn, p.max_turn))

    def _stuck(self, tick: Tick, pose: tuple[float, float, float]) -> bool:
        p = self.params
        cp = self.checkpoint
        if cp is None or math.hypot(pose[0] - cp[0], pose[1] - cp[1]) > p.progress_distance:
            self.checkpoint = (pose[0], pose[1], tick.time_ns)
            return False
        if tick.time_ns - self.checkpoint[2] > round(p.progress_window * NS_PER_S):
            self.checkpoint = (pose[0], pose[1], tick.time_ns)
            return True
        return False

    def _recover(self, tick: Tick, pose: tuple[float, float, float]) -> tuple[float, float]:
        """Back up (while the scan behind is clear, at most ~3 s), then replan with the scan."""
        p = self.params
        r = self.recovery
        moved = math.hypot(pose[0] - r["start"][0], pose[1] - r["start"][1])
        elapsed = tick.time_ns - r["since"]
        free = f.arc_clearance(self.points, pose, -p.backup_speed, 0.0, 0.3,
                               p.robot_radius + p.safety_margin)
        if moved < p.backup_distance and elapsed < 3 * NS_PER_S and free >= 0.1:
            return -p.backup_speed, 0.0
        self.recovery = None
        points = self.points
        if self.crowd is not None and self.crowd.others.known:  # robots move: not the map's
            points = points[~self.crowd.robot_points(points, self.crowd.around(pose))]
        self.planner.mark(points)
        self._replan(pose, tick.time_ns)
        return 0.0, 0.0

    def metrics(self) -> dict[str, float]:
        """goal_reached (latched until a new goal), time_to_goal (s, -1 before),
        path_length, min_clearance, recoveries; and for a NavigateToPose server: nav_state
        (0 idle, 1 active, 2 reached, 3 failed: no path), the pose (nav_x, nav_y, nav_yaw),
        the goal (nav_goal_x, nav_goal_y, nav_goal_yaw), nav_distance_remaining (m along
        the plan)."""
        done = self.reached_ns is not None and self.active
        out = {"goal_reached": 1.0 if done else 0.0,
               "time_to_goal": self.reached_ns / NS_PER_S if done else -1.0,
               "path_length": self.path_length,
               "min_clearance": self.min_clearance if math.isfinite(self.min_clearance) else -1.0,
               "recoveries": float(self.recoveries)}
        if self.crowd is not None:
            out.update(self.crowd.metrics())
        if self.pose is None:
            return out
        state = (IDLE if not self.active else REACHED if done else FAILED if self.failed
                 else ACTIVE)
        x, y, yaw = self.pose
        out.update(nav_state=state, nav_x=x, nav_y=y, nav_yaw=yaw, nav_goal_x=self.goal[0],
                   nav_goal_y=self.goal[1], nav_goal_yaw=self.goal[2],
                   nav_distance_remaining=self._remaining(self.pose))
        return out

    def _remaining(self, pose: tuple[float, float, float]) -> float:
        """Distance left along the plan from its point nearest the robot (straight to the
        goal without a plan)."""
        if self.path is None or len(self.path) == 0:
            return math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
        ahead = self.path[self.index:]
        d = np.hypot(ahead[:, 0] - pose[0], ahead[:, 1] - pose[1])
        i = int(np.argmin(d))
        return float(d[i] + self.tail[self.index + i])


def _turn(w: float, limit: float, floor: float = 0.25) -> float:
    """An in-place turn rate: clipped to ``limit`` and at least ``floor`` in magnitude."""
    w = max(-limit, min(limit, w))
    return math.copysign(max(abs(w), floor), w)


def _pose(odom: Any) -> tuple[float, float, float]:
    return pose_of(odom.pose.pose)


_POSED: dict[int, tuple] = {}  # id(model) -> (model, its data at the default pose)


def _posed(model: mujoco.MjModel) -> mujoco.MjData:
    """The model's data at its default pose (kinematics only), one per model: a swarm's
    controllers share one model, and this is a whole swarm's worth of bodies."""
    found = _POSED.get(id(model))
    if found is None or found[0] is not model:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        _POSED.clear()  # keep only the latest model alive
        found = _POSED[id(model)] = (model, data)
    return found[1]


def _laser_mount(model: mujoco.MjModel, base: str, site: str) -> tuple[float, float, float]:
    """(x, y, yaw) of the laser site in the base body's frame, from the MJCF."""
    data = _posed(model)
    b = body_id(model, base)
    s = named_id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    rel = mat_t_vec(data.xmat[b], data.site_xpos[s] - data.xpos[b])
    rs = mat_t_mul(data.xmat[b], data.site_xmat[s])
    return rel[0], rel[1], math.atan2(rs[1][0], rs[0][0])
