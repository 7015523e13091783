"""What a scenario says about a robot described in URDF or xacro (the ``urdf:`` key of a
robot whose ``description`` is a ``.urdf``, ``.xacro`` or ``.urdf.xacro``): xacro
arguments, where its ROS packages are, its base, drive wheels, sensors, command interfaces
and actuator gains. Pure data; ``descriptions/urdf.py`` reads the description with it."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class Strict(BaseModel):
    """Unknown keys are errors (as every scenario section; plan.model imports this module)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class GainsSpec(Strict):
    """Gains of the actuators cosim adds: kp (position), kv (position damping, velocity)."""

    kp: float | None = Field(None, ge=0)
    kv: float | None = Field(None, ge=0)


class UrdfSpec(Strict):
    """A URDF or xacro robot: how cosim reads it (docs/tutorials/own-robot.md)."""

    args: dict[str, str | bool | int | float] = Field(default_factory=dict, description="xacro "
                                                      "arguments, "
                                 "name -> value (as name:=value on the xacro command line)")
    packages: dict[str, str] = Field(default_factory=dict, description="ROS package name -> "
                                     "its folder (holding package.xml), relative to this file; "
                                     "searched before AMENT_PREFIX_PATH and ROS_PACKAGE_PATH")
    base: Literal["auto", "free", "fixed"] = Field("auto", description="free: a mobile robot "
                                                   "(a free joint at the root link); fixed: "
                                                   "fixed to the world; auto: free with wheels")
    wheels: tuple[str, str] | None = Field(None, description="[left, right] drive wheel joints")
    wheel_radius: float | None = Field(None, gt=0, description="m; default: from the wheels' "
                                       "collision geometry")
    wheel_separation: float | None = Field(None, gt=0, description="m; default: from the "
                                           "wheels' positions")
    sensors: dict[Literal["lidar", "camera", "imu"], str] = Field(
        default_factory=dict, description="sensor kind -> the link it hangs on, e.g. "
        "{lidar: base_scan}; Gazebo <sensor> tags of the description add theirs")
    interfaces: dict[str, Literal["position", "velocity", "effort"]] = Field(
        default_factory=dict, description="joint -> command interface, for joints the "
        "description's <ros2_control> block does not command")
    gains: dict[str, GainsSpec] = Field(default_factory=dict, description="joint name, or "
                                        "wheel / position / velocity / effort -> {kp, kv}")


class UsdSpec(Strict):
    """A robot described in OpenUSD (UsdPhysics bodies, joints, drives): how cosim reads it
    (docs/how-to/usd-robots.md). Names are the prims' names, not their paths."""

    base: Literal["auto", "free", "fixed"] = Field("auto", description="free: a mobile robot; "
                                                   "fixed: fixed to the world; auto: fixed when "
                                                   "a joint holds the robot to the world (Isaac's "
                                                   "root_joint), else free")
    wheels: tuple[str, str] | None = Field(None, description="[left, right] drive wheel joints")
    wheel_radius: float | None = Field(None, gt=0, description="m; default: from the wheels' "
                                       "collision geometry")
    wheel_separation: float | None = Field(None, gt=0, description="m; default: from the "
                                           "wheels' positions")
    sensors: dict[Literal["lidar", "camera", "imu"], str] = Field(
        default_factory=dict, description="sensor kind -> the link or frame prim (by name) it "
        "hangs on, e.g. {lidar: base_scan}; UsdGeom.Camera prims add cameras")
    interfaces: dict[str, Literal["position", "velocity", "effort"]] = Field(
        default_factory=dict, description="joint -> command interface, for joints without a "
        "PhysicsDriveAPI (urdf-usd-converter's layout) or to override a drive's")
    gains: dict[str, GainsSpec] = Field(default_factory=dict, description="joint name, or "
                                        "wheel / position / velocity / effort -> {kp, kv}; "
                                        "over the drive's stiffness and damping")
