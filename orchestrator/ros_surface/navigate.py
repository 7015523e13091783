"""The NavigateToPose action server (``/navigate_to_pose``) of an interactive run.

A goal (geometry_msgs/PoseStamped in ``map`` or ``odom``: one frame here, odometry is
ground truth) is put into the run's external arrivals as /goal_pose: it enters at the
external node's next activation and is recorded like any message. The navigation node (the
one that takes /goal_pose, cosim's control node) tells how the goal goes in the metrics of
every activation (``nav_state``, its pose, its goal, the distance left, recoveries); the
server follows them tick by tick in the order the master decides them:

- feedback at every activation of the navigation node while it works on this goal, with
  ``estimated_time_remaining`` as Nav2's navigator computes it: the distance left over the
  robot's speed, when it moves faster than 1 cm/s with more than 10 cm to go (zero
  otherwise); the speed is the robot's travel over the last 0.3 s of reports, as Nav2
  smooths odometry over 0.3 s;
- succeeded when the node reports this goal reached;
- aborted when the node finds no path (the robot is then stopped), when a newer goal
  replaces it, when the run is reset or ends;
- cancelled: a stop request (/goal_pose with a zero quaternion) enters like a goal, and the
  goal is cancelled once the node reports that it stopped.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque

from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.qos import QoSProfile

from orchestrator.ros_surface.local_goals import LocalAction
from orchestrator.ros_surface.simcontrol import RunControl
from plan.poses import pose_of
from plan.timeutil import NS_PER_S, Ns, tick_time_ns
from runtime.arrivals import Arrivals

FRAMES = ("map", "odom")
UNKNOWN, TF_ERROR = 9000, 9002  # Nav2's error codes (named in the action after Jazzy)
IDLE, ACTIVE, REACHED, FAILED = 0.0, 1.0, 2.0, 3.0  # the control node's nav_state
SAME = 1e-6  # how close the node's goal must be to this one to be it
WAIT_S = 0.1
FEEDBACK_DEPTH = 100  # feedback comes in bursts when the run goes faster than real time
SPEED_WINDOW_NS = 300_000_000  # Nav2's odometry smoother's default window
MIN_SPEED, MIN_DISTANCE = 0.01, 0.1  # Nav2: below these, no estimate (zero)

log = logging.getLogger("cosim")


class NavigateServer:
    """Goals in, the navigation node's reports out as feedback and results.

    What a goal or a cancel puts into the run is put before the client hears that it was
    accepted, so a client that asks while the run is paused knows the tick it enters at."""

    def __init__(self, node, group, control: RunControl, arrivals: Arrivals, navigator: str,
                 goal_topic: str, tick_ns: Ns, counted=None):
        self.control = control
        self.arrivals = arrivals
        self.navigator = navigator
        self.goal_topic = goal_topic
        self.tick_ns = tick_ns
        self._cond = threading.Condition()
        self._reports: deque[tuple[int, int, dict[str, float]]] = deque(maxlen=4096)
        self._seq = 0
        self._latest = None  # the request of the newest goal put into the run
        self._put_at: dict[int, int] = {}  # id of a goal request -> _seq when it was put
        self._stopped: dict[int, int] = {}  # id of a cancelled request -> _seq at its stop
        # ``counted``: the services' wrapper that makes the end of the run wait for a goal
        execute = counted(self._execute) if counted else self._execute
        self.server = ActionServer(node, NavigateToPose, "/navigate_to_pose", execute,
                                   callback_group=group, goal_callback=self._on_goal,
                                   cancel_callback=self._on_cancel,
                                   feedback_pub_qos_profile=QoSProfile(depth=FEEDBACK_DEPTH))
        control.observers.append(self._observe)

    def local_action(self) -> LocalAction:
        """This server's callbacks, for goals from the live endpoints."""
        return LocalAction(NavigateToPose, self._on_goal, self._execute, self._on_cancel)

    def _observe(self, tick: int, reports: dict) -> None:
        """The master decided ``tick``: keep the navigation node's report of it."""
        done = reports.get(self.navigator)
        if done is None or "nav_state" not in done.metrics:
            return
        with self._cond:
            self._seq += 1
            self._reports.append((self._seq, tick, done.metrics))
            self._cond.notify_all()

    def _on_goal(self, request) -> GoalResponse:
        """Accept every goal; put a valid one into the run (a goal that cannot be taken is
        aborted with the reason once it executes)."""
        if goal_problem(request.pose) is None:
            msg = PoseStamped()
            msg.header.frame_id = "odom"
            msg.pose = request.pose.pose
            with self._cond:
                self._latest = request
                self._put_at[id(request)] = self._seq
                self.arrivals.put(self.goal_topic, msg)
            log.info("NavigateToPose: goal (%g, %g, %g) from %s", *pose_of(request.pose.pose),
                     self.control.at())
        return GoalResponse.ACCEPT

    def _on_cancel(self, handle) -> CancelResponse:
        """Accept; stop the robot when the goal is the one it is working on: /goal_pose
        with a zero quaternion, the control node's 'no goal'."""
        with self._cond:
            if handle.request is self._latest:
                msg = PoseStamped()
                msg.header.frame_id = "odom"
                msg.pose.orientation.w = 0.0
                self.arrivals.put(self.goal_topic, msg)
                self._stopped[id(handle.request)] = self._seq
                log.info("NavigateToPose: cancel from %s", self.control.at())
        return CancelResponse.ACCEPT

    def _execute(self, handle) -> NavigateToPose.Result:
        request = handle.request
        problem = goal_problem(request.pose)
        if problem:
            return _finish(handle, "abort", *problem)
        goal = pose_of(request.pose.pose)
        with self._cond:
            seen, epoch = self._put_at.pop(id(request)), self.control.epoch
        started = recoveries = None
        track: deque[tuple[int, float, float]] = deque()  # (tick, x, y) of this goal
        while True:
            # read before the reports: a run's last reports come before its end or reset
            run_over, epoch_now = self.control.ended, self.control.epoch
            with self._cond:
                if self._seq == seen:
                    self._cond.wait(WAIT_S)
                fresh = [r for r in self._reports if r[0] > seen]
                seen = fresh[-1][0] if fresh else seen
                replaced = self._latest is not request
                stopping = self._stopped.get(id(request))
            for seq, tick, m in fresh:
                if stopping is not None:
                    if seq > stopping and m["nav_state"] == IDLE:
                        return _finish(handle, "canceled", 0, "cancelled: the robot stopped")
                    continue
                if not same_goal(m, goal):
                    continue
                if started is None:
                    started, recoveries = tick, m.get("recoveries", 0.0)
                track.append((tick, m["nav_x"], m["nav_y"]))
                handle.publish_feedback(self._feedback(tick, started, recoveries, m,
                                                       self._speed(track)))
                if m["nav_state"] == REACHED:
                    return _finish(handle, "succeed", 0, "")
                if m["nav_state"] == FAILED:
                    return _finish(handle, "abort", UNKNOWN, "no path to the goal; the robot "
                                   "stopped")
            how = "canceled" if handle.is_cancel_requested else "abort"
            if replaced:
                return _finish(handle, how, UNKNOWN, "replaced by a newer goal")
            if epoch_now != epoch:
                return _finish(handle, how, UNKNOWN, "the run was reset")
            if run_over is not None:
                return _finish(handle, how, UNKNOWN, f"the run ended: {run_over}")

    def _speed(self, track: deque[tuple[int, float, float]]) -> float:
        """The robot's speed (m/s): its travel from the oldest report within the last
        0.3 s (at least the previous one) to the newest; drops older reports."""
        now = track[-1][0]
        while len(track) > 2 and self._ns(now) - self._ns(track[1][0]) >= SPEED_WINDOW_NS:
            track.popleft()
        (t0, x0, y0), (t1, x1, y1) = track[0], track[-1]
        if t1 == t0:
            return 0.0
        return math.hypot(x1 - x0, y1 - y0) / ((self._ns(t1) - self._ns(t0)) / 1e9)

    def _ns(self, tick: int) -> int:
        return tick_time_ns(tick, self.tick_ns)

    def _feedback(self, tick: int, started: int, recoveries: float,
                  m: dict[str, float], speed: float) -> NavigateToPose.Feedback:
        fb = NavigateToPose.Feedback()
        pose = fb.current_pose
        pose.header.frame_id = "odom"
        pose.header.stamp.sec, pose.header.stamp.nanosec = divmod(self._ns(tick), NS_PER_S)
        pose.pose.position.x, pose.pose.position.y = m["nav_x"], m["nav_y"]
        pose.pose.orientation.z = math.sin(m["nav_yaw"] / 2)
        pose.pose.orientation.w = math.cos(m["nav_yaw"] / 2)
        elapsed = self._ns(tick) - self._ns(started)
        fb.navigation_time.sec, fb.navigation_time.nanosec = divmod(elapsed, NS_PER_S)
        fb.number_of_recoveries = int(m.get("recoveries", 0.0) - recoveries)
        fb.distance_remaining = float(m["nav_distance_remaining"])
        if speed > MIN_SPEED and fb.distance_remaining > MIN_DISTANCE:
            eta = round(fb.distance_remaining / speed * 1e9)
            fb.estimated_time_remaining.sec, fb.estimated_time_remaining.nanosec = divmod(
                eta, 10**9)
        return fb


