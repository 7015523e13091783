"""Every robot's per-tick bookkeeping at once: the drives, the path and goal accounting, and
the odometry, joint states, IMU and moving frames each robot publishes, as numpy arrays over
all robots of a swarm instead of a Python loop of small numpy calls per robot.

Every published value is the one the per-robot code computes (``DiffDrive.update``,
``messages.odometry``, ``RobotFrames.dynamic``, ``SimulatedImu.measure``), bit for bit: the
same IEEE operations in the same order, elementwise (no BLAS), the IMU's noise drawn from the
one generator in the same order, and the quaternion products through MuJoCo's own
``mju_mulQuat`` and ``mju_quatIntegrate`` as before. tests/test_physics_batch.py compares
them with the per-robot code.
"""

from __future__ import annotations

import array
from typing import Any

import mujoco
import numpy as np

from nodes.contract import Tick
from nodes.physics import fast_messages as fm
from nodes.physics import messages as m
from plan.topic_names import JOINT_STATES, ODOM

COVARIANCE = np.array(m.TRUTH_COVARIANCE, dtype=np.float64)
IMU = "/imu"
NEGATE = np.array([1.0, -1.0, -1.0, -1.0])  # a quaternion's conjugate


class SwarmDrives:
    """The differential drives of every driven robot, stepped together: each substep moves
    each applied twist towards its command within the acceleration limits and writes the
    wheel speeds into ``ctrl``, as ``DiffDrive.update`` does one robot at a time. The rigs'
    ``DiffDrive`` objects keep the state between ticks (a twin or a teleport sets it)."""

    def __init__(self, rigs: list, dt: float):
        drives = [r.drive for r in rigs]
        self.rigs = rigs
        get = lambda key: np.array([getattr(d, key) for d in drives], dtype=np.float64)  # noqa: E731
        self.max_v, self.max_w = get("max_linear_speed"), get("max_angular_speed")
        self.step_v = get("max_linear_accel") * dt
        self.step_w = get("max_angular_accel") * dt
        self.half_separation = 0.5 * get("wheel_separation")
        self.radius = get("wheel_radius")
        self.left = np.array([r.wheel_act[0] for r in rigs], dtype=np.int64)
        self.right = np.array([r.wheel_act[1] for r in rigs], dtype=np.int64)

    def integrate(self, model: mujoco.MjModel, data: mujoco.MjData,
                  commands: list[tuple[float, float]], substeps: int, after_step) -> None:
        """``substeps`` world steps with the commanded (v, w) per rig; ``after_step`` after
        each one."""
        if not self.rigs:
            for _ in range(substeps):
                mujoco.mj_step(model, data)
                after_step()
            return
        cmd = np.array(commands, dtype=np.float64).reshape(len(self.rigs), 2)
        v_cmd = np.minimum(np.maximum(cmd[:, 0], -self.max_v), self.max_v)
        w_cmd = np.minimum(np.maximum(cmd[:, 1], -self.max_w), self.max_w)
        v = np.array([r.drive.v for r in self.rigs], dtype=np.float64)
        w = np.array([r.drive.w for r in self.rigs], dtype=np.float64)
        ctrl = data.ctrl
        for _ in range(substeps):
            v = v + np.minimum(np.maximum(v_cmd - v, -self.step_v), self.step_v)
            w = w + np.minimum(np.maximum(w_cmd - w, -self.step_w), self.step_w)
            half = self.half_separation * w
            ctrl[self.left] = (v - half) / self.radius
            ctrl[self.right] = (v + half) / self.radius
            mujoco.mj_step(model, data)
            after_step()
        for rig, vi, wi in zip(self.rigs, v.tolist(), w.tolist(), strict=True):
            rig.drive.v, rig.drive.w = vi, wi


