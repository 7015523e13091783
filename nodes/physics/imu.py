"""An IMU from MuJoCo's gyro, accelerometer and framequat sensors on one site (REP-145).

- ``angular_velocity``: the gyro, rad/s in the sensor frame.
- ``linear_acceleration``: the accelerometer, m/s^2 in the sensor frame: the specific force,
  so at rest with z up it reads +9.81 on z (REP-145).
- ``orientation``: the site's orientation in the world frame (x east, y north, z up: the
  world, map and odom frames of a cosim run share their axes up to ``map_to_odom``).

Noise: each axis of the gyro and accelerometer carries a constant bias, drawn once per reset
from N(0, bias_stddev^2), plus white noise N(0, stddev^2) per sample; the orientation is
turned by a rotation vector drawn from N(0, orientation_stddev^2) per axis. All draws come
from the node's seeded generator, in a fixed order. Each covariance is the diagonal of its
white noise, stddev^2, as REP-145's ``*_stddev`` parameters define it (a bias is not noise:
it is the same in every sample). A stddev of 0 gives a zero covariance, which ROS reads as
"unknown", so the defaults are small but not zero.
"""

from __future__ import annotations

import mujoco
import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from sensor_msgs.msg import Imu

SENSOR = mujoco.mjtObj.mjOBJ_SENSOR
SITE = mujoco.mjtObj.mjOBJ_SITE
KINDS = (("gyro", mujoco.mjtSensor.mjSENS_GYRO),
         ("accelerometer", mujoco.mjtSensor.mjSENS_ACCELEROMETER),
         ("orientation", mujoco.mjtSensor.mjSENS_FRAMEQUAT))


class ImuParams(BaseModel):
    """The IMU's site and sensors in the MJCF, its frame, and its noise (REP-145 names)."""

    model_config = ConfigDict(extra="forbid")
    site: str = "imu"
    frame_id: str = "imu_link"
    gyro: str = "imu_gyro"
    accelerometer: str = "imu_accel"
    orientation: str = "imu_quat"
    angular_velocity_stddev: float = Field(0.002, ge=0, description="rad/s, white noise")
    angular_velocity_bias_stddev: float = Field(0.001, ge=0, description="rad/s, per reset")
    linear_acceleration_stddev: float = Field(0.02, ge=0, description="m/s^2, white noise")
    linear_acceleration_bias_stddev: float = Field(0.01, ge=0, description="m/s^2, per reset")
    orientation_stddev: float = Field(0.002, ge=0, description="rad per axis, white noise")


def imu_problems(model: mujoco.MjModel, params: ImuParams) -> list[tuple[str, str, str]]:
    """What the world lacks for this IMU: (key, problem, accepted) per problem."""
    site = mujoco.mj_name2id(model, SITE, params.site)
    for key, kind in KINDS:
        name = getattr(params, key)
        sid = mujoco.mj_name2id(model, SENSOR, name)
        wanted = {"gyro": "gyro", "accelerometer": "accelerometer",
                  "orientation": "framequat"}[key]
        example = (f'<{wanted} name="{name}" site="{params.site}"/>' if key != "orientation"
                   else f'<framequat name="{name}" objtype="site" objname="{params.site}"/>')
        if sid < 0:
            return [(f"params.imu.{key}", f"the world has no sensor {name!r}.",
                     f"a {wanted} sensor on site {params.site!r} in the MJCF, e.g. {example}.")]
        if (model.sensor_type[sid] != kind or model.sensor_objtype[sid] != SITE
                or model.sensor_objid[sid] != site):
            return [(f"params.imu.{key}", f"sensor {name!r} is not a {wanted} sensor on site "
                     f"{params.site!r}.", f"e.g. {example}")]
    return []


class SimulatedImu:
    """Reads the IMU's MuJoCo sensors and adds seeded noise; builds sensor_msgs/Imu."""

    def __init__(self, model: mujoco.MjModel, params: ImuParams, rng: np.random.Generator,
                 bias: np.ndarray | None = None):
        """Its sensors in ``model``; its bias drawn from ``rng`` (which then draws its
        noise), or ``bias`` carried over from the same IMU in a world recompiled."""
        self.params = params
        self.rng = rng
        adr = {key: int(model.sensor_adr[mujoco.mj_name2id(model, SENSOR, getattr(params, key))])
               for key, _ in KINDS}
        self.gyro = slice(adr["gyro"], adr["gyro"] + 3)
        self.accel = slice(adr["accelerometer"], adr["accelerometer"] + 3)
        self.quat = slice(adr["orientation"], adr["orientation"] + 4)
        p = params
        self.noise = np.repeat([p.angular_velocity_stddev, p.linear_acceleration_stddev,
                                p.orientation_stddev], 3)
        self.bias = bias if bias is not None else rng.normal(size=6) * np.repeat(
            [p.angular_velocity_bias_stddev, p.linear_acceleration_bias_stddev], 3)
        self.covariance = [_diagonal(s * s) for s in (p.orientation_stddev,
                                                      p.angular_velocity_stddev,
                                                      p.linear_acceleration_stddev)]

    def measure(self, data: mujoco.MjData) -> Imu:
        """One sample of the current state (the sensors must be computed: mj_forward)."""
        s = data.sensordata
        draw = self.rng.normal(size=9) * self.noise
        gyro = s[self.gyro] + self.bias[:3] + draw[:3]
        accel = s[self.accel] + self.bias[3:] + draw[3:6]
        quat = s[self.quat].copy()
        mujoco.mju_quatIntegrate(quat, draw[6:], 1.0)  # a small turn in the sensor frame
        msg = Imu()
        msg.header.frame_id = self.params.frame_id
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        o.w, o.x, o.y, o.z = (float(v) for v in quat)
        w.x, w.y, w.z = (float(v) for v in gyro)
        a.x, a.y, a.z = (float(v) for v in accel)
        (msg.orientation_covariance, msg.angular_velocity_covariance,
         msg.linear_acceleration_covariance) = self.covariance
        return msg


def _diagonal(variance: float) -> np.ndarray:
    return np.diag(np.full(3, variance)).ravel()
