"""A URDF document read into plain data: links (inertial, visuals, collisions), joints
(kind, axis, limits), the ``<ros2_control>`` joints and their interfaces, the
``<gazebo reference=...>`` sensor tags and friction, and the controllers files a
gz_ros2_control or mujoco_ros2_control plugin tag names (``<parameters>``). Nothing here
loads MuJoCo."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from descriptions.description_error import DescriptionError

JOINT_KINDS = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
LIDAR_TYPES = ("ray", "gpu_ray", "lidar", "gpu_lidar")
CAMERA_TYPES = ("camera", "depth", "depth_camera", "rgbd_camera", "multicamera")


@dataclass
class UrdfLink:
    """A link: its mass (None without ``<inertial>``), principal inertia diagonal, and its
    visual and collision elements (kept as XML elements for the conversion)."""

    name: str
    mass: float | None
    inertia: tuple[float, float, float] | None
    visuals: list[ET.Element] = field(default_factory=list)
    collisions: list[ET.Element] = field(default_factory=list)


@dataclass
class UrdfJoint:
    """A joint: kind, parent and child links, axis and the ``<limit>`` values."""

    name: str
    kind: str
    parent: str
    child: str
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None
    mimic: str | None = None


@dataclass
class ControlJoint:
    """A joint of the ``<ros2_control>`` block: command and state interfaces, each command
    interface's ``min``/``max`` params (None when absent) and each state interface's
    ``initial_value`` param (where given)."""

    name: str
    commands: tuple[str, ...]
    states: tuple[str, ...]
    limits: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    initial: dict[str, float] = field(default_factory=dict)


@dataclass
class GazeboSensor:
    """A ``<gazebo reference="LINK"><sensor>`` tag: type, name, and its numbers."""

    link: str
    type: str
    name: str
    params: dict[str, float | int | str] = field(default_factory=dict)

    @property
    def kind(self) -> str | None:
        """cosim's sensor kind (lidar, camera, imu), None for a type cosim has not."""
        if self.type in LIDAR_TYPES:
            return "lidar"
        if self.type in CAMERA_TYPES:
            return "camera"
        return "imu" if self.type == "imu" else None


@dataclass
class Urdf:
    """The whole document: robot name, links and joints in file order, the root link,
    ros2_control joints, Gazebo sensors, per-link friction (``mu1``), the text of each
    ``<parameters>`` of its ros2_control plugin tag, in order (``controllers_files``), and
    the ``<ros2_control>`` blocks' ``<sensor>`` elements with their state interfaces
    (``control_sensors``: cosim gives them none, and says so)."""

    name: str
    links: dict[str, UrdfLink]
    joints: dict[str, UrdfJoint]
    root: str
    control: dict[str, ControlJoint]
    sensors: list[GazeboSensor]
    friction: dict[str, float]
    unsupported: list[str]
    controllers_files: list[str] = field(default_factory=list)
    control_sensors: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def children(self, link: str) -> list[UrdfJoint]:
        """The joints whose parent is ``link``."""
        return [j for j in self.joints.values() if j.parent == link]

    def parent_joint(self, link: str) -> UrdfJoint | None:
        """The joint whose child is ``link`` (None for the root)."""
        return next((j for j in self.joints.values() if j.child == link), None)


