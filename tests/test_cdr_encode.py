"""The generated CDR encoder gives exactly rclpy's bytes with the padding zeroed, for every
message type of the standard packages, filled at random (seeded) and left at defaults."""

from __future__ import annotations

import importlib
import math
import random

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import serialize_message
from rosidl_parser import definition as d
from sensor_msgs.msg import JointState, LaserScan

from nodes.control.global_planner import path_message
from runtime.cdr.canonical import canonical_cdr
from runtime.cdr.encode import encode, encoder_for

PACKAGES = ["std_msgs", "geometry_msgs", "sensor_msgs", "nav_msgs", "diagnostic_msgs",
            "rosgraph_msgs", "builtin_interfaces", "visualization_msgs", "trajectory_msgs",
            "shape_msgs", "stereo_msgs", "tf2_msgs"]


def message_classes() -> list[type]:
    """Every message class of the standard packages installed with rclpy."""
    classes = []
    for package in PACKAGES:
        module = importlib.import_module(f"{package}.msg")
        classes += [getattr(module, name) for name in sorted(dir(module))
                    if isinstance(getattr(module, name), type)
                    and hasattr(getattr(module, name), "SLOT_TYPES")]
    return classes


def random_value(slot, rng: random.Random, depth: int):
    """A value for one field; sequences get 0-4 elements (bounded ones up to their bound)."""
    if isinstance(slot, d.BasicType):
        return _random_basic(slot.typename, rng)
    if isinstance(slot, d.AbstractString):
        bound = getattr(slot, "maximum_size", None) or 6
        return "".join(rng.choice("ab é€") for _ in range(rng.randrange(min(bound, 6) + 1)))
    if isinstance(slot, d.NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        return fill(getattr(module, slot.name)(), rng, depth + 1)
    if isinstance(slot, d.Array):
        return [random_value(slot.value_type, rng, depth) for _ in range(slot.size)]
    bound = slot.maximum_size if isinstance(slot, d.BoundedSequence) else 4
    count = rng.randrange(bound + 1) if depth < 3 else 0
    return [random_value(slot.value_type, rng, depth) for _ in range(count)]


def _random_basic(typename: str, rng: random.Random):
    if typename == "boolean":
        return rng.random() < 0.5
    if typename in ("float", "double"):
        return rng.choice([0.0, -0.0, 1.5, math.inf, -math.inf, rng.uniform(-1e3, 1e3)])
    if typename == "octet":
        return bytes([rng.randrange(256)])
    bits = int("".join(c for c in typename if c.isdigit()) or 8)
    if typename.startswith("u") or typename == "char":
        return rng.randrange(2 ** bits)
    return rng.randrange(-2 ** (bits - 1), 2 ** (bits - 1))


def fill(msg, rng: random.Random, depth: int = 0):
    """``msg`` with every field set to a random value of its type."""
    for name, slot in zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True):
        setattr(msg, name, random_value(slot, rng, depth))
    return msg


def rclpy_bytes(msg) -> bytes:
    return canonical_cdr(serialize_message(msg), type(msg))


@pytest.mark.parametrize("msg_class", message_classes(), ids=lambda c: c.__name__)
def test_encoder_matches_rclpy_for_random_messages(msg_class):
    rng = random.Random(msg_class.__name__)
    assert encoder_for(msg_class) is not None, "every standard type has a generated encoder"
    for i in range(12):
        msg = fill(msg_class(), rng) if i else msg_class()
        assert encode(msg) == rclpy_bytes(msg)


def test_a_real_plan_takes_the_generated_path():
    msg = path_message(np.cumsum(np.full((50, 2), 0.1), axis=0), "map", 0.5)
    encoded = encoder_for(Path)(msg)
    assert encoded is not None
    assert encoded == rclpy_bytes(msg)
    assert len(encoded) > 50 * 56


def test_fixed_size_types_are_padded_like_rmw():
    # rmw_fastrtps sizes a fixed-size message rounded up to 4 bytes
    from std_msgs.msg import Bool
    assert encode(Bool(data=True)) == b"\x00\x01\x00\x00\x01\x00\x00\x00"


def test_an_empty_primitive_sequence_is_padded_like_rmw():
    # rmw's size estimate aligns an empty double[] as if it had elements, so its bytes end
    # in zeros past what is written: the generated encoder gives those zeros too
    msg = JointState(name=["a"], position=[1.0], velocity=[], effort=[2.0])
    encoded = encoder_for(JointState)(msg)
    assert encoded == rclpy_bytes(msg)
    assert len(encoded) == 68 and encoded[-4:] == bytes(4)
    scan = LaserScan(ranges=[1.0, 2.0])
    assert encode(scan) == rclpy_bytes(scan)


def _emptied(msg, rng: random.Random, depth: int = 0):
    """``msg`` filled at random with every primitive sequence, at any depth, left empty
    or not by a coin."""
    for name, slot in zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True):
        if isinstance(slot, d.AbstractSequence) and isinstance(slot.value_type, d.BasicType):
            value = random_value(slot, rng, depth) if rng.random() < 0.5 else []
        elif isinstance(slot, d.NamespacedType):
            module = importlib.import_module(".".join(slot.namespaces))
            value = _emptied(getattr(module, slot.name)(), rng, depth + 1)
        elif (isinstance(slot, (d.AbstractSequence, d.Array))
              and isinstance(slot.value_type, d.NamespacedType)):
            module = importlib.import_module(".".join(slot.value_type.namespaces))
            count = slot.size if isinstance(slot, d.Array) else rng.randrange(4)
            value = [_emptied(getattr(module, slot.value_type.name)(), rng, depth + 1)
                     for _ in range(count if depth < 3 else 0)]
        else:
            value = random_value(slot, rng, depth)
        setattr(msg, name, value)
    return msg


