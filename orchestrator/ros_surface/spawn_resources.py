"""What a SpawnEntity request asks to put into the world, read as an object
(``plan.events.ObjectSpec``): a small SDFormat or URDF model of one link whose collision (or
else visual) geometry is a box, cylinder, sphere or mesh, given as ``resource_string`` or
as a file (``uri``), or a mesh file (STL, OBJ, COLLADA) itself. Robots (several links, joints) are
not objects; they are refused with ``UNSUPPORTED_FORMAT``.

An SDFormat model is static when it says ``<static>true</static>``, else free with its
link's ``<inertial><mass>`` (1 kg, SDFormat's default, when it gives none); a URDF link is
free when it has an ``<inertial><mass>``, else static; a mesh file is static. Poses inside
the model (of its link, collision or visual) are not read: the object stands at the
request's ``initial_pose``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from pydantic import ValidationError
from simulation_interfaces.srv import SpawnEntity

from plan.events import ObjectSpec

R = SpawnEntity.Response
FORMATS = ["sdf", "urdf", "stl", "obj", "dae"]  # SimulatorFeatures.spawn_formats
MESHES = (".stl", ".obj", ".dae")  # ASCII STL and COLLADA converted (descriptions.mesh_convert)
FRAMES = ("", "world", "map", "odom")


class Refused(Exception):
    """A request that cannot be served: its result code and why."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def requested_object(request: SpawnEntity.Request, outside=None) -> tuple[str, ObjectSpec]:
    """(the name the resource gives, the object at the request's pose, named after the
    request or else that) of a SpawnEntity request; ``Refused`` naming the problem.
    ``outside(path)``: why the client may not name that file (its ``uri``, or a mesh its
    ``resource_string`` names), or None; asked before the file is looked at."""
    text, base, mesh = _resource(request, outside)
    pose = pose_of(request.initial_pose)
    if mesh is not None:
        found = {"name": "", "shape": "mesh", "mesh": str(mesh), "static": True}
    else:
        found = _model(text, base, outside)
    name = request.name or found.pop("name")
    found.pop("name", None)
    try:
        return name, ObjectSpec.model_validate({"name": name or "object", **found,
                                                "pose": pose})
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(p) for p in error["loc"])
        code = R.NAME_INVALID if where == "name" else R.RESOURCE_PARSE_ERROR
        raise Refused(code, f"{where or 'the object'}: {error['msg']}") from None


def _resource(request: SpawnEntity.Request, outside=None
              ) -> tuple[str, Path | None, Path | None]:
    """(model text, the folder its relative files are in, or a mesh file) of the request."""
    uri = request.uri
    if not uri:
        if not request.resource_string.strip():
            raise Refused(R.NO_RESOURCE, "neither uri nor resource_string is given.")
        return request.resource_string, None, None
    if "://" in uri and not uri.startswith("file://"):
        raise Refused(R.UNSUPPORTED_FORMAT, f"uri {uri!r}: only files are read (a path or "
                      "file://PATH; package:// and other schemes are not).")
    if outside is not None and (why := outside(uri)) is not None:
        raise Refused(R.NO_RESOURCE, f"uri {why}")
    path = Path(uri.removeprefix("file://")).expanduser()
    if not path.is_file():
        raise Refused(R.NO_RESOURCE, f"uri {uri!r}: no such file.")
    suffix = path.suffix.lower()
    if suffix in MESHES:
        return "", None, path.resolve()
    if suffix not in (".sdf", ".urdf", ".xml"):
        robot = (" (a robot enters through the scenario's events: robot: {name, start, "
                 "goal, description}; docs/how-to/world-events.md)"
                 if suffix in (".xacro", ".usd", ".usda", ".usdc") else "")
        raise Refused(R.UNSUPPORTED_FORMAT, f"uri {uri!r}: cosim spawns SDFormat or URDF "
                      f"models of one link, or mesh files ({', '.join(MESHES)}){robot}.")
    try:
        return path.read_text(), path.resolve().parent, None
    except (OSError, UnicodeDecodeError) as exc:
        raise Refused(R.RESOURCE_PARSE_ERROR, f"uri {uri!r} cannot be read: {exc}") from None


def pose_of(stamped) -> dict:
    """The object's pose from a PoseStamped: x, y, heading; z 0 means on the floor."""
    if stamped.header.frame_id not in FRAMES:
        raise Refused(R.INVALID_POSE, f"unknown frame {stamped.header.frame_id!r}: use world "
                      "(or '', map, odom: the same).")
    p, q = stamped.pose.position, stamped.pose.orientation
    values = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
    if not all(map(math.isfinite, values)):
        raise Refused(R.INVALID_POSE, "the pose is not finite.")
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    if norm == 0.0:
        q.w, norm = 1.0, 1.0  # an unset orientation: no rotation
    if abs(q.x) / norm > 1e-6 or abs(q.y) / norm > 1e-6:
        raise Refused(R.INVALID_POSE, "objects stand upright: give a heading only (a "
                      "rotation about z).")
    pose = {"x": p.x, "y": p.y, "yaw": 2 * math.atan2(q.z, q.w)}
    if p.z != 0.0:
        pose["z"] = p.z
    return pose


