"""URDF and xacro robot descriptions (descriptions/): packages, xacro, the MuJoCo conversion,
the robot model and the errors, on cosim's two test robots under scenarios/robots/ and on
small broken descriptions written here. In-process: no ROS traffic."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from descriptions.description_error import DescriptionError
from descriptions.packages import PackageNotFound, PackageResolver
from descriptions.urdf import UrdfOptions, load_urdf
from descriptions.xacro_expand import expand

ROOT = Path(__file__).resolve().parent.parent
ROBOTS = ROOT / "scenarios" / "robots"
BOT = ROBOTS / "mybot_description" / "urdf" / "mybot.urdf.xacro"
ARM = ROBOTS / "myarm_description" / "urdf" / "myarm.urdf.xacro"
PACKAGES = {"mybot_description": str(ROBOTS / "mybot_description"),
            "myarm_description": str(ROBOTS / "myarm_description")}
WHEELS = ("wheel_left_joint", "wheel_right_joint")
INERTIAL = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" '
            'ixz="0" iyz="0"/></inertial>')


def bot(**kw) -> UrdfOptions:
    return UrdfOptions(packages=PACKAGES, wheels=WHEELS, env={}, **kw)


@pytest.fixture(scope="module")
def mybot():
    return load_urdf(BOT, bot())


@pytest.fixture(scope="module")
def myarm():
    return load_urdf(ARM, UrdfOptions(packages=PACKAGES, env={}))


def write_urdf(tmp_path: Path, body: str, name: str = "r.urdf") -> Path:
    path = tmp_path / name
    path.write_text(f'<robot name="r">{body}</robot>')
    return path


# -- packages --------------------------------------------------------------------------

def test_packages_map_first_then_ament_prefix_then_ros_package_path(tmp_path):
    prefix = tmp_path / "install"
    (prefix / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (prefix / "share" / "ament_index" / "resource_index" / "packages" / "pkg_a").touch()
    (prefix / "share" / "pkg_a").mkdir()
    src = tmp_path / "src" / "deep" / "folder_b"
    src.mkdir(parents=True)
    (src / "package.xml").write_text("<package><name>pkg_b</name></package>")
    env = {"AMENT_PREFIX_PATH": str(prefix), "ROS_PACKAGE_PATH": str(tmp_path / "src")}
    resolver = PackageResolver({"pkg_c": str(tmp_path)}, env)
    assert resolver.find("pkg_a") == (prefix / "share" / "pkg_a").resolve()
    assert resolver.find("pkg_b") == src.resolve()  # by package.xml's <name>, not the folder
    assert resolver.find("pkg_c") == tmp_path.resolve()
    mapped = PackageResolver({"pkg_a": str(src)}, env)
    assert mapped.find("pkg_a") == src.resolve()  # the map wins over AMENT_PREFIX_PATH
    assert mapped.resolve_uri("package://pkg_a/meshes/x.stl", tmp_path) == \
        src.resolve() / "meshes" / "x.stl"
    with pytest.raises(PackageNotFound, match="'nope'.*AMENT_PREFIX_PATH.*ROS_PACKAGE_PATH"):
        resolver.find("nope")


# -- xacro -----------------------------------------------------------------------------

def test_xacro_expands_with_args_and_find():
    text = expand(BOT, {"lidar_samples": "720", "with_camera": "false"},
                  PackageResolver(PACKAGES, {})).urdf
    assert "<samples>720</samples>" in text
    assert '<link name="camera_link"' not in text
    assert 'name="wheel_left_joint"' in text  # from the macro of the $(find)-included file
    assert "package://mybot_description/meshes/wheel.stl" in text  # left for the loader


def test_the_expanded_urdf_does_not_depend_on_where_the_package_lies(tmp_path):
    """/robot_description is in every digest: the same robot expanded from two places is
    the same text (xacro's banner names the file, not its absolute path)."""
    import shutil

    pkg = ROOT / "scenarios" / "robots" / "mybot_description"
    elsewhere = tmp_path / "somewhere" / "mybot_description"
    shutil.copytree(pkg, elsewhere)
    texts = [expand(where / "urdf" / "mybot.urdf.xacro", {"lidar_samples": "360"},
                    PackageResolver({"mybot_description": where})).urdf
             for where in (pkg, elsewhere)]
    assert texts[0] == texts[1] and str(pkg) not in texts[0]


def test_xacro_error_carries_xacros_message(tmp_path):
    path = tmp_path / "bad.urdf.xacro"
    path.write_text('<robot name="b" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                    '<link name="${undefined_thing}"/></robot>')
    with pytest.raises(DescriptionError, match="xacro error:.*undefined_thing") as exc:
        expand(path)
    assert str(path) in str(exc.value)


def test_an_argument_the_xacro_does_not_declare_is_refused_naming_those_it_does(tmp_path):
    with pytest.raises(DescriptionError, match="'wheel_raduis' is not declared by the "
                       "description.*declares: lidar_samples, with_camera, with_imu") as exc:
        expand(BOT, {"wheel_raduis": "0.08"}, PackageResolver(PACKAGES, {}))
    assert exc.value.arg == "wheel_raduis"
    # an argument read by $(arg) without a declaration is xacro's command-line kind: taken
    path = tmp_path / "r.urdf.xacro"
    path.write_text('<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                    '<xacro:arg name="size" default="1"/>'
                    '<link name="$(arg prefix)base"/></robot>')
    assert '<link name="p_base"/>' in expand(path, {"prefix": "p_", "size": "2"}).urdf
    with pytest.raises(DescriptionError, match="'sise', 'prefx' are not declared.*: size$"):
        expand(path, {"prefix": "p_", "sise": "2", "prefx": "q_"})


def test_unknown_package_in_find_names_it():
    with pytest.raises(DescriptionError, match=r"\$\(find mybot_description\).*packages:"):
        expand(BOT, {}, PackageResolver({}, {}))


# -- the diff-drive robot --------------------------------------------------------------

def test_mybot_keeps_every_link_as_a_body_and_site(mybot):
    model = mybot.spec.compile()
    links = [k.name for k in mybot.model.links]
    assert links == ["base_footprint", "base_link", "wheel_left_link", "wheel_right_link",
                     "caster_front_link", "caster_back_link", "base_scan", "imu_link",
                     "camera_link", "camera_optical_frame"]
    for name in links:
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0, name
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0, name
    assert mybot.model.mobile and mybot.model.base_link == "base_footprint"
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert [j.name for j in mybot.model.joints if j.kind == "continuous"] == list(WHEELS)


def test_mybot_drive_sensors_and_footprint_from_the_description(mybot):
    drive = mybot.model.drive
    assert (drive.left_joint, drive.right_joint) == WHEELS
    assert drive.wheel_radius == pytest.approx(0.06, abs=1e-4)
    assert drive.wheel_separation == pytest.approx(0.40, abs=1e-4)
    assert mybot.model.footprint_radius == pytest.approx(math.hypot(0.22, 0.06), abs=2e-3)
    lidar = mybot.model.sensor("lidar")
    assert (lidar.name, lidar.link) == ("lds_lidar", "base_scan")
    params = dict(lidar.params)
    assert params["samples"] == 360 and params["range_min"] == 0.12
    assert params["range_max"] == 12.0 and params["update_rate"] == 10
    assert params["fov"] == pytest.approx(2 * math.pi, abs=1e-4)
    assert mybot.model.sensor("imu").link == "imu_link"
    camera = mybot.model.sensor("camera")
    assert camera.link == "camera_link" and dict(camera.params)["width"] == 160
    model = mybot.spec.compile()
    for name in ("imu_link_gyro", "imu_link_accel", "imu_link_quat"):
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name) >= 0
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera_link")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # a Gazebo camera looks along its link's +x: MuJoCo's camera looks along its -z
    assert -data.cam_xmat[cam].reshape(3, 3)[:, 2] == pytest.approx([1, 0, 0], abs=1e-6)
    assert mybot.model.scoped("robot_1").sensor("lidar").mujoco_name == "robot_1/base_scan"


def test_mybot_dae_visual_replaced_with_a_note_and_geoms_grouped(mybot):
    assert any("chassis_visual.dae" in n and "collision geometry" in n for n in mybot.notes)
    model = mybot.spec.compile()
    visual = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "base_link_visual_0")
    collision = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "base_link_collision_0")
    assert model.geom_type[visual] == model.geom_type[collision] == mujoco.mjtGeom.mjGEOM_MESH
    assert set(model.geom_group.tolist()) == {3, 4}  # unseen by cosim's lidar (groups 0-2)
    caster = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "caster_front_link_collision_0")
    assert model.geom_friction[caster][0] == 0.0  # Gazebo <mu1>0</mu1>


