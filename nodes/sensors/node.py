"""The sensors node: lidar (LaserScan), 3D lidar (PointCloud2) and RGB-D camera.

Each instance runs the sensors its parameters name, so a scenario can run the lidar and the
camera as two nodes at different rates. The node mirrors the physics world: it loads the
same MJCF and, every activation, copies qpos from /cosim/world_state (a same_tick input).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator
from sensor_msgs.msg import CameraInfo, Image, LaserScan, PointCloud2

from nodes.contract import StepNode, Tick
from nodes.sensors.camera import COLOR_TOPIC, DEPTH_TOPIC, INFO_TOPIC, CameraParams, RgbdCamera
from nodes.sensors.lidar import Lidar2D, Lidar3D, LidarParams, PointCloudParams
from nodes.sensors.mirror import WorldMirror
from nodes.sensors.others import OtherRobots, robot_sensors

WORLD_STATE = "/cosim/world_state"


class SensorsParams(BaseModel):
    """Which sensors this instance runs (at least one), each with its own settings."""

    model_config = ConfigDict(extra="forbid")
    lidar: LidarParams | None = None
    point_cloud: PointCloudParams | None = None
    camera: CameraParams | None = None
    robot: str | None = Field(None, description="set by for_each: robot: the robot whose "
                              "sensors these are (names prefixed ROBOT/); the lidar sees "
                              "the other robots")

    @model_validator(mode="after")
    def _one_sensor(self) -> SensorsParams:
        if self.lidar is None and self.point_cloud is None and self.camera is None:
            raise ValueError("give at least one of lidar, point_cloud, camera")
        return self


class SensorsNode(StepNode):
    """Ray-cast lidars and a rendered camera over a kinematic mirror of the world."""

    Params = SensorsParams
    needs_world = True

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

    def setup(self) -> None:
        """Load the mirror and build the configured sensors."""
        p = self.params
        self.mirror = WorldMirror(self.config.world, self.config.robots)
        others = None
        if p.robot is not None:
            p = robot_sensors(p, p.robot)
            others = OtherRobots(self.mirror.model, self.config.robots, p.robot)
        self.lidar = (Lidar2D(self.mirror, p.lidar, self.config.period_ns, others)
                      if p.lidar else None)
        self.cloud = Lidar3D(self.mirror, p.point_cloud, others) if p.point_cloud else None
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
