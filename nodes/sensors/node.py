"""The sensors node: lidar (LaserScan), 3D lidar (PointCloud2) and RGB-D camera.

Each instance runs the sensors its parameters name, so a scenario can run the lidar and the
camera as two nodes at different rates. The node mirrors the physics world: it loads the
same MJCF and, every activation, copies qpos from /cosim/world_state (a same_tick input).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, model_validator
from sensor_msgs.msg import CameraInfo, Image, LaserScan, PointCloud2

from descriptions.robot_model import RobotModel, Sensor
from descriptions.robot_needs import missing_sensor
from descriptions.robot_reader import RobotNames
from nodes.contract import StepNode, Tick
from nodes.physics.world import robots_of, swarm_of
from nodes.sensors.camera import COLOR_TOPIC, DEPTH_TOPIC, INFO_TOPIC, CameraParams, RgbdCamera
from nodes.sensors.lidar import Lidar2D, Lidar3D, LidarParams, PointCloudParams
from nodes.sensors.mirror import WorldMirror
from nodes.sensors.others import OtherRobots, StaticWorld

WORLD_STATE = "/cosim/world_state"


class SensorsParams(BaseModel):
    """Which sensors this instance runs (at least one), each with its own settings."""

    model_config = ConfigDict(extra="forbid")
    lidar: LidarParams | None = None
    point_cloud: PointCloudParams | None = None
    camera: CameraParams | None = None

    @model_validator(mode="after")
    def _one_sensor(self) -> SensorsParams:
        if self.lidar is None and self.point_cloud is None and self.camera is None:
            raise ValueError("give at least one of lidar, point_cloud, camera")
        return self


class SensorsNode(StepNode):
    """Ray-cast lidars and a rendered camera over a kinematic mirror of the world."""

    Params = SensorsParams
    needs_world = True
    shares_inputs = True  # the world state 64 lidars of a process read: decoded once

    @classmethod
    def outputs(cls, params: SensorsParams) -> dict[str, type]:
        """/scan, /point_cloud and the camera topics, for the sensors that are configured."""
        out: dict[str, type] = {}
        if params.lidar is not None:
            out["/scan"] = LaserScan
        if params.point_cloud is not None:
            out["/point_cloud"] = PointCloud2
        if params.camera is not None:
            out[COLOR_TOPIC] = Image
            if params.camera.depth:
                out[DEPTH_TOPIC] = Image
            out[INFO_TOPIC] = CameraInfo
        return out

    @classmethod
    def rendered_outputs(cls, params: SensorsParams) -> frozenset[str]:
        """The camera's colour and depth images (its CameraInfo is not rendered)."""
        if params.camera is None:
            return frozenset()
        return frozenset({COLOR_TOPIC, DEPTH_TOPIC} if params.camera.depth else {COLOR_TOPIC})

    @classmethod
    def accepted_inputs(cls, params: SensorsParams) -> set[str]:
        """Only the world state."""
        return {WORLD_STATE}

    @classmethod
    def description_names(cls, params: SensorsParams) -> dict[str, Any]:
        """The lidar's site and frame and the camera, where the parameters name them."""
        lidar = params.lidar or params.point_cloud
        names = {}
        if lidar is not None:
            names.update(laser_site=lidar.site, laser_frame=lidar.frame_id)
        if params.camera is not None:
            names.update(camera=params.camera.camera, camera_frame=params.camera.frame_id)
        return {key: value for key, value in names.items() if value is not None}

    @classmethod
    def robot_problems(cls, params: SensorsParams, robot: RobotModel, model: Any
                       ) -> list[tuple[str, str, str]]:
        """A lidar or point cloud needs the robot's lidar, a camera its camera (or the site
        or camera its parameters or cosim's conventions name, which it falls back to)."""
        names = RobotNames.of(cls.description_names(params))
        problems = []
        lidar = next((key for key in ("lidar", "point_cloud") if getattr(params, key)), None)
        if lidar is not None:
            problems += missing_sensor(robot, "lidar", f"params.{lidar}", names.laser_site,
                                       f"params.{lidar}.site", model)
        if params.camera is not None:
            problems += missing_sensor(robot, "camera", "params.camera", names.camera,
                                       "params.camera.camera", model)
        return problems

    def setup(self) -> None:
        """Load the mirror and build the configured sensors, each at the robot model's site or
        camera; a robot of a swarm sees the other robots."""
        robots = robots_of(self.config, self.description_names(self.params))
        p = _placed(self.params, robots[0] if len(robots) == 1 else None)
        self.mirror = WorldMirror.shared(self.config.world, self.config.layout,
                                         self.config.events)
        others = self.arena = None
        if self.config.layout is not None and len(robots) == 1:
            swarm = swarm_of(self.config, self.description_names(self.params))
            others = OtherRobots(self.mirror.model, swarm, robots[0])
            if p.lidar or p.point_cloud:
                self.arena = StaticWorld.shared(self.config.world, self.config.layout,
                                                self.mirror.model, self.config.events)
        self.lidar = (Lidar2D(self.mirror, p.lidar, self.config.period_ns, others, self.arena)
                      if p.lidar else None)
        self.cloud = (Lidar3D(self.mirror, p.point_cloud, others, self.arena)
                      if p.point_cloud else None)
        self.camera = (RgbdCamera(self.mirror, p.camera, self.config.render_warm_up)
                       if p.camera else None)
        self.count = 0

    def step(self, tick: Tick, inputs: dict[str, Any]) -> dict[str, Any]:
        """Pose the mirror from the world state, then measure with every configured sensor."""
        state = inputs.get(WORLD_STATE)
        if state is None:
            raise ValueError(f"sensors need {WORLD_STATE} at every activation (a same_tick "
                             "input from the physics node)")
        self.mirror.update(state)
        if self.arena is not None:
            m = self.mirror
            self.arena.update(m.data.qpos, m.version, m.model, m.label)
        out: dict[str, Any] = {}
        if self.lidar:
            out["/scan"] = self.lidar.measure(self.rng)
        if self.cloud:
            out["/point_cloud"] = self.cloud.measure(self.rng)
        if self.camera:
            color, depth, info = self.camera.render()
            out[COLOR_TOPIC] = color
            if depth is not None:
                out[DEPTH_TOPIC] = depth
            out[INFO_TOPIC] = info
        self.count += 1
        return out

    def metrics(self) -> dict[str, float]:
        """How many times the sensors measured."""
        return {"measurements": float(self.count)}