def _model(text: str, base: Path | None, outside=None) -> dict:
    """The object fields (and ``name``) of an SDFormat or URDF model of one link."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise Refused(R.RESOURCE_PARSE_ERROR, f"the model is not XML: {exc}.") from None
    if root.tag == "sdf":
        model = root.find("model")
        if model is None:
            raise Refused(R.UNSUPPORTED_FORMAT, "the SDFormat holds no <model> (worlds and "
                          "other elements are not spawned).")
        static = (model.findtext("static") or "false").strip().lower() in ("true", "1")
        fmt, name = "SDFormat", model.get("name", "")
    elif root.tag == "robot":
        model, fmt, name, static = root, "URDF", root.get("name", ""), None
    else:
        raise Refused(R.UNSUPPORTED_FORMAT, f"<{root.tag}> is neither SDFormat (<sdf>) nor "
                      "URDF (<robot>).")
    links = model.findall("link")
    if len(links) != 1 or model.findall("joint") or model.findall("include"):
        raise Refused(R.UNSUPPORTED_FORMAT, f"the {fmt} model has {len(links)} links and "
                      f"{len(model.findall('joint'))} joints: SpawnEntity takes objects of one "
                      "link; a robot enters through the scenario's events: (robot: {name, "
                      "start, goal, description}), planned so that its nodes run with it "
                      "(docs/how-to/world-events.md).")
    link = links[0]
    geometry = link.find("collision/geometry")
    if geometry is None:
        geometry = link.find("visual/geometry")
    if geometry is None or len(geometry) == 0:
        raise Refused(R.RESOURCE_PARSE_ERROR, f"the {fmt} link has no collision or visual "
                      "geometry.")
    out = {"name": name, **_geometry(geometry[0], fmt, base, outside)}
    mass = _mass(link, fmt)
    if fmt == "SDFormat":
        out["static"] = static
        if not static:
            out["mass"] = mass if mass is not None else 1.0
    else:
        out["static"] = mass is None
        if mass is not None:
            out["mass"] = mass
    colour = _colour(link, fmt)
    if colour is not None:
        out["rgba"] = colour
    return out


def _geometry(shape: ET.Element, fmt: str, base: Path | None, outside=None) -> dict:
    def numbers(text: str | None, what: str) -> list[float]:
        try:
            return [float(v) for v in (text or "").split()]
        except ValueError:
            raise Refused(R.RESOURCE_PARSE_ERROR, f"{what}: {text!r} is not numbers.") from None

    sdf = fmt == "SDFormat"
    if shape.tag == "box":
        return {"shape": "box", "size": numbers(shape.findtext("size") if sdf
                                                else shape.get("size"), "box size")}
    if shape.tag == "cylinder":
        r = shape.findtext("radius") if sdf else shape.get("radius")
        length = shape.findtext("length") if sdf else shape.get("length")
        return {"shape": "cylinder", "size": numbers(f"{r} {length}", "cylinder")}
    if shape.tag == "sphere":
        r = shape.findtext("radius") if sdf else shape.get("radius")
        return {"shape": "sphere", "size": numbers(r, "sphere radius")}
    if shape.tag == "mesh":
        uri = (shape.findtext("uri") if sdf else shape.get("filename")) or ""
        scale = numbers(shape.findtext("scale") if sdf else shape.get("scale"), "mesh scale")
        return {"shape": "mesh", "mesh": str(_mesh_file(uri, base, outside)),
                "scale": scale or [1.0, 1.0, 1.0]}
    raise Refused(R.UNSUPPORTED_FORMAT, f"<{shape.tag}> geometry: cosim spawns a box, "
                  "cylinder, sphere or mesh.")


def _mesh_file(uri: str, base: Path | None, outside=None) -> Path:
    """A model's mesh file; one a resource_string names (``base`` None) is the client's,
    asked of ``outside`` (a model file's own meshes are its author's)."""
    if "://" in uri and not uri.startswith("file://"):
        raise Refused(R.UNSUPPORTED_ASSETS, f"mesh {uri!r}: only files are read (a path or "
                      "file://PATH; package:// and model:// are not).")
    path = Path(uri.removeprefix("file://"))
    if not path.is_absolute():
        if base is None:
            raise Refused(R.MISSING_ASSETS, f"mesh {uri!r}: a resource_string's mesh needs "
                          "an absolute path.")
        path = base / path
    elif base is None and outside is not None and (why := outside(path)) is not None:
        raise Refused(R.MISSING_ASSETS, f"mesh {why}")
    if path.suffix.lower() not in MESHES:
        raise Refused(R.UNSUPPORTED_ASSETS, f"mesh {uri!r}: cosim reads {', '.join(MESHES)}.")
    if not path.is_file():
        raise Refused(R.MISSING_ASSETS, f"mesh {uri!r}: no such file ({path}).")
    return path.resolve()


def _mass(link: ET.Element, fmt: str) -> float | None:
    node = link.find("inertial/mass")
    if node is None:
        return None
    text = node.text if fmt == "SDFormat" else node.get("value")
    try:
        return float(text)
    except (TypeError, ValueError):
        raise Refused(R.RESOURCE_PARSE_ERROR, f"inertial mass {text!r} is not a number.") \
            from None


def _colour(link: ET.Element, fmt: str) -> list[float] | None:
    text = (link.findtext("visual/material/diffuse") if fmt == "SDFormat" else
            (link.find("visual/material/color").get("rgba")
             if link.find("visual/material/color") is not None else None))
    try:
        values = [float(v) for v in (text or "").split()]
    except ValueError:
        return None
    if len(values) == 3:
        values.append(1.0)
    return values if len(values) == 4 else None
