"""The physics node's bookkeeping for all robots at once (nodes.physics.batch) publishes,
bit for bit, what the per-robot code does: drives, odometry, joint states, IMU (the same
noise draws), moving frames, the path driven; and the slot-built messages
(nodes.physics.fast_messages) equal and encode like those built the usual way."""

from __future__ import annotations

import copy
import dataclasses

import mujoco
import numpy as np
import pytest
from geometry_msgs.msg import Twist
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray

from descriptions.load import load_scenario
from nodes.contract import Tick
from nodes.physics import fast_messages as fm
from nodes.physics import messages as m
from nodes.physics.batch import COVARIANCE, IMU
from nodes.physics.frames import RobotFrames, transform
from orchestrator.lockstep.inprocess import make_node
from plan.topic_names import JOINT_STATES, ODOM
from runtime.cdr.encode import encode
from tests.helpers import ROOT, SCENARIOS

SMALL = SCENARIOS / "swarm_small.yaml"
SWARM_URDF = ROOT / "scenarios" / "swarm_urdf.yaml"


def same(a, b) -> None:
    """Equal messages with equal bytes."""
    assert a == b
    assert encode(a) == encode(b)


def test_slot_built_messages_equal_those_built_the_usual_way():
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.normal(size=7)
        v = rng.normal(size=6)
        usual = m.odometry(q, v, "robot_1/odom", "robot_1/base_link")
        lin = usual.twist.twist.linear
        same(fm.odometry(q.tolist(), (lin.x, lin.y, lin.z), v[3:].tolist(), COVARIANCE,
                         "robot_1/odom", "robot_1/base_link"), usual)
        same(fm.transform_stamped("a", "b", q[:3].tolist(), q[3:].tolist()),
             transform("a", "b", q[:3], q[3:]))
        usual = m.joint_state(["j1", "j2"], q[:2], q[2:4], q[4:6])
        same(fm.joint_state(["j1", "j2"], m.f64(q[:2]), m.f64(q[2:4]), m.f64(q[4:6])), usual)
        cov = [np.diag(np.full(3, s)).ravel() for s in rng.random(3)]
        usual = Imu()
        usual.header.frame_id = "imu_link"
        o, w, a = usual.orientation, usual.angular_velocity, usual.linear_acceleration
        o.w, o.x, o.y, o.z = q[3:].tolist()
        w.x, w.y, w.z = v[:3].tolist()
        a.x, a.y, a.z = v[3:].tolist()
        (usual.orientation_covariance, usual.angular_velocity_covariance,
         usual.linear_acceleration_covariance) = cov
        same(fm.imu("imu_link", q[3:].tolist(), v[:3].tolist(), v[3:].tolist(), cov), usual)


