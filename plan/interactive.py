"""What an interactive scenario adds: the topics through which ROS 2 clients change a run.

With ``interactive: true`` the loader wires, for every cosim node (not foreign programs),
the inputs that the orchestrator's ROS 2 servers feed through the scenario's external node
(which it creates when the scenario has no ``external:`` section):

- ``/goal_pose`` (geometry_msgs/msg/PoseStamped) into every node that takes it (the
  navigation controller): NavigateToPose goals;
- ``/cosim/set_pose`` (simulation_interfaces/msg/NamedPose: the entity's name, the pose, and
  in ``description`` which request it is) into every node that takes it (physics):
  SetEntityState teleports;
- ``/cosim/params/<node>`` (rcl_interfaces/msg/ParameterEvent) into every node whose class
  has runtime parameters: ROS 2 parameter sets;
- ``/cosim/world_edits`` (std_msgs/msg/String: every SpawnEntity and DeleteEntity request
  accepted so far, as JSON, ``plan.events.parse_edits``) into every node that takes it
  (physics): objects put into and taken out of the world.

Whatever a client sends enters at the external node's next activation and is recorded and
hashed like any message, so a run replays. The wiring is part of the plan, whatever the
transport or driver, so an interactive scenario gives one digest multi-process and
in-process; it differs from the same scenario without ``interactive``.
"""

from __future__ import annotations

GOAL_TOPIC = "/goal_pose"
SET_POSE_TOPIC = "/cosim/set_pose"
PARAMS_PREFIX = "/cosim/params/"
WORLD_EDITS_TOPIC = "/cosim/world_edits"

GOAL_TYPE = "geometry_msgs/msg/PoseStamped"
SET_POSE_TYPE = "simulation_interfaces/msg/NamedPose"
PARAMS_TYPE = "rcl_interfaces/msg/ParameterEvent"
WORLD_EDITS_TYPE = "std_msgs/msg/String"

FED_INPUTS = {GOAL_TOPIC: GOAL_TYPE, SET_POSE_TOPIC: SET_POSE_TYPE,
              WORLD_EDITS_TOPIC: WORLD_EDITS_TYPE}
"""Inputs a node takes from clients when its class accepts them, with their types."""


def params_topic(node: str) -> str:
    """The topic that carries parameter changes of ``node``: /cosim/params/<node>."""
    return PARAMS_PREFIX + node.replace("@", "_at_")  # plan.robots.topic_token