def goal_problem(goal: PoseStamped) -> tuple[int, str] | None:
    """(error code, why) a goal cannot be taken, or None."""
    if goal.header.frame_id not in FRAMES:
        return TF_ERROR, (f"goal frame {goal.header.frame_id!r} is unknown: cosim has map and "
                          "odom (the same frame)")
    p, q = goal.pose.position, goal.pose.orientation
    if not all(map(math.isfinite, (p.x, p.y, p.z, q.x, q.y, q.z, q.w))):
        return UNKNOWN, "the goal pose is not finite"
    if q.x == q.y == q.z == q.w == 0.0:
        return UNKNOWN, "the goal's quaternion is zero: no orientation"
    return None


def same_goal(m: dict[str, float], goal: tuple[float, float, float]) -> bool:
    """Whether the navigation node's report is about ``goal``."""
    if m.get("nav_state", IDLE) == IDLE:
        return False
    dyaw = (m["nav_goal_yaw"] - goal[2] + math.pi) % (2 * math.pi) - math.pi
    return (abs(m["nav_goal_x"] - goal[0]) <= SAME and abs(m["nav_goal_y"] - goal[1]) <= SAME
            and abs(dyaw) <= SAME)


def _finish(handle, how: str, code: int, text: str) -> NavigateToPose.Result:
    log.info("NavigateToPose: %s %s", how, text)
    getattr(handle, how)()
    return NavigateToPose.Result(error_code=code, error_msg=text)


