"""The typed scenario model: what a scenario YAML file may contain (unknown keys are refused)."""

from __future__ import annotations

from fractions import Fraction
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

from plan.description_spec import UrdfSpec, UsdSpec
from plan.events import EventSpec
from plan.spawnables import Spawnable
from plan.timeutil import parse_duration_ns, rate_to_period_ns

DurationNs = Annotated[int, BeforeValidator(parse_duration_ns)]
"""A duration given as '30s', '10ms', '250us', '100ns' or seconds, held as integer ns."""

PeriodNs = Annotated[int | Fraction, BeforeValidator(rate_to_period_ns)]
"""A rate given in Hz, held as its exact period in ns (a Fraction where not whole: 30 Hz)."""

RATE_HELP = ("a rate in Hz greater than zero whose period is a whole number of ticks, e.g. "
             "10, 15, 30, 50, 100")
DURATION_HELP = "a duration greater than zero such as '30s', '10ms', '250us' or 30"
TICK_HELP = ("; default: the gcd of the periods, exact even where not whole ns (30 Hz with "
             "50 Hz: 1/150 s); tick k is at k * tick rounded half up to whole ns, once, and "
             "/clock and every header stamp carry that time (a 30 Hz message n: "
             "round(n * 1e9 / 30) ns, so 0, 33333333, 66666667, 100000000, ...)")

Name = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
Topic = Annotated[str, Field(pattern=r"^/[A-Za-z0-9_/]*[A-Za-z0-9_]$")]


class Strict(BaseModel):
    """Base of every scenario section: unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class InputSpec(Strict):
    """One input edge: the topic a node consumes and whether it waits for this tick's sample."""

    topic: Topic = Field(description="a ROS 2 topic name such as /scan")
    mode: Literal["same_tick", "delayed"] = Field(
        description="same_tick (wait for this tick's sample) or delayed (use the previous one)")


class DebugSpec(Strict):
    """Test-only runtime knobs that must never change an output."""

    step_delay: DurationNs | None = Field(None, description=DURATION_HELP)


class NodeSpec(Strict):
    """One node: what runs (kind or module), how often, its parameters, inputs and remaps."""

    name: Name = Field(description="letters, digits and _, starting with a letter")
    kind: str | None = Field(None, description="a built-in node kind (physics, sensors, "
                             "control, ...); one of kind, module and command")
    module: str | None = Field(None, description="your own step class as 'package.module:Class' "
                               "(a subclass of nodes.contract.StepNode)")
    period_ns: PeriodNs = Field(alias="rate", description=RATE_HELP)  # given as a rate in Hz
    params: dict[str, Any] = Field(default_factory=dict, description="a mapping: the kind's "
                                   "parameters, checked against its Params model")
    inputs: list[InputSpec] = Field(default_factory=list, description="a list of {topic, mode}: "
                                    "the topics this node consumes (the schedule's edges)")
    remap: dict[Topic, Topic] = Field(default_factory=dict, description="a mapping: topic the "
                                      "node knows -> topic it uses in this run, e.g. "
                                      "{/cmd_vel: /robot1/cmd_vel}")
    debug: DebugSpec = Field(default_factory=DebugSpec, description="a mapping of test-only knobs")
    command: list[str] | None = Field(None, min_length=1, description="a foreign ROS 2 "
                                      "program: [program, args...], run from the scenario's "
                                      "directory with use_sim_time")
    external: bool = Field(False, description="true: not spawned; you start it with "
                           "'cosim-node KIND --scenario FILE --node NAME --lockstep'")
    process: Name | None = Field(None, description="nodes with the same process name share "
                                 "one OS process (one transport session, one wait); the "
                                 "result is the same whatever the packing")
    prefix: str | None = Field(None, description="a command that wraps the node's process, "
                               "like ros2 launch's prefix, e.g. 'gdb -ex run --args' or "
                               "'valgrind'; it must exec the node (keep its pid)")
    for_each: Literal["robot"] | None = Field(None, description="robot: one instance of this "
                                              "node per robot of the robots: section, named "
                                              "NAME@ROBOT, its topics under the robot's "
                                              "namespace (/ROBOT/; a lone robot's at the root)")
    robots: list[Name] | None = Field(None, min_length=1, description="with for_each: only "
                                      "these robots (default: every robot)")


class GoalSpec(Strict):
    """Where the robot must get to, and how close counts."""

    x: float = Field(description="a number, in metres")
    y: float = Field(description="a number, in metres")
    yaw: float = Field(0.0, description="a number, in radians")
    position_tolerance: float = Field(0.25, gt=0, description="a number > 0: metres "
                                      "from the goal that count as reached")
    yaw_tolerance: float = Field(3.2, gt=0, description="a number > 0: radians "
                                 "from the goal's yaw that count (the default, over pi, ignores "
                                 "the heading)")