def test_mybot_drives_forward_on_a_floor(mybot):
    spec = mybot.spec.copy()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1])
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:] = 5.0  # both wheels 5 rad/s: 0.3 m/s forward
    while data.time < 2.0:
        mujoco.mj_step(model, data)
    x, y = data.qpos[0], data.qpos[1]
    assert 0.4 < x < 0.7 and abs(y) < 0.02, (x, y)
    assert abs(data.qpos[2]) < 0.01  # base_footprint stays on the floor


# -- the arm ---------------------------------------------------------------------------

def test_myarm_interfaces_limits_and_meshes(myarm):
    m = myarm.model
    assert not m.mobile and m.drive is None
    assert [(a.joint, a.interface) for a in m.actuated] == [
        ("shoulder_pan", "position"), ("shoulder_lift", "position"), ("elbow", "position"),
        ("wrist_1", "position"), ("wrist_2", "velocity"), ("wrist_3", "effort")]
    assert m.actuated[5].state_interfaces == ("position", "velocity", "effort")
    model = myarm.spec.compile()
    assert model.njnt == 6  # fixed to the world: no free joint
    def act(name):
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
    assert model.actuator_ctrlrange[act("elbow_position")] == pytest.approx([-2.6, 2.6])
    assert model.actuator_forcerange[act("elbow_position")] == pytest.approx([-40, 40])
    assert model.actuator_ctrlrange[act("wrist_2_velocity")] == pytest.approx([-3, 3])
    assert model.actuator_ctrlrange[act("wrist_3_effort")] == pytest.approx([-2, 2])  # min/max
    assert model.nmesh == 6  # STL base, the scaled link STL four times, the OBJ wrist
    assert model.nexclude == 7  # adjacent links never collide (the base is welded to the world)
    joint = next(j for j in m.joints if j.name == "shoulder_lift")
    assert (joint.limits.lower, joint.limits.upper, joint.limits.velocity) == (-2.0, 2.0, 2.0)


