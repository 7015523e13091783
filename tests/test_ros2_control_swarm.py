"""ros2_control in a swarm: each robot's controller manager and controllers under its
namespace, from one controllers file (its /** wildcard blocks), as namespaced
ros2_control_nodes would serve them."""

from __future__ import annotations

import json

from descriptions.load import load_scenario
from orchestrator.lockstep.inprocess import run_in_process
from orchestrator.outputs.bag import BagReader
from plan.ros_types import message_class
from tests.helpers import ROOT

SWARM = ROOT / "scenarios" / "swarm_urdf_control.yaml"
ROBOTS = [f"robot_{i}" for i in range(4)]
TICK_MS = 20


def test_four_urdf_robots_reach_their_goals_through_their_own_diff_drive_controllers(
        tmp_path):
    from orchestrator.api import run

    scenario = load_scenario(SWARM)
    # each robot's manager runs in the physics step; what clients feed it is the robot's
    graph = {i.graph_topic: i.producer for i in scenario.nodes["physics"].inputs}
    for robot in ROBOTS:
        assert graph[f"/{robot}/controller_manager/cosim/switch"] == "external"
        assert graph[f"/{robot}/diff_drive_controller/cmd_vel"] == f"control@{robot}"
    done = run(SWARM, in_process=True, out=tmp_path / "a", picture=False)
    assert done.success
    metrics = done.outcome.result.metrics
    assert metrics["physics"]["robots_arrived"] == 4.0
    odom = message_class("nav_msgs/msg/Odometry")
    with BagReader(done.run_dir / "bag") as bag:
        for robot in ROBOTS:
            assert metrics["physics"][
                f"{robot}/controller_manager/active:diff_drive_controller"] == 1.0
            # the robot's base moved only by its own diff drive controller's wheel speeds,
            # limited by its linear.x.max_velocity (0.8) from the one file's /** block
            truth = [m.twist.twist.linear.x for _, m in bag.messages(f"/{robot}/odom", odom)]
            assert max(abs(v) for v in truth) <= 0.8 + 0.02
            assert max(abs(v) for v in truth) > 0.3
            assert f"/{robot}/cmd_vel" not in bag.counts
            assert bag.counts[f"/{robot}/diff_drive_controller/odom"] > 0
            # its odometry in its own frames, as upstream's tf_frame_prefix default has them
            _, wheels = next(bag.messages(f"/{robot}/diff_drive_controller/odom", odom))
            assert (wheels.header.frame_id, wheels.child_frame_id) == (
                f"{robot}/odom", f"{robot}/base_footprint")
            assert bag.counts[f"/{robot}/diff_drive_controller/cmd_vel"] > 0