class JointGoalSpec(Strict):
    """Where a robot's joints must get to (an arm's last target), and how close counts."""

    positions: dict[str, float] = Field(min_length=1, description="joint name -> position "
                                        "(rad for a hinge), e.g. {elbow: 1.2}")
    tolerance: float = Field(0.05, gt=0, description="largest error of any joint (rad)")
    speed_tolerance: float = Field(0.1, gt=0, description="largest speed of any of these "
                                   "joints (rad/s): reached means there and settling")


class Region(Strict):
    """An axis-aligned rectangle of the floor: x and y ranges in metres."""

    x: tuple[float, float] = Field(description="[min, max], two numbers in metres")
    y: tuple[float, float] = Field(description="[min, max], two numbers in metres")


class PlanarPose(Strict):
    """A position in metres and a heading in radians."""

    x: float = Field(description="a number, in metres")
    y: float = Field(description="a number, in metres")
    yaw: float = Field(0.0, description="a number, in radians")


class NamedRobot(Strict):
    """One robot of a robots: list: its name, its namespace, start pose and goal."""

    name: Name = Field(description="letters, digits and _; the robot's name (and its "
                       "namespace when it has one)")
    namespace: Name | None = Field(None, description="the robot's ROS namespace and TF frame "
                                   "prefix (/NS/cmd_vel, NS/base_link); default: its name when "
                                   "the section has several robots, none when it has one (the "
                                   "root: /cmd_vel, base_link, as robot_state_publisher)")
    start: PlanarPose | None = Field(None, description="where it starts; in a USD stage "
                                     "with robot prims, the prim named so places it instead")
    goal: PlanarPose = Field(description="where it must get to")


class RobotsSpec(Strict):
    """Many robots from one description in one world (plan/robots.py): either ``count``
    robots placed by the scenario seed in ``region`` (goals in ``goal_region``, or the
    start mirrored through the region's centre), or ``named`` robots, each with its start
    and goal."""

    description: str | None = Field(None, description="the MJCF, URDF, xacro or USD of one robot "
                                    "(like worlds/robot.xml), relative to this file; each robot's "
                                    "topics and frames get its namespace (several robots, or one "
                                    "with named[].namespace); default: the one a USD stage's "
                                    "robot prims name (cosim:robot:mjcf)")
    base_body: str = Field("base_link", description="the robot's root body in the description")
    urdf: UrdfSpec | None = Field(None, description="how a URDF or xacro description is read "
                                  "(xacro args, packages, wheels, sensors, ...; "
                                  "docs/tutorials/own-robot.md)")
    usd: UsdSpec | None = Field(None, description="how a USD robot description (.usd, .usda, "
                                ".usdc with UsdPhysics bodies and joints) is read (base, "
                                "wheels, sensors, interfaces, gains; docs/how-to/usd-robots.md)")
    count: int | None = Field(None, ge=1, le=1024, description="this many robots, placed by "
                              "the scenario seed in region (instead of named)")
    name_prefix: Name = Field("robot", description="count: robots are named PREFIX_0, ...")
    region: Region | None = Field(None, description="count: where the robots start")
    goal_region: Region | None = Field(None, description="count: where their goals are; "
                                       "default: each start mirrored through region's centre")
    clearance: float = Field(0.8, gt=0, description="count: least distance in metres between "
                             "two robots' starts (and two goals)")
    named: list[NamedRobot] | None = Field(None, min_length=1, description="robots by name, "
                                           "each with its start and goal (instead of count)")
    position_tolerance: float = Field(0.3, gt=0, description="m from its goal that counts "
                                      "as reached")
    yaw_tolerance: float = Field(3.2, gt=0, description="a number > 0: radians "
                                 "from its goal's yaw that count")
    success_fraction: float = Field(1.0, gt=0, le=1, description="the fraction of robots that "
                                    "must reach their goals for the run to succeed")
    controllers: str | Literal[False] | None = Field(
        None, description="a ros2_control controllers file (controller_manager: "
        "ros__parameters: ...), relative to this file: every robot gets its controller manager "
        "from it, a node controller_manager (for_each: robot) at the file's update_rate, "
        "wired to physics by cosim; default: the file(s) a URDF description's "
        "gz_ros2_control plugin tag names (its parameters elements), if any; false: no "
        "controller manager, whatever the description names (the robots driven on cmd_vel "
        "and joint_commands)")


class SuccessSpec(Strict):
    """What a successful run means: goal reached (if a goal is given) and few enough collisions."""

    reach_goal: bool = Field(True, description="true or false: success "
                             "needs the goal reached (when the scenario has one)")
    max_collisions: int = Field(0, ge=0, description="a whole number >= 0: the "
                                 "most collisions a successful run may have")
    stop_on_goal: bool = Field(True, description="true or false: end the "
                               "run at the tick the goal is reached")


class DeadlineSpec(Strict):
    """How long to wait for every node to be ready, and for every due node to finish a tick."""

    start: DurationNs = Field(30_000_000_000, description=DURATION_HELP)
    tick: DurationNs = Field(10_000_000_000, description=DURATION_HELP)