def test_myarm_position_servo_reaches_its_target_and_gains_are_settable(myarm):
    model = myarm.spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "elbow_position")] = 0.5
    while data.time < 3.0:
        mujoco.mj_step(model, data)
    elbow = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "elbow")]
    assert data.qpos[elbow] == pytest.approx(0.5, abs=0.1)  # kp 60 against gravity
    soft = load_urdf(ARM, UrdfOptions(packages=PACKAGES, env={},
                                      gains={"elbow": {"kp": 5.0}, "position": {"kv": 1.0}}))
    soft_model = soft.spec.compile()
    a = mujoco.mj_name2id(soft_model, mujoco.mjtObj.mjOBJ_ACTUATOR, "elbow_position")
    b = mujoco.mj_name2id(soft_model, mujoco.mjtObj.mjOBJ_ACTUATOR, "wrist_1_position")
    assert soft_model.actuator_gainprm[a][0] == 5.0 and soft_model.actuator_gainprm[b][0] == 60
    assert soft_model.actuator_biasprm[b][2] == -1.0  # kv from the interface's gains


# -- errors ----------------------------------------------------------------------------

def test_missing_mesh_names_the_link_and_path(tmp_path):
    path = write_urdf(tmp_path, f'<link name="base">{INERTIAL}<collision><geometry>'
                      '<mesh filename="meshes/gone.stl"/></geometry></collision></link>')
    with pytest.raises(DescriptionError, match=r"link 'base'.*gone\.stl.*does not exist") as e:
        load_urdf(path)
    assert e.value.link == "base" and e.value.path == str(tmp_path / "meshes" / "gone.stl")


def test_unknown_package_in_mesh_names_the_link(tmp_path):
    path = write_urdf(tmp_path, f'<link name="base">{INERTIAL}<visual><geometry>'
                      '<mesh filename="package://ghost_pkg/m.stl"/></geometry></visual></link>')
    with pytest.raises(DescriptionError, match=r"link 'base'.*ghost_pkg.*not found"):
        load_urdf(path, UrdfOptions(env={}))


def test_massless_moving_link_is_named_with_the_fix(tmp_path):
    path = write_urdf(tmp_path, f'<link name="base">{INERTIAL}</link><link name="arm"/>'
                      '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
                      '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')
    with pytest.raises(DescriptionError, match=r"link 'arm'.*no <inertial>.*joint 'j'.*Fix"):
        load_urdf(path)


