"""ROS 2 message definitions as Foxglove's ``ros2msg`` schemas and rosbridge type names.

A ``ros2msg`` schema is the type's ``.msg`` text followed by the definition of every type it
uses, each after a line of 80 ``=`` and ``MSG: pkg/msg/Name`` (the layout rosbag2 and MCAP
use). rosbags' Jazzy type store knows the common packages; any other type (the packages
built into the venv, a user's own) is read from ``<prefix>/share/<pkg>/msg/<Name>.msg``.
"""

from __future__ import annotations

import functools
import os
import re
import sys
import threading
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError

_lock = threading.Lock()
_UNKNOWN = re.compile(r"Type '([^']+)' is unknown")


def normalise_type(name: str) -> str:
    """'nav_msgs/Odometry' or 'nav_msgs/msg/Odometry' -> 'nav_msgs/msg/Odometry' (rosbridge
    clients write either); service types keep their 'srv'."""
    parts = name.strip().strip("/").split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts)


def same_type(given: str, expected: str, kind: str = "msg") -> bool:
    """Whether a client's type name names ``expected`` (with or without the 'msg'/'srv')."""
    parts = given.strip().strip("/").split("/")
    if len(parts) == 2:
        parts.insert(1, kind)
    return "/".join(parts) == expected


@functools.cache
def _store():
    return get_typestore(Stores.ROS2_JAZZY)


def share_dirs() -> list[Path]:
    """Where installed ROS packages keep their definitions: the venv's share/ and the
    prefixes of AMENT_PREFIX_PATH."""
    prefixes = [Path(sys.prefix)]
    prefixes += [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [p / "share" for p in prefixes]


def _definition_file(package: str, kind: str, name: str) -> Path:
    for share in share_dirs():
        path = share / package / kind / f"{name}.{kind}"
        if path.is_file():
            return path
    raise LookupError(f"no definition of {package}/{kind}/{name} under "
                      f"{', '.join(str(s) for s in share_dirs())}")


def _register(typename: str, text: str) -> None:
    _store().register(get_types_from_msg(text, typename))


def _generate(typename: str) -> str:
    """The concatenated definition, loading unknown dependencies from share/ as needed."""
    with _lock:
        for _ in range(100):
            try:
                text, _ = _store().generate_msgdef(typename, ros_version=2)
                return text
            except TypesysError as exc:
                match = _UNKNOWN.search(str(exc))
                if not match:
                    raise
                missing = normalise_type(match.group(1))
                package, _, name = missing.split("/")
                _register(missing, _definition_file(package, "msg", name).read_text())
        raise LookupError(f"{typename}: too many nested unknown types")


@functools.cache
def message_schema(typename: str) -> str:
    """The ``ros2msg`` schema of 'pkg/msg/Name'."""
    return _generate(normalise_type(typename))


@functools.cache
def service_schemas(typename: str) -> tuple[str, str]:
    """(request, response) ``ros2msg`` schemas of service 'pkg/srv/Name'."""
    package, _, name = typename.split("/")
    text = _definition_file(package, "srv", name).read_text()
    request, response = re.split(r"^---[ \t]*$", text, maxsplit=1, flags=re.MULTILINE)
    out = []
    for part, body in (("Request", request), ("Response", response)):
        # rosbags names only 'msg' types; the part's own name never appears in its schema
        part_type = f"{package}/msg/{name}_{part}"
        with _lock:
            if part_type not in _store().fielddefs:
                _register(part_type, body)
        out.append(_generate(part_type))
    return out[0], out[1]