class ZenohSpec(Strict):
    """Where the zenoh transport's sessions meet (used only with ``transport: zenoh``)."""

    listen: list[str] = Field(
        default_factory=list,
        description="zenoh endpoints the orchestrator's router listens on and its nodes connect "
                    "to, e.g. ['tcp/10.0.0.1:7447']; default tcp/127.0.0.1 on a free port")
    connect: list[str] = Field(
        default_factory=list,
        description="zenoh endpoints the orchestrator's router also connects to (e.g. a zenohd)")
    mirror_to_dds: list[Topic] = Field(
        default_factory=list,
        description="topics the orchestrator republishes on ROS 2 (DDS) for ros2 tools")


class ExternalSpec(Strict):
    """Topics that enter the run from outside (an action client, a rosbridge client, a
    real robot) at tick boundaries, recorded so the run replays: an orchestrator-owned node
    named ``external`` publishes, at ``rate``, the latest message received on each topic."""

    period_ns: PeriodNs = Field(alias="rate", description=RATE_HELP)  # given as a rate in Hz
    topics: dict[Topic, str] = Field(min_length=1, description="topic -> message type, e.g. "
                                     "{/goal_pose: geometry_msgs/msg/PoseStamped}")


class TwinSpec(Strict):
    """A digital twin (plan/twin.py): the run connects to a real robot's rosbridge server,
    is paced on the wall clock, takes the robot's topics in through the external node and
    sends chosen run topics back."""

    url: str | None = Field(None, description="ws://HOST:PORT of the robot's rosbridge server "
                            "(--twin overrides it)")
    subscribe: dict[Topic, Topic] = Field(min_length=1, description="robot topic -> the run's "
                                          "external topic it enters as, e.g. "
                                          "{/odom: /real/odom}")
    publish: dict[Topic, Topic] = Field(default_factory=dict, description="run topic -> the "
                                        "robot topic it is sent back as, e.g. "
                                        "{/scan: /twin/scan}")
    stale_after: DurationNs = Field(500_000_000, description="a robot topic with nothing new "
                                    "for this long is stale, e.g. '500ms'")
    reconnect_max: DurationNs = Field(5_000_000_000, description="the longest wait between "
                                      "two tries to reach the robot (backoff), e.g. '5s'")


class SimulationInterfacesSpec(Strict):
    """Where a run serves simulation_interfaces (ros2 runs, multi-process)."""

    namespace: str = Field(
        "", pattern=r"^(/?|(/[A-Za-z][A-Za-z0-9_]*)+/?)$",
        description="'' (the root: /get_simulator_features, /step_simulation, ..., as Isaac "
                    "Sim and O3DE serve them) or a namespace such as /cosim "
                    "(/cosim/step_simulation, as Gazebo serves them under /gzserver)")


class ScenarioModel(Strict):
    """A whole scenario file."""

    name: Name = Field(description="letters, digits and _, starting with a letter")
    seed: int = Field(0, ge=0, description="a whole number >= 0")
    duration: DurationNs = Field(description=DURATION_HELP)
    tick: DurationNs | None = Field(None, description=DURATION_HELP + TICK_HELP)
    transport: Literal["ros2", "zenoh"] = Field("ros2", description="ros2 or zenoh")
    zenoh: ZenohSpec = Field(default_factory=ZenohSpec)
    world: str | None = Field(None, description="path of the world file, relative to this file")
    goal: GoalSpec | None = None
    joint_goal: JointGoalSpec | None = None
    robots: RobotsSpec | None = Field(None, description="many robots (plan/robots.py)")
    success: SuccessSpec = Field(default_factory=SuccessSpec)
    deadlines: DeadlineSpec = Field(default_factory=DeadlineSpec)
    external: ExternalSpec | None = None
    interactive: bool = Field(False, description="true: ROS 2 clients may change the run "
                              "(NavigateToPose goals, SetEntityState, parameter sets); each "
                              "change enters at a tick boundary through the external node "
                              "and is recorded (see plan/interactive.py)")
    twin: TwinSpec | None = None
    simulation_interfaces: SimulationInterfacesSpec = Field(
        default_factory=SimulationInterfacesSpec)
    nodes: list[NodeSpec] = Field(min_length=1)
    events: list[EventSpec] = Field(default_factory=list, description="objects that enter "
                                    "and leave the running world at given times, e.g. "
                                    "[{at: 5s, spawn: {name: box1, shape: box, size: [0.3, "
                                    "0.3, 0.5], pose: {x: 1, y: 0}}}, {at: 8s, delete: box1}] "
                                    "(plan/events.py)")
    spawnables: list[Spawnable] = Field(default_factory=list, description="what clients may "
                                        "spawn, as GetSpawnables lists it: files and folders "
                                        "relative to this file, each a path or {path, "
                                        "description}, e.g. [models/, {path: "
                                        "robots/bot.urdf, description: a second robot}]")

    @property
    def has_goal(self) -> bool:
        """Whether the run has a goal to reach: a pose (``goal``) or joint positions."""
        return (self.goal is not None or self.joint_goal is not None
                or self.robots is not None)
