"""``cosim-describe``: load a robot description the way a run loads it and say what cosim
made of it (links and frames, joints and their command interfaces, the drive, sensors,
what the conversion changed or dropped), optionally with a picture of the robot and its
frames rendered off screen. What ``check_urdf`` and ``urdf_to_graphviz`` are to ROS users.

    cosim-describe robot.urdf.xacro [--arg k:=v] [--package name=path] [--wheels L,R]
                   [--base auto|free|fixed] [--sensor kind=link] [--picture out.png]
    cosim-describe robot.usda [--wheels L,R] [--base ...] [--sensor kind=link] [--picture ...]
    cosim-describe scenario.yaml [--picture out.png]   # robots.description and robots.urdf
                                                       # (robots.usd for a USD description)

Exit 0 when it loads, 2 (with the reason) when it does not.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: render off screen

from descriptions.description_error import DescriptionError  # noqa: E402
from descriptions.packages import PackageResolver  # noqa: E402
from descriptions.readers import (  # noqa: E402
    URDF,
    describing_reader,
    is_usd_file,
    load_with_options,
    section_options,
)
from descriptions.urdf import LoadedUrdf, UrdfOptions, guess_wheels  # noqa: E402
from descriptions.urdf_parse import parse_urdf  # noqa: E402
from descriptions.xacro_expand import expand  # noqa: E402


def _pairs(values: list[str], sep: str, what: str) -> dict[str, str]:
    out = {}
    for value in values:
        key, found, rest = value.partition(sep)
        if not found or not key:
            raise SystemExit(f"cosim-describe: {what} {value!r} is not NAME{sep}VALUE")
        out[key] = rest
    return out


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line."""
    p = argparse.ArgumentParser(prog="cosim-describe", description=__doc__.split("\n\n")[0])
    p.add_argument("description", type=Path, help=".urdf, .xacro or .urdf.xacro, a USD "
                   "robot (.usd, .usda, .usdc), or a scenario .yaml whose robots: names one "
                   "(read with its robots.urdf or robots.usd)")
    p.add_argument("--arg", action="append", default=[], metavar="NAME:=VALUE",
                   help="a xacro argument (repeatable)")
    p.add_argument("--package", action="append", default=[], metavar="NAME=PATH",
                   help="where a ROS package is (repeatable; before AMENT_PREFIX_PATH, "
                        "ROS_PACKAGE_PATH)")
    p.add_argument("--wheels", metavar="LEFT,RIGHT",
                   help="the two drive wheel joints (default: guessed from joint names)")
    p.add_argument("--no-drive", action="store_true", help="no drive even if wheels are found")
    p.add_argument("--base", choices=("auto", "free", "fixed"), default="auto")
    p.add_argument("--sensor", action="append", default=[], metavar="KIND=LINK",
                   help="a lidar, camera or imu on a link (repeatable)")
    p.add_argument("--picture", type=Path, metavar="PNG", help="render the robot to this PNG")
    return p.parse_args(argv)


def from_scenario(ns: argparse.Namespace) -> tuple[Path, UrdfOptions]:
    """The description and its settings as a scenario's ``robots:`` section gives them
    (``robots.description`` and ``robots.urdf`` or ``robots.usd``; without a description, the
    USD robot the world's prims reference), read as the run reads them."""
    import yaml

    scenario = ns.description.resolve()
    doc = yaml.safe_load(scenario.read_text()) or {}
    robots = doc.get("robots") or {}
    if robots.get("description"):
        description = (scenario.parent / robots["description"]).resolve()
    else:  # the robot described in USD that the world's prims reference, if one
        description = _stage_robot(scenario.parent / str(doc.get("world", "")))
        if description is None:
            raise SystemExit(f"cosim-describe: {scenario}: no robots.description to describe")
    key = describing_reader(description).settings_key
    return description, section_options(description, robots.get(key), scenario.parent)


def _stage_robot(world: Path) -> Path | None:
    """The one USD robot file the prims of a USD world reference (None: none, or several)."""
    from descriptions.worldfile import open_stage, usd_robot_mounts

    if not is_usd_file(world) or not world.is_file():
        return None
    files = {m.mjcf for m in usd_robot_mounts(open_stage(world))}
    return files.pop() if len(files) == 1 else None


def options_of(ns: argparse.Namespace) -> UrdfOptions:
    """UrdfOptions from the command line; wheels guessed when none are named."""
    options = UrdfOptions(args=_pairs(ns.arg, ":=", "--arg"),
                          packages=_pairs(ns.package, "=", "--package"),
                          base=ns.base, sensors=_pairs(ns.sensor, "=", "--sensor"))
    wheels = None
    if ns.wheels:
        wheels = tuple(w.strip() for w in ns.wheels.split(","))
    elif not ns.no_drive and describing_reader(ns.description) is URDF:
        resolver = PackageResolver(dict(options.packages))
        text = expand(ns.description, options.args, resolver).urdf
        wheels = guess_wheels(parse_urdf(text, str(ns.description)))
    elif not ns.no_drive:  # another format: read once without a drive to see its joints
        wheels = guess_wheels(load_with_options(ns.description, options).urdf)
    return UrdfOptions(**{**options.__dict__, "wheels": wheels})


def _fmt(x: float | None) -> str:
    return "-" if x is None else f"{x:g}"