def _with_primitive_sequences() -> list[type]:
    from control_msgs import msg as control
    classes = message_classes() + [getattr(control, n) for n in sorted(dir(control))
                                   if hasattr(getattr(control, n), "SLOT_TYPES")]
    return [c for c in classes if encoder_for(c) is not None and "else:\n" in
            encoder_for(c).source]


@pytest.mark.parametrize("msg_class", _with_primitive_sequences(), ids=lambda c: c.__name__)
def test_empty_primitive_sequences_at_every_depth_match_rclpy(msg_class):
    # the estimator's zeros must come out right whatever lies before and after the empty
    # sequence: every type with a primitive sequence, each one empty or not by a coin
    rng = random.Random("empty " + msg_class.__name__)
    for _ in range(16):
        msg = _emptied(msg_class(), rng)
        assert encode(msg) == rclpy_bytes(msg)


def test_the_trajectory_controller_state_takes_the_generated_path():
    from control_msgs.msg import JointTrajectoryControllerState
    from trajectory_msgs.msg import JointTrajectoryPoint

    point = JointTrajectoryPoint(positions=[0.1] * 6, velocities=[0.0] * 6)
    msg = JointTrajectoryControllerState(joint_names=list("abcdef"), reference=point,
                                         feedback=point, error=point, output=point)
    assert encoder_for(JointTrajectoryControllerState)(msg) == rclpy_bytes(msg)


def test_kept_strings_give_the_same_bytes_when_the_cache_is_full(monkeypatch):
    import runtime.cdr.encode as encoder
    monkeypatch.setattr(encoder, "_CACHE_SIZE", 2)
    rng = random.Random("cache")
    for _ in range(20):
        msg = fill(JointState(), rng)
        assert encode(msg) == rclpy_bytes(msg)
        assert encode(msg) == rclpy_bytes(msg)  # again, from what is kept
    assert len(encoder._strings) <= 2 and len(encoder._string_seqs) <= 2


def test_a_constant_message_gives_rclpy_bytes_at_every_stamp():
    from builtin_interfaces.msg import Time
    from control_msgs.msg import JointTrajectoryControllerState
    from tf2_msgs.msg import TFMessage

    from runtime.cdr.encode import ConstantTails

    tails = ConstantTails()
    stamps = ((0, 0), (3, 10_000_000), (2**31 - 1, 999_999_999), (5, 1))
    msg = JointTrajectoryControllerState()
    for sec, nanosec in stamps:
        msg.header.stamp = Time(sec=sec, nanosec=nanosec)
        assert tails.encode("/state", msg) == rclpy_bytes(msg)
    assert tails._last["/state"][0] is msg
    other = JointTrajectoryControllerState(joint_names=["a"])  # another: its own bytes
    assert tails.encode("/state", other) == rclpy_bytes(other)
    assert tails._last["/state"][0] is other  # the last one only is held
    # the controller's plan (nodes.control.node: /plan), and its replan under the same key
    for path in (np.cumsum(np.full((60, 2), 0.1), axis=0), np.array([[0.0, 0.0], [1.0, 2.0]]),
                 None):
        plan = path_message(path, "map", 0.25)
        for sec, nanosec in stamps:
            plan.header.stamp = Time(sec=sec, nanosec=nanosec)
            assert tails.encode("/plan", plan) == rclpy_bytes(plan)
        assert tails._last["/plan"][0] is plan
    assert sorted(tails._last) == ["/plan", "/state"]
    tf = fill(TFMessage(), random.Random("tf"))  # no header first: encoded every time
    assert tails.encode("/tf", tf) == rclpy_bytes(tf)
    for transform in tf.transforms:
        transform.header.stamp = Time(sec=7)
    assert tails.encode("/tf", tf) == rclpy_bytes(tf)
    assert "/tf" not in tails._last


def test_the_marks_are_the_steps_own_and_a_replan_replaces_the_kept_plan():
    from builtin_interfaces.msg import Time

    from nodes.contract import Tick, constant_message, take_output_marks
    from runtime.cdr.encode import ConstantTails
    from runtime.exchange import prepare_outputs

    take_output_marks()
    tails = ConstantTails()
    args = ("control", {"/plan": Path}, {"/plan": "/r1/plan"})
    plan = path_message(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 1.5]]), "map", 0.0)
    for k in range(3):  # marked at every step: encoded once, then stamped
        items = prepare_outputs(*args, Tick(k, k * 100_000_000), {"/plan": constant_message(plan)},
                                tails=tails)
        assert take_output_marks() is None  # taken by prepare_outputs
        plan_bytes = rclpy_bytes(plan)
        assert plan.header.stamp == Time(sec=0, nanosec=k * 100_000_000)
        assert items == [("/r1/plan", plan_bytes)]
        assert tails._last["/plan"][0] is plan
    plan.poses.pop()  # not marked at this step: encoded anew, whatever is kept
    items = prepare_outputs(*args, Tick(3, 300_000_000), {"/plan": plan}, tails=tails)
    assert items == [("/r1/plan", rclpy_bytes(plan))]
    replan = path_message(np.array([[5.0, 5.0], [6.0, 6.0]]), "map", 1.0)
    items = prepare_outputs(*args, Tick(4, 400_000_000), {"/plan": constant_message(replan)},
                            tails=tails)
    assert items == [("/r1/plan", rclpy_bytes(replan))]
    assert len(tails._last) == 1 and tails._last["/plan"][0] is replan  # the old plan let go
