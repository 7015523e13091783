"""The controllers file read as ros2_control reads it, once: one reading per file content
(an edited file is read again), several files merged in order as ros2_control_node merges
its ``--params-file`` files."""

from __future__ import annotations

import os

import yaml

from nodes.ros2_control.config import read_controllers_file

JTC = "joint_trajectory_controller/JointTrajectoryController"
JSB = "joint_state_broadcaster/JointStateBroadcaster"


def write(path, doc: dict):
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def manager(rate: int, **controllers: str) -> dict:
    return {"controller_manager": {"ros__parameters": {
        "update_rate": rate, **{n: {"type": t} for n, t in controllers.items()}}}}


def jtc(*joints: str, **more) -> dict:
    return {"jtc": {"ros__parameters": {"joints": list(joints),
                                        "command_interfaces": ["position"],
                                        "state_interfaces": ["position", "velocity"],
                                        **more}}}


def test_a_file_is_read_once_per_content_and_again_when_edited(tmp_path):
    path = write(tmp_path / "c.yaml", {**manager(50, jtc=JTC), **jtc("a", "b")})
    first = read_controllers_file(path)
    assert read_controllers_file(str(path)) is first  # the same reading, not a new one
    stat = path.stat()
    write(path, {**manager(25, jtc=JTC), **jtc("a", "b")})  # same size, maybe same mtime
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    again = read_controllers_file(path)
    assert again is not first and again.update_rate == 25


def test_several_files_merge_in_order_a_later_parameter_over_an_earlier(tmp_path):
    base = write(tmp_path / "base.yaml", {**manager(50, jtc=JTC), **jtc("a", "b")})
    extra = write(tmp_path / "extra.yaml", {
        "controller_manager": {"ros__parameters": {"update_rate": 100, "jsb": {"type": JSB}}},
        **jtc("c", "d")})
    merged = read_controllers_file(base, extra)
    assert merged.update_rate == 100
    assert [c.name for c in merged.controllers] == ["jtc", "jsb"]
    assert merged.named("jtc").params.joints == ["c", "d"]
    assert read_controllers_file(base).named("jtc").params.joints == ["a", "b"]