def test_bad_wheels_and_sensor_links_are_named(tmp_path):
    with pytest.raises(DescriptionError, match="joint 'nope'.*not in the description"):
        load_urdf(BOT, bot().__class__(packages=PACKAGES, env={}, wheels=("nope", "x")))
    with pytest.raises(DescriptionError, match="joint 'scan_joint'.*fixed: it does not turn"):
        load_urdf(BOT, UrdfOptions(packages=PACKAGES, env={},
                                   wheels=("scan_joint", "wheel_right_joint")))
    with pytest.raises(DescriptionError, match="link 'laser'.*not in the description"):
        load_urdf(BOT, bot(sensors={"lidar": "laser"}))


def test_collada_collision_mesh_is_an_error(tmp_path):
    (tmp_path / "m.dae").write_text("<COLLADA/>")
    path = write_urdf(tmp_path, f'<link name="base">{INERTIAL}<collision><geometry>'
                      '<mesh filename="m.dae"/></geometry></collision></link>')
    with pytest.raises(DescriptionError, match="link 'base'.*collision mesh 'm.dae'.*does not "
                       "read.*binary STL or OBJ"):
        load_urdf(path)


# -- cosim-describe --------------------------------------------------------------------

@pytest.mark.parametrize("robot,expect", [
    (BOT, ["drive: differential", "radius 0.0600 m, separation 0.4000 m",
           "lidar 'lds_lidar' on link base_scan", "samples 90", "chassis_visual.dae",
           "camera_optical_frame"]),
    (ARM, ["fixed to the world", "command effort -> actuator wrist_3_effort",
           "command velocity -> actuator wrist_2_velocity", "tool0"])])
def test_describe_prints_an_account_and_a_picture(tmp_path, robot, expect):
    png = tmp_path / "robot.png"
    args = [sys.executable, "-m", "descriptions.describe", str(robot), "--picture", str(png),
            "--arg", "lidar_samples:=90"] if robot == BOT else [
        sys.executable, "-m", "descriptions.describe", str(robot), "--picture", str(png)]
    for name, path in PACKAGES.items():
        args += ["--package", f"{name}={path}"]
    out = subprocess.run(args, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    for text in expect:
        assert text in out.stdout, text
    from matplotlib import image
    pixels = image.imread(png)
    assert pixels.shape[:2] == (480, 640) and np.std(pixels[..., :3]) > 0.05


def test_describe_exits_2_naming_the_problem(tmp_path):
    out = subprocess.run([sys.executable, "-m", "descriptions.describe", str(BOT)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT,
                         env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)})
    assert out.returncode == 2
    assert "$(find mybot_description)" in out.stderr and "packages:" in out.stderr


# -- what robot_state_publisher would publish ---------------------------------------------

def test_urdf_frames_and_joint_states_under_the_urdfs_own_names(mybot):
    from descriptions.robot_state import RobotStateFrames

    spec = mujoco.MjSpec()
    spec.copy_during_attach = True
    frame = spec.worldbody.add_frame(pos=[1.0, 2.0, 0.0])
    spec.attach(mybot.spec, frame=frame, prefix="robot_1/")
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    frames = RobotStateFrames(model, mybot.model.scoped("robot_1"))
    static = {(t.parent, t.child): t for t in frames.static(data)}
    scan = static[("robot_1/base_link", "robot_1/base_scan")]
    assert scan.pos == pytest.approx((0.08, 0, 0.14)) and scan.quat == pytest.approx((1, 0, 0, 0))
    optical = static[("robot_1/camera_link", "robot_1/camera_optical_frame")]
    assert optical.quat == pytest.approx((0.5, -0.5, 0.5, -0.5), abs=1e-6)  # rpy -pi/2 0 -pi/2
    assert len(static) == 7
    moving = {(t.parent, t.child): t for t in frames.moving(data)}
    base = frames.base(data)
    assert (base.parent, base.child) == ("robot_1/odom", "robot_1/base_footprint")
    assert base.pos == pytest.approx((1, 2, 0)) and frames.has_moving
    assert ("robot_1/base_link", "robot_1/wheel_left_link") in moving
    states = frames.joint_states(data)
    assert states.names == WHEELS and states.position == (0.0, 0.0)


def test_a_world_root_link_is_the_world(tmp_path):
    from descriptions.robot_state import RobotStateFrames

    path = write_urdf(tmp_path, '<link name="world"/><joint name="fix" type="fixed">'
                      '<parent link="world"/><child link="base"/><origin xyz="0 0 0.5"/>'
                      f'</joint><link name="base">{INERTIAL}</link>')
    loaded = load_urdf(path)
    assert not loaded.model.mobile and loaded.model.base_link == "base"
    model = loaded.spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    (fix,) = RobotStateFrames(model, loaded.model).static(data)
    assert (fix.parent, fix.child, fix.pos) == ("world", "base", (0.0, 0.0, 0.5))
    with pytest.raises(DescriptionError, match="root link is 'world'"):
        load_urdf(path, UrdfOptions(base="free"))