class SwarmBook:
    """The path each mobile robot drives, its pose goal, and what every robot publishes:
    /odom, /joint_states, /imu and its moving /tf frames, from index arrays made once."""

    def __init__(self, model: mujoco.MjModel, rigs: list, replaced: frozenset[str] = frozenset()):
        """``replaced``: the /joint_states topics (graph names) something else in the step
        publishes (a joint_state_broadcaster in the physics step): not built here."""
        self.rigs = rigs
        self.joint_states = [rig.topics[JOINT_STATES] not in replaced for rig in rigs]
        self.any_joint_states = any(self.joint_states)
        n = len(rigs)
        self.mobile = np.array([r.mobile for r in rigs], dtype=bool)
        mobile = [r for r in rigs if r.mobile]
        self.qpos_index = np.array([[r.qadr + k for k in range(7)] for r in mobile],
                                   dtype=np.int64).reshape(-1, 7)
        self.qvel_index = np.array([[r.vadr + k for k in range(6)] for r in mobile],
                                   dtype=np.int64).reshape(-1, 6)
        self.fixed_base = np.array([r.base for r in rigs if not r.mobile], dtype=np.int64)
        self.all_mobile = bool(self.mobile.all())
        # path driven (mobile robots, in rig order among them)
        self.path = np.zeros(len(mobile))
        self.last_xy: tuple[np.ndarray, np.ndarray] | None = None
        self.mobile_slot = {id(r): i for i, r in enumerate(mobile)}
        # pose goals (a joint goal is checked instead where there is one)
        self.goal_rigs = [r for r in mobile if r.goal is not None and r.joint_goal is None]
        slots = [self.mobile_slot[id(r)] for r in self.goal_rigs]
        self.goal_slot = np.array(slots, dtype=np.int64)
        self.goal_xy = np.array([[r.goal["x"], r.goal["y"]] for r in self.goal_rigs],
                                dtype=np.float64).reshape(-1, 2)
        self.goal_tolerance = np.array([r.goal["position_tolerance"] for r in self.goal_rigs],
                                       dtype=np.float64)
        self.joint_goal_rigs = [r for r in rigs if r.joint_goal is not None]
        # joints: one gather for every robot, split per robot
        self.joint_q = np.concatenate([np.asarray(r.state_q, dtype=np.int64) for r in rigs]
                                      or [np.zeros(0, np.int64)])
        self.joint_v = np.concatenate([np.asarray(r.state_v, dtype=np.int64) for r in rigs]
                                      or [np.zeros(0, np.int64)])
        bounds = np.cumsum([0] + [len(r.state_names) for r in rigs])
        self.joint_bounds = list(zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True))
        # moving frames: every robot's, in rig order then each robot's own order
        moving = [(i, mb) for i, r in enumerate(rigs) if r.frames is not None
                  for mb in r.frames.moving]
        self.moving = moving
        self.moving_body = np.array([mb.body for _, mb in moving], dtype=np.int64)
        self.moving_parent = np.array([mb.parent for _, mb in moving], dtype=np.int64)
        self.map_to_odom = []
        for r in rigs:
            mo = None if r.frames is None else r.frames.map_to_odom
            if mo is not None:
                frame, pos, quat = mo
                mo = (frame, tuple(float(v) for v in pos), tuple(float(v) for v in quat))
            self.map_to_odom.append(mo)
        # IMUs
        self.imus = [(i, r.imu) for i, r in enumerate(rigs) if r.imu is not None]
        if self.imus:
            imus = [u for _, u in self.imus]
            self.gyro = np.array([[u.gyro.start + k for k in range(3)] for u in imus])
            self.accel = np.array([[u.accel.start + k for k in range(3)] for u in imus])
            self.quat = np.array([[u.quat.start + k for k in range(4)] for u in imus])
            self.imu_noise = np.stack([u.noise for u in imus])
            self.imu_bias = np.stack([u.bias for u in imus])
            rngs: dict[int, tuple[np.random.Generator, list[int]]] = {}
            for k, u in enumerate(imus):  # the node's generator; a robot that entered: its own
                rngs.setdefault(id(u.rng), (u.rng, []))[1].append(k)
            self.imu_rngs = [(rng, np.array(ks)) for rng, ks in rngs.values()]
        self.n = n

    def base_poses(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Every base's (x, y, z, qw, qx, qy, qz) and its free joint's velocity (zero for a
        base fixed to the world), one row per rig."""
        if self.all_mobile:
            return data.qpos[self.qpos_index], data.qvel[self.qvel_index]
        pose = np.empty((self.n, 7))
        vel = np.zeros((self.n, 6))
        pose[self.mobile] = data.qpos[self.qpos_index]
        vel[self.mobile] = data.qvel[self.qvel_index]
        fixed = ~self.mobile
        pose[fixed, :3] = data.xpos[self.fixed_base]
        pose[fixed, 3:] = data.xquat[self.fixed_base]
        return pose, vel

    def account(self, data: mujoco.MjData, tick: Tick) -> None:
        """The path driven by every mobile robot, and each goal in ground truth (sticky): the
        pose within the goal's tolerances, or the joints within the joint goal's."""
        if len(self.path):
            xy = data.qpos[self.qpos_index[:, :2]]
            x, y = xy[:, 0], xy[:, 1]
            if self.last_xy is not None:
                self.path += np.hypot(x - self.last_xy[0], y - self.last_xy[1])
            self.last_xy = (x, y)
            if self.goal_rigs:
                # only a robot within its goal's position tolerance can have arrived: the
                # same distance as Rig.check_goal's, which decides
                near = np.hypot(x[self.goal_slot] - self.goal_xy[:, 0],
                                y[self.goal_slot] - self.goal_xy[:, 1]) <= self.goal_tolerance
                for k in np.flatnonzero(near).tolist():
                    rig = self.goal_rigs[k]
                    if rig.goal_time_ns is None:
                        rig.check_goal(data, tick)
        for rig in self.joint_goal_rigs:
            if rig.goal_time_ns is None:
                rig.check_goal(data, tick)

    def path_length(self, rig) -> float:
        """The path rig ``rig`` has driven, m (0 for a base fixed to the world)."""
        slot = self.mobile_slot.get(id(rig))
        return 0.0 if slot is None else float(self.path[slot])

    def publish(self, data: mujoco.MjData, out: dict[str, Any], tf: bool) -> list:
        """Every robot's odometry, joint states (where no broadcaster replaces them) and IMU
        into ``out``; every moving frame."""
        rigs = self.rigs
        pose, vel = self.base_poses(data)
        qw, qx, qy, qz = pose[:, 3], pose[:, 4], pose[:, 5], pose[:, 6]
        vx, vy, vz = vel[:, 0], vel[:, 1], vel[:, 2]
        # messages.quat_to_mat then plan.rot3.mat_t_vec, elementwise in the same order
        r00 = 1 - 2 * (qy * qy + qz * qz)
        r01 = 2 * (qx * qy - qz * qw)
        r02 = 2 * (qx * qz + qy * qw)
        r10 = 2 * (qx * qy + qz * qw)
        r11 = 1 - 2 * (qx * qx + qz * qz)
        r12 = 2 * (qy * qz - qx * qw)
        r20 = 2 * (qx * qz - qy * qw)
        r21 = 2 * (qy * qz + qx * qw)
        r22 = 1 - 2 * (qx * qx + qy * qy)
        linear = np.stack([r00 * vx + r10 * vy + r20 * vz, r01 * vx + r11 * vy + r21 * vz,
                           r02 * vx + r12 * vy + r22 * vz], axis=1).tolist()
        angular = vel[:, 3:6].tolist()
        poses = pose.tolist()
        if self.any_joint_states:
            jq = data.qpos[self.joint_q].tobytes()
            jv = data.qvel[self.joint_v].tobytes()
            je = data.qfrc_actuator[self.joint_v].tobytes()
        own = self.joint_states
        for i, rig in enumerate(rigs):
            out[rig.topics[ODOM]] = fm.odometry(poses[i], linear[i], angular[i], COVARIANCE,
                                                rig.odom_frame, rig.base_frame)
            if not own[i]:  # a broadcaster's replaces it
                continue
            a, b = self.joint_bounds[i]
            out[rig.topics[JOINT_STATES]] = fm.joint_state(
                rig.state_names, _f64(jq, a, b), _f64(jv, a, b), _f64(je, a, b))
        if self.imus:
            self._imu(data, out)
        return self._frames(data, poses) if tf else []

    def _imu(self, data: mujoco.MjData, out: dict[str, Any]) -> None:
        """SimulatedImu.measure for every IMU: one draw of each generator for all the IMUs
        it serves (the same numbers, in the same order, as one draw of nine per robot)."""
        s = data.sensordata
        if len(self.imu_rngs) == 1:
            draw = self.imu_rngs[0][0].normal(size=(len(self.imus), 9))
        else:
            draw = np.empty((len(self.imus), 9))
            for rng, ks in self.imu_rngs:
                draw[ks] = rng.normal(size=(len(ks), 9))
        draw *= self.imu_noise
        gyro = (s[self.gyro] + self.imu_bias[:, :3] + draw[:, :3]).tolist()
        accel = (s[self.accel] + self.imu_bias[:, 3:] + draw[:, 3:6]).tolist()
        quats = s[self.quat]
        turn = draw[:, 6:]
        quat = np.empty(4)
        for k, (i, unit) in enumerate(self.imus):
            quat[:] = quats[k]
            mujoco.mju_quatIntegrate(quat, turn[k], 1.0)  # a small turn in the sensor frame
            out[self.rigs[i].topics[IMU]] = fm.imu(unit.params.frame_id, quat.tolist(),
                                                   gyro[k], accel[k], unit.covariance)

    def _frames(self, data: mujoco.MjData, poses: list) -> list:
        """``dynamic`` of every robot's frames: map -> odom, odom -> base (where its frames
        publish it), its moving bodies (batched: every robot's, MJCF or described) and the
        moving links read per robot (RobotFrames.links: a joint on a world site), every
        robot through the same path."""
        moved: list[list] = [[] for _ in self.rigs]
        if self.moving:
            body, parent = self.moving_body, self.moving_parent
            a, b, c, d, e, f, g, h, i = data.xmat[parent].T
            rel = data.xpos[body] - data.xpos[parent]
            x, y, z = rel[:, 0], rel[:, 1], rel[:, 2]
            pos = np.stack([a * x + d * y + g * z, b * x + e * y + h * z,
                            c * x + f * y + i * z], axis=1).tolist()
            conj = data.xquat[parent] * NEGATE  # mju_negQuat, exactly
            child = data.xquat[body]
            quat = np.empty((len(body), 4))
            for k in range(len(body)):
                mujoco.mju_mulQuat(quat[k], conj[k], child[k])
            quats = quat.tolist()
            for k, (rig_index, mb) in enumerate(self.moving):
                moved[rig_index].append(fm.transform_stamped(mb.parent_frame, mb.frame,
                                                             pos[k], quats[k]))
        out = []
        for k, rig in enumerate(self.rigs):
            if rig.frames is None:
                continue
            mo = self.map_to_odom[k]
            frames = rig.frames
            if mo is not None:
                out.append(fm.transform_stamped(mo[0], frames.odom_frame, mo[1], mo[2]))
            if frames.publishes_base:
                p = poses[k]
                out.append(fm.transform_stamped(frames.odom_frame, frames.base_frame, p[:3],
                                                p[3:7]))
            out += moved[k]
            out += frames.links(data)
        return out


def _f64(buffer: bytes, start: int, end: int) -> array.array:
    """Items ``start:end`` of a float64 buffer as the array.array rclpy keeps."""
    out = array.array("d")
    out.frombytes(buffer[start * 8:end * 8])
    return out