def parse_urdf(text: str, description: str) -> Urdf:
    """Read a URDF document; DescriptionError naming the link or joint for a broken tree."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DescriptionError(description, f"not well-formed XML: {exc}",
                               fix="correct the XML") from None
    if root.tag != "robot":
        raise DescriptionError(description, f"the root element is <{root.tag}>, not <robot>",
                               fix="a URDF's top element is <robot name=...>")
    links = {}
    for el in root.findall("link"):
        link = _link(el, description)
        if link.name in links:
            raise DescriptionError(description, "two links have this name", link=link.name,
                                   fix="give every link its own name")
        links[link.name] = link
    joints: dict[str, UrdfJoint] = {}
    for el in root.findall("joint"):
        joint = _joint(el, description, links)
        if joint.name in joints:
            raise DescriptionError(description, "two joints have this name", joint=joint.name,
                                   fix="give every joint its own name")
        joints[joint.name] = joint
    if not links:
        raise DescriptionError(description, "the robot has no <link>", fix="add links")
    children = {j.child for j in joints.values()}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise DescriptionError(
            description, f"the links form {len(roots)} trees (roots {roots}), not one",
            fix="connect every link to one root link by joints")
    parents = [j.child for j in joints.values()]
    twice = sorted({c for c in parents if parents.count(c) > 1})
    if twice:
        raise DescriptionError(description, "the link is the child of two joints",
                               link=twice[0], fix="a link has one parent joint")
    sensors, friction = _gazebo(root, description, links)
    unsupported = sorted({el.tag for el in root if el.tag not in (
        "link", "joint", "material", "gazebo", "ros2_control", "transmission", "mujoco")})
    return Urdf(root.get("name", ""), links, joints, roots[0], _ros2_control(root),
                sensors, friction, unsupported, _plugin_parameters(root),
                {s.get("name", ""): tuple(i.get("name", "") for i in s.findall("state_interface"))
                 for block in root.findall("ros2_control") for s in block.findall("sensor")})


def _floats(text: str | None, n: int, default: tuple[float, ...]) -> tuple[float, ...]:
    if text is None:
        return default
    values = tuple(float(v) for v in text.split())
    return values if len(values) == n else default


def _opt(el: ET.Element | None, attr: str) -> float | None:
    value = None if el is None else el.get(attr)
    return None if value is None else float(value)


def _link(el: ET.Element, description: str) -> UrdfLink:
    name = el.get("name")
    if not name:
        raise DescriptionError(description, "a <link> has no name", fix="name every link")
    inertial = el.find("inertial")
    mass = inertia = None
    if inertial is not None:
        mass = _opt(inertial.find("mass"), "value") or 0.0
        i = inertial.find("inertia")
        inertia = (0.0, 0.0, 0.0) if i is None else tuple(
            float(i.get(k, 0)) for k in ("ixx", "iyy", "izz"))
    return UrdfLink(name, mass, inertia, el.findall("visual"), el.findall("collision"))


def _joint(el: ET.Element, description: str, links: dict[str, UrdfLink]) -> UrdfJoint:
    name, kind = el.get("name", ""), el.get("type", "")
    if not name:
        raise DescriptionError(description, "a <joint> has no name", fix="name every joint")
    if kind not in JOINT_KINDS:
        raise DescriptionError(description, f"type {kind!r} is not a URDF joint type",
                               joint=name, fix=f"one of {', '.join(JOINT_KINDS)}")
    ends = {}
    for end in ("parent", "child"):
        e = el.find(end)
        link = None if e is None else e.get("link")
        if link not in links:
            raise DescriptionError(description, f"its {end} link {link!r} is not in the "
                                   "description", joint=name, fix="name an existing link")
        ends[end] = link
    axis_el = el.find("axis")
    axis = _floats(None if axis_el is None else axis_el.get("xyz"), 3, (1.0, 0.0, 0.0))
    limit = el.find("limit")
    mimic = el.find("mimic")
    return UrdfJoint(name, kind, ends["parent"], ends["child"], axis,
                     _opt(limit, "lower"), _opt(limit, "upper"), _opt(limit, "effort"),
                     _opt(limit, "velocity"), None if mimic is None else mimic.get("joint"))


def _param(el: ET.Element, name: str) -> float | None:
    for p in el.findall("param"):
        if p.get("name") == name and p.text and p.text.strip():
            try:
                return float(p.text)
            except ValueError:
                return None
    return None


def _ros2_control(root: ET.Element) -> dict[str, ControlJoint]:
    joints: dict[str, ControlJoint] = {}
    for block in root.findall("ros2_control"):
        for j in block.findall("joint"):
            commands = j.findall("command_interface")
            states = j.findall("state_interface")
            initial = {s.get("name", ""): _param(s, "initial_value") for s in states}
            joints[j.get("name", "")] = ControlJoint(
                j.get("name", ""), tuple(c.get("name", "") for c in commands),
                tuple(s.get("name", "") for s in states),
                {c.get("name", ""): (_param(c, "min"), _param(c, "max")) for c in commands},
                {k: v for k, v in initial.items() if v is not None})
    return joints


def _plugin_parameters(root: ET.Element) -> list[str]:
    """The ``<parameters>`` texts of the ros2_control simulator plugin, in file order: a
    ``<plugin>`` of a top-level ``<gazebo>`` (gz_ros2_control, gazebo_ros2_control,
    ign_ros2_control) or ``<mujoco>`` tag whose filename or name says ros2_control."""
    found = []
    for holder in [*root.findall("gazebo"), *root.findall("mujoco")]:
        for plugin in holder.iter("plugin"):
            named = (plugin.get("filename", "") + " " + plugin.get("name", "")).lower()
            if "ros2_control" in named:
                found += [p.text.strip() for p in plugin.findall("parameters")
                          if p.text and p.text.strip()]
    return found


def _number(text: str | None) -> float | int | None:
    if text is None or not text.strip():
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return int(value) if value.is_integer() and "." not in text else value


def _sensor_params(s: ET.Element) -> dict[str, float | int | str]:
    """The numbers cosim reads from a Gazebo sensor (classic ``<ray>`` or gz ``<lidar>``)."""
    wanted = {
        "update_rate": "update_rate",
        "ray/scan/horizontal/samples": "samples",
        "ray/scan/horizontal/min_angle": "min_angle",
        "ray/scan/horizontal/max_angle": "max_angle",
        "ray/range/min": "range_min", "ray/range/max": "range_max",
        "ray/noise/stddev": "noise_stddev",
        "lidar/scan/horizontal/samples": "samples",
        "lidar/scan/horizontal/min_angle": "min_angle",
        "lidar/scan/horizontal/max_angle": "max_angle",
        "lidar/range/min": "range_min", "lidar/range/max": "range_max",
        "lidar/noise/stddev": "noise_stddev",
        "camera/horizontal_fov": "horizontal_fov",
        "camera/image/width": "width", "camera/image/height": "height",
        "camera/clip/near": "near", "camera/clip/far": "far",
    }
    params: dict[str, float | int | str] = {}
    for path, key in wanted.items():
        value = _number(s.findtext(path))
        if value is not None:
            params[key] = value
    if "min_angle" in params and "max_angle" in params:
        params["fov"] = min(2 * math.pi, float(params["max_angle"]) - float(params["min_angle"]))
    return params


def _gazebo(root: ET.Element, description: str, links: dict[str, UrdfLink]
            ) -> tuple[list[GazeboSensor], dict[str, float]]:
    sensors, friction = [], {}
    for g in root.findall("gazebo"):
        ref = g.get("reference")
        if ref is None:
            continue
        if ref not in links:
            raise DescriptionError(description, f'a <gazebo reference="{ref}"> names a link '
                                   "that is not in the description", link=ref,
                                   fix="reference an existing link")
        mu = [_number(g.findtext(k)) for k in ("mu1", "mu2")]
        mu = [float(m) for m in mu if m is not None]
        if mu:
            friction[ref] = min(mu)
        for s in g.findall("sensor"):
            sensors.append(GazeboSensor(ref, s.get("type", ""), s.get("name", ref),
                                        _sensor_params(s)))
    return sensors, friction