def commands(names: list[str], k: int, heads: bool) -> dict:
    """Different commands per robot and tick, some beyond the drive's limits, and head
    positions so that the moving frames move."""
    out = {}
    for i, name in enumerate(names):
        t = Twist()
        t.linear.x = [0.4, -2.0, 1.5, 0.1][(i + k // 5) % 4]
        t.angular.z = [0.0, 3.5, -1.0, 0.7][(i + k // 7) % 4]
        out[f"/{name}/cmd_vel"] = t
        if heads:
            out[f"/{name}/joint_commands"] = Float64MultiArray(
                data=[0.3 * i - 0.5, 0.1 * k % 0.6])
    return out


def reference_drive(swarm, data: mujoco.MjData, inputs: dict) -> tuple[mujoco.MjData, list]:
    """One period the per-robot way: DiffDrive.update per robot per substep."""
    model = swarm.model
    ref = copy.copy(data)
    drives = [dataclasses.replace(r.drive) for r in swarm.driven]
    cmds = [m.twist_of(inputs.get(r.topics["/cmd_vel"])) for r in swarm.driven]
    for _ in range(swarm.substeps):
        for rig, drive, (v, w) in zip(swarm.driven, drives, cmds, strict=True):
            left, right = rig.wheel_act
            ref.ctrl[left], ref.ctrl[right] = drive.update(v, w, swarm.dt)
        mujoco.mj_step(model, ref)
    return ref, drives


@pytest.mark.parametrize("path, params", [
    (SMALL, {}), (SMALL, {"imu": None, "tf": {"map_frame": None}}),
    (SWARM_URDF, {"robot_description": True})], ids=["imu-and-map", "no-imu-no-map", "urdf"])
def test_the_batch_publishes_what_each_robot_would_bit_for_bit(path, params):
    scenario = load_scenario(path, {"nodes.physics.params": params})
    node = make_node(scenario, "physics")
    swarm = node.swarm
    rigs = swarm.rigs
    names = [r.name for r in rigs]
    period = scenario.nodes["physics"].spec.period_ns
    path = [0.0] * len(rigs)
    last = None
    heads = all(len(r.head_act) == 2 for r in rigs)
    for k in range(40):
        inputs = commands(names, k, heads)
        if k and heads:
            swarm.data.ctrl[[a for r in rigs for a in r.head_act]] = np.concatenate(
                [inputs[f"/{n}/joint_commands"].data for n in names])
        if k:
            data = swarm.data
            ref_data, ref_drives = reference_drive(swarm, data, inputs)
        state = node.rng.bit_generator.state
        out = node.step(Tick(k, k * period), inputs)
        data = swarm.data
        if k:
            assert data.qpos.tobytes() == ref_data.qpos.tobytes()
            assert data.qvel.tobytes() == ref_data.qvel.tobytes()
            assert [(r.drive.v, r.drive.w) for r in rigs] == [(d.v, d.w) for d in ref_drives]
        rng = np.random.Generator(type(node.rng.bit_generator)())
        rng.bit_generator.state = state
        transforms = []
        for rig in rigs:
            q = rig.base_pose(data)
            same(out[rig.topics[ODOM]], m.odometry(q, data.qvel[rig.vadr:rig.vadr + 6],
                                                   rig.odom_frame, rig.base_frame))
            described = rig.described
            same(out[rig.topics[JOINT_STATES]], described.joint_state(data) if described else
                 m.joint_state(rig.joint_names, data.qpos[rig.joint_q], data.qvel[rig.joint_v],
                               data.qfrc_actuator[rig.joint_v]))
            if rig.imu is None:
                assert rig.topics[IMU] not in out
            else:
                kept, rig.imu.rng = rig.imu.rng, rng
                try:
                    same(out[rig.topics[IMU]], rig.imu.measure(data))
                finally:
                    rig.imu.rng = kept
            assert type(rig.frames) is RobotFrames  # one frame publisher, any format
            transforms += rig.frames.dynamic(data, q)
            if described:  # its moving links, as pairs of bodies: robot_state_publisher's
                reference = described.state.moving(data)
                assert reference and rig.frames.moving and not rig.frames.link_frames
                links = rig.frames.dynamic(data, q)[-len(reference):]
                for t, r in zip(links, reference, strict=True):
                    assert (t.header.frame_id, t.child_frame_id) == (r.parent, r.child)
                    p, o = t.transform.translation, t.transform.rotation
                    quat = np.array([o.w, o.x, o.y, o.z])
                    assert np.allclose([p.x, p.y, p.z], r.pos, rtol=0, atol=1e-12)
                    assert np.allclose(quat * np.sign(quat @ r.quat), r.quat, rtol=0,
                                       atol=1e-12)
        assert len(out["/tf"].transforms) == len(transforms)
        if not rigs[0].described:
            per_robot = 3 + (swarm.params.tf.map_frame is not None)  # (map,) base, head
            assert len(transforms) == per_robot * len(rigs)
        for a, b in zip(out["/tf"].transforms, transforms, strict=True):
            same(a, b)
        xy = [(float(data.qpos[r.qadr]), float(data.qpos[r.qadr + 1])) for r in rigs]
        if last is not None:
            path = [p + float(np.hypot(x - lx, y - ly))
                    for p, (x, y), (lx, ly) in zip(path, xy, last, strict=True)]
        last = xy
    metrics = node.metrics()
    assert [metrics[f"{n}/path_length"] for n in names] == path
    assert all(p > 0.05 for p in path), path  # they moved