def test_scenario_urdf_settings_become_options_and_errors_exit_2():
    from descriptions.description_error import scenario_error
    from descriptions.urdf_robot import layout_settings, layout_urdf_robot, options_of, urdf_options
    from plan.description_spec import UrdfSpec

    spec = UrdfSpec.model_validate({
        "args": {"lidar_samples": 180}, "packages": {"mybot_description":
                                                     "robots/mybot_description"},
        "wheels": ["wheel_left_joint", "wheel_right_joint"], "sensors": {"imu": "imu_link"},
        "gains": {"wheel": {"kv": 3}}})
    options = urdf_options(spec, ROOT / "scenarios")
    assert options.packages["mybot_description"] == str(ROBOTS / "mybot_description")
    settings = layout_settings(spec, ROOT / "scenarios")  # what the layout carries
    assert options_of(settings) == options
    loaded = layout_urdf_robot(BOT, settings)
    assert layout_urdf_robot(BOT, settings) is loaded  # once per process
    assert loaded.model.settings == settings
    assert dict(loaded.model.sensor("lidar").params)["samples"] == 180
    model = loaded.spec.compile()
    assert model.actuator_gainprm[0][0] == 3.0
    try:
        layout_urdf_robot(BOT, layout_settings(None, ROOT / "scenarios"))
    except DescriptionError as exc:
        err = scenario_error(exc, "nav_urdf.yaml", "robots.description")
    assert str(err).startswith("nav_urdf.yaml: robots.description: robot description ")


def test_a_urdf_that_uses_xacro_is_expanded(tmp_path):
    # TurtleBot3's .urdf files are xacro (a namespace arg), as launch files run xacro on them
    path = tmp_path / "tb.urdf"
    path.write_text('<robot name="tb" xmlns:xacro="http://ros.org/wiki/xacro">'
                    '<xacro:arg name="namespace" default=""/>'
                    '<link name="$(arg namespace)base"/></robot>')
    assert '<link name="r1_base"/>' in expand(path, {"namespace": "r1_"}).urdf
    plain = write_urdf(tmp_path, '<link name="base"/>', "plain.urdf")
    with pytest.raises(DescriptionError, match="xacro arguments given for a plain .urdf"):
        expand(plain, {"x": "1"})


@pytest.mark.parametrize("scenario", ["nav_urdf.yaml", "nav_usd_robot.yaml"])
def test_describe_takes_the_options_the_run_takes(scenario):
    # one way from a scenario's robots.urdf or robots.usd section to the reader's options:
    # the settings JSON the layout carries (its keys sorted), read back
    from descriptions.load import load_scenario
    from descriptions.readers import describing_reader, section_options
    from descriptions.urdf_robot import options_of
    from descriptions.usd_robot import usd_options

    path = ROOT / "scenarios" / scenario
    section = {"base": "free", "sensors": {"lidar": "base_scan", "imu": "base_link"},
               "wheels": list(WHEELS)}
    robots = (yaml.safe_load(path.read_text()) or {})["robots"]
    key = describing_reader(ROOT / "scenarios" / robots["description"]).settings_key
    section = {**(robots.get(key) or {}), **section}
    layout = load_scenario(path, {f"robots.{key}": section}).robots
    run = (options_of(layout.settings) if key == "urdf"
           else usd_options(json.loads(layout.settings)))
    described = section_options(layout.description, section, path.parent)
    assert described == run
    # in the run's order too (a URDF robot's settings JSON has its keys sorted)
    assert [list(getattr(described, f)) for f in ("args", "sensors", "interfaces", "gains")] \
        == [list(getattr(run, f)) for f in ("args", "sensors", "interfaces", "gains")]


def test_describe_reads_a_scenarios_robot_as_the_run_does(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump({"robots": {
        "description": str(BOT), "urdf": {"args": {"lidar_samples": "90"},
                                          "packages": PACKAGES, "wheels": list(WHEELS)}}}))
    out = subprocess.run([sys.executable, "-m", "descriptions.describe", str(scenario)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "samples 90" in out.stdout and "drive: differential" in out.stdout
