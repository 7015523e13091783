"""The controller manager's switch and lifecycle rules, as upstream's (pure functions)."""

from __future__ import annotations

from nodes.ros2_control.config import read_controllers_file
from nodes.ros2_control.interface import JointReading
from nodes.ros2_control.manager import ControllerManager
from nodes.ros2_control.switching import BEST_EFFORT, NOTHING_TO_DO, STRICT, plan_switch
from tests.helpers import ROOT

STATES = {"jsb": "active", "jtc": "active", "fwd": "inactive", "raw": "unconfigured"}
CLAIMS = {"jsb": (), "jtc": ("a/position", "b/position"), "fwd": ("a/position",),
          "raw": ("b/position",)}


def test_best_effort_switches_what_it_can_and_says_what_it_did():
    done = plan_switch(STATES, CLAIMS, ["fwd", "nope", "raw"], ["jtc", "fwd"], 0)
    assert done.ok and done.activate == ["fwd"] and done.deactivate == ["jtc"]
    assert done.message == ("Successfully switched controllers!\nDeactivated controllers: "
                            "[ jtc ]\nActivated controllers: [ fwd ]")
    # every name unknown: refused; nothing left to do: ok, and said
    assert not plan_switch(STATES, CLAIMS, ["nope"], [], BEST_EFFORT).ok
    assert plan_switch(STATES, CLAIMS, ["jtc"], [], BEST_EFFORT).message == NOTHING_TO_DO


def test_strict_refuses_the_whole_request_at_the_first_problem():
    done = plan_switch(STATES, CLAIMS, ["fwd", "raw"], ["jtc"], STRICT)
    assert not done.ok and not done.activate and "'raw' is in 'unconfigured' state" in \
        done.message
    assert "no controller with this name exists" in plan_switch(
        STATES, CLAIMS, [], ["jtc", "nope"], STRICT).message
    assert "'fwd' can not be deactivated since it is not active" in plan_switch(
        STATES, CLAIMS, [], ["fwd"], STRICT).message
    ok = plan_switch(STATES, CLAIMS, ["fwd"], ["jtc"], STRICT)
    assert ok.ok and ok.message == "Successfully switched controllers!"


def test_a_claimed_command_interface_is_refused_whatever_the_strictness():
    for strictness in (BEST_EFFORT, STRICT):
        done = plan_switch(STATES, CLAIMS, ["fwd"], [], strictness)
        assert not done.ok
        assert done.message == ("Unable to activate controller 'fwd' since the command "
                                "interface 'a/position' is currently claimed by another "
                                "controller.")
    assert "cannot run" in plan_switch(STATES, CLAIMS, ["fwd"], ["jtc"], STRICT,
                                       {"fwd": "cannot run"}).message


def test_unload_load_configure_and_activate_as_upstream():
    manager = ControllerManager(read_controllers_file(
        ROOT / "scenarios" / "controllers" / "arm_controllers.yaml"))
    names = list(manager.states())
    jtc = "joint_trajectory_controller"
    state = {j: JointReading(0.0) for j in ("shoulder_pan", "shoulder_lift", "elbow",
                                            "wrist_1", "wrist_2", "wrist_3")}
    assert jtc in names
    assert manager.lifecycle("load", jtc).startswith("A controller named")
    assert "no controller with this name" in manager.lifecycle("configure", "nope")
    manager.activate([jtc], state)
    assert "still active" in manager.lifecycle("unload", jtc)
    manager.controllers[jtc].deactivate()
    assert manager.lifecycle("unload", jtc) is None
    assert jtc not in manager.states() and manager.metrics()[f"state:{jtc}"] == 0.0
    _, problem = manager.switch([jtc], [], state)
    assert "not loaded" in problem
    assert manager.lifecycle("load", jtc) is None
    assert manager.states()[jtc] == "unconfigured"
    assert "unconfigured" in manager.switch([jtc], [], state)[1]
    assert manager.lifecycle("configure", jtc) is None
    assert manager.states()[jtc] == "inactive" and manager.metrics()[f"state:{jtc}"] == 2.0