def control(*args: str) -> str:
    """cosim-ros2 control ... against robot 2's manager; its standard output (exit 0)."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "orchestrator.ros2cli", "control", *args,
                           "-c", "/robot_2/controller_manager", "--service-timeout", "40"],
                          capture_output=True,
                          text=True, timeout=60, cwd=ROOT, env=_plain_output())
    assert done.returncode == 0, done.stderr
    return done.stdout


def _plain_output() -> dict[str, str]:
    import os

    return {**os.environ, "RCUTILS_COLORIZED_OUTPUT": "0"}


def test_a_robots_manager_answers_ros2controlcli_and_upstreams_services(tmp_path, ros_node):
    """cosim-ros2 control against a paused swarm: robot 2's controllers and hardware under
    /robot_2/controller_manager; a switch enters at the next tick, for robot 2 only; unload,
    load, configure and activate again, as upstream's manager takes them. The multi-process
    run (packed by kind) and an in-process run fed what it recorded give one digest."""
    from controller_manager_msgs.srv import (
        ConfigureController,
        ListControllers,
        ListHardwareComponents,
        LoadController,
        SwitchController,
        UnloadController,
    )
    from simulation_interfaces.msg import SimulationState

    from tests.sim_client import OK, SimClient, orchestrate

    ddc = "diff_drive_controller"
    cm = "/robot_2/controller_manager/"
    sim = SimClient(ros_node)

    def states(robot: str = "robot_2") -> dict[str, str]:
        listed = sim.call(ListControllers, f"/{robot}/controller_manager/list_controllers",
                          ListControllers.Request()).controller
        return {c.name: c.state for c in listed}

    with orchestrate(SWARM, tmp_path / "out", "--paused", "--pack", "kind") as proc:
        assert sim.step(2).result == OK
        assert control("list_controllers", "--claimed-interfaces") == (
            f"{ddc} diff_drive_controller/DiffDriveController  active\n"
            "\tclaimed interfaces:\n\t\twheel_left_joint/velocity\n"
            "\t\twheel_right_joint/velocity\n")
        assert control("list_hardware_interfaces") == (
            "command interfaces\n\twheel_left_joint/velocity [available] [claimed]\n"
            "\twheel_right_joint/velocity [available] [claimed]\nstate interfaces\n"
            + "".join(f"\twheel_{side}_joint/{i}\n" for side in ("left", "right")
                      for i in ("effort", "position", "velocity")))
        assert control("switch_controllers", "--deactivate", ddc, "--strict").startswith(
            "Successfully switched controllers!")
        assert states() == {ddc: "active"}  # it enters at the next tick
        assert sim.step(1).result == OK
        assert states() == {ddc: "inactive"} and states("robot_1") == {ddc: "active"}

        strict = sim.call(SwitchController, cm + "switch_controller", SwitchController.Request(
            activate_controllers=[ddc, "nope"], strictness=SwitchController.Request.STRICT))
        assert not strict.ok and "'nope' because no controller" in strict.message
        assert sim.call(UnloadController, cm + "unload_controller",
                        UnloadController.Request(name=ddc)).ok
        assert sim.step(1).result == OK
        assert states() == {}
        assert not sim.call(ConfigureController, cm + "configure_controller",
                            ConfigureController.Request(name=ddc)).ok  # not loaded
        for verb, srv, after in (("load", LoadController, "unconfigured"),
                                 ("configure", ConfigureController, "inactive")):
            assert sim.call(srv, f"{cm}{verb}_controller", srv.Request(name=ddc)).ok
            assert sim.step(1).result == OK
            assert states() == {ddc: after}
        assert control("switch_controllers", "--activate", ddc, "--activate-asap") \
            .startswith("Successfully switched controllers!\nActivated controllers: "
                        f"[ {ddc} ]")
        assert sim.step(1).result == OK
        assert states() == {ddc: "active"}
        component, = sim.call(ListHardwareComponents, cm + "list_hardware_components",
                              ListHardwareComponents.Request()).component
        assert component.state.label == "active" and component.rw_rate == 50
        assert {i.name for i in component.command_interfaces if i.is_claimed} == {
            "wheel_left_joint/velocity", "wheel_right_joint/velocity"}
        stop = sim.set_state(SimulationState.STATE_STOPPED)
        _, err = proc.communicate(timeout=120)
    sim.close()
    # the switches, unload, load and configure were recorded where they entered: fed again,
    # an in-process run gives the run's digest
    stopped_at = int(stop.error_message.split("before tick ")[1].split()[0])
    run_dir = next((tmp_path / "out").iterdir())
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert manifest["ticks"] == stopped_at, err
    scenario = load_scenario(SWARM, {"duration": f"{(stopped_at - 1) * TICK_MS}ms"})
    inputs = recorded_inputs(run_dir, scenario)
    entered = [inputs[k][f"{cm}cosim/switch"].data.partition(" ")[2]  # '#<id> <request>'
               for k in sorted(inputs)]
    assert [d for i, d in enumerate(entered) if d and d != entered[i - 1]] == [
        f"-{ddc}", f"unload:{ddc}", f"load:{ddc}", f"configure:{ddc}", f"+{ddc}"]
    assert not any(inputs[k]["/robot_1/controller_manager/cosim/switch"].data for k in inputs)
    assert run_in_process(scenario, external=lambda k: inputs.get(k, {})).digest == \
        manifest["digest"]
    assert run_in_process(scenario).digest != manifest["digest"]  # they changed the run


def recorded_inputs(run_dir, scenario) -> dict[int, dict]:
    """What the external node published at each tick where a client sent something, from
    the run's bag."""
    inputs: dict[int, dict] = {}
    with BagReader(run_dir / "bag") as bag:
        for topic in scenario.nodes["external"].outputs:
            cls = message_class(bag.msgtype(topic))
            for stamp, msg in bag.messages(topic, cls):
                inputs.setdefault(stamp // (TICK_MS * 1_000_000), {})[topic] = msg
    return inputs