def account(loaded: LoadedUrdf, options: UrdfOptions) -> str:
    """The readable account of a loaded description."""
    m, urdf = loaded.model, loaded.urdf
    lines = [f"robot {urdf.name!r} from {m.source}"]
    if options.args:
        lines.append("  xacro args: " + " ".join(f"{k}:={v}" for k, v in options.args.items()))
    base = (f"mobile: a free joint '{m.base_link}_free' on the root link" if m.mobile
            else "fixed to the world")
    lines += [f"base link: {m.base_link} ({base})",
              f"footprint radius: {m.footprint_radius:.3f} m (from the collision geometry)",
              "", f"links ({len(m.links)}), every one a TF frame and a MuJoCo body and site:"]

    def tree(link: str, depth: int) -> None:
        joint = urdf.parent_joint(link)
        info = urdf.links[link]
        mass = "no inertial" if info.mass is None else f"{info.mass:g} kg"
        how = "" if joint is None else f"  <- {joint.kind} joint {joint.name}"
        what = (f"{mass}, {len(info.collisions)} collision, {len(info.visuals)} visual"
                if link != "world" or joint else "the world where the robot is placed: a "
                "site, not a body")
        lines.append(f"  {'  ' * depth}{link}  [{what}]{how}")
        for child in urdf.children(link):
            tree(child.child, depth + 1)

    tree(urdf.root, 0)
    commanded = {a.joint: a for a in m.actuated}
    wheels = () if m.drive is None else (m.drive.left_joint, m.drive.right_joint)
    moving = [j for j in urdf.joints.values() if j.kind != "fixed"]
    lines += ["", f"moving joints ({len(moving)}):"]
    for j in moving:
        limits = f"[{_fmt(j.lower)}, {_fmt(j.upper)}]" if j.kind != "continuous" else "unlimited"
        what = "not commanded"
        if j.name in commanded:
            a = commanded[j.name]
            how = a.interface if not a.modes else (
                f"{' or '.join(m.interface for m in a.modes)} (one actuator, its mode "
                "switched to the interface an activated controller claims)")
            what = (f"command {how} -> actuator {a.actuator}; state "
                    f"{'/'.join(a.state_interfaces)}")
        elif j.name in wheels:
            side = "left" if j.name == wheels[0] else "right"
            what = f"{side} drive wheel -> velocity actuator {j.name}_velocity"
        lines.append(f"  {j.name}: {j.kind} {limits}, axis {' '.join(f'{v:g}' for v in j.axis)}"
                     f", effort {_fmt(j.effort)}, velocity {_fmt(j.velocity)}: {what}")
    lines.append("")
    if m.drive is None:
        lines.append("drive: none")
    else:
        d = m.drive
        src = "given" if options.wheel_radius is not None else "read from the wheels' geometry"
        lines.append(f"drive: differential, wheels {d.left_joint} (left) and {d.right_joint} "
                     f"(right), radius {d.wheel_radius:.4f} m, separation "
                     f"{d.wheel_separation:.4f} m ({src})")
    lines.append(f"sensors ({len(m.sensors)}):" if m.sensors else "sensors: none")
    for s in m.sensors:
        params = ", ".join(f"{k} {v:g}" if not isinstance(v, str) else f"{k} {v}"
                           for k, v in s.params) or "cosim's defaults"
        lines.append(f"  {s.kind} {s.name!r} on link {s.link} (MuJoCo {s.mujoco_name}): {params}")
    lines += ["", "converted or dropped:" if loaded.notes else "converted or dropped: nothing"]
    lines += [f"  - {n}" for n in loaded.notes]
    return "\n".join(lines)


def picture(loaded: LoadedUrdf, out: Path, width: int = 640, height: int = 480) -> None:
    """Render the robot on a floor with every link's frame (x red, y green, z blue) and
    name, collision geometry translucent over the visuals, to a PNG."""
    import mujoco
    from matplotlib import image

    spec = loaded.spec.copy()
    alone = spec.compile()  # where the robot is and how big, before the floor is added
    centre, extent = alone.stat.center.copy(), float(alone.stat.extent)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.01],
                            rgba=[0.85, 0.85, 0.8, 1])
    spec.worldbody.add_light(pos=[1, -1, 3], dir=[-0.3, 0.3, -1], diffuse=[0.8, 0.8, 0.8])
    spec.visual.headlight.ambient = [0.4, 0.4, 0.4]
    model = spec.compile()
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    model.vis.scale.framelength = 0.15 * extent / max(model.stat.meansize, 1e-3)
    model.vis.scale.framewidth = 0.01 * extent / max(model.stat.meansize, 1e-3)
    for g in range(model.ngeom):
        if model.geom_group[g] == 3:
            model.geom_rgba[g, 3] = 0.35
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 0, 0, 1, 1, 0]
    option.sitegroup[:] = [0, 0, 0, 0, 0, 1]
    option.frame = mujoco.mjtFrame.mjFRAME_SITE
    option.label = mujoco.mjtLabel.mjLABEL_SITE
    camera = mujoco.MjvCamera()
    camera.lookat[:] = centre
    camera.distance = 1.5 * extent
    camera.azimuth, camera.elevation = 135.0, -25.0
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.update_scene(data, camera=camera, scene_option=option)
        image.imsave(out, renderer.render())


def main(argv: list[str] | None = None) -> int:
    """Print the account (and write the picture); 2 when the description does not load."""
    ns = parse_args(argv)
    try:
        if ns.description.suffix.lower() in (".yaml", ".yml"):
            ns.description, options = from_scenario(ns)
        else:
            options = options_of(ns)
        loaded = load_with_options(ns.description, options)
    except DescriptionError as exc:
        print(f"cosim-describe: {exc}", file=sys.stderr)
        return 2
    print(account(loaded, options))
    if ns.picture:
        picture(loaded, ns.picture)
        print(f"\npicture: {ns.picture}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