def _placed(params: SensorsParams, robot: RobotModel | None) -> SensorsParams:
    """The sensors' parameters with each sensor's site or camera and frame as the robot
    model has them; as given (or cosim's conventions) in a world without the robot."""
    names = RobotNames.of(SensorsNode.description_names(params))
    update: dict[str, Any] = {}
    lidar = robot.sensor("lidar") if robot is not None else None
    site = lidar.mujoco_name if lidar else names.laser_site
    frame = lidar.link if lidar else names.laser_frame
    for key in ("lidar", "point_cloud"):
        sensor = getattr(params, key)
        if sensor is not None:
            update[key] = sensor.model_copy(update={"site": site, "frame_id": frame})
            described = _from_description(sensor, lidar)
            if described:  # checked as the scenario's own values would be
                update[key] = type(sensor).model_validate(
                    {**update[key].model_dump(), **described})
    if params.camera is not None:
        camera = robot.sensor("camera") if robot is not None else None
        update["camera"] = params.camera.model_copy(update={
            "camera": camera.mujoco_name if camera else names.camera,
            "frame_id": camera.link if camera else names.camera_frame})
    return params.model_copy(update=update)


# A description's lidar parameters (a URDF's Gazebo <sensor> tag) -> the lidar's fields.
LIDAR_FROM_DESCRIPTION = {"samples": "beams", "fov": "fov", "range_min": "range_min",
                          "range_max": "range_max", "noise_stddev": "noise_stddev"}


def _from_description(params: BaseModel, sensor: Sensor | None) -> dict[str, Any]:
    """The lidar fields the robot model's sensor gives (a URDF's Gazebo tag: samples, field
    of view, range limits, noise) that the scenario's parameters leave unset."""
    if sensor is None:
        return {}
    given = dict(sensor.params)
    return {field: given[key] for key, field in LIDAR_FROM_DESCRIPTION.items()
            if key in given and field not in params.model_fields_set}
