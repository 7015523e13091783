"""joint_state_broadcaster/JointStateBroadcaster: the hardware's joint states on
``/joint_states`` and ``/dynamic_joint_states`` (``~/...`` with ``use_local_topics``)."""

from __future__ import annotations

from control_msgs.msg import DynamicJointState
from pydantic import Field
from sensor_msgs.msg import JointState

from nodes.contract import encoded_message
from nodes.ros2_control import fast_messages as fast
from nodes.ros2_control.interface import (
    INTERFACES,
    Claim,
    ControllerInterface,
    ControllerParams,
    JointStates,
    Update,
)
from nodes.ros2_control.param_types import OptionalJointNames


class JointStateBroadcasterParams(ControllerParams):
    """joint_state_broadcaster's parameters (its ``joint_state_broadcaster.yaml``)."""

    joints: OptionalJointNames = Field([], description="the joints to publish; empty: every "
                                       "joint of the hardware, in its order")
    use_local_topics: bool = Field(False, description="publish on ~/joint_states instead of "
                                   "/joint_states")
    frame_id: str = Field("base_link", description="the header's frame")
    publish_dynamic_joint_states: bool = Field(True, description="also publish "
                                               "/dynamic_joint_states")


class JointStateBroadcaster(ControllerInterface):
    """Publishes position, velocity and effort of its joints (or of all) at every update."""

    Params = JointStateBroadcasterParams

    def _topic(self, name: str) -> str:
        return f"~/{name}" if self.params.use_local_topics else f"/{name}"

    def claim(self) -> Claim:
        """Every state interface of its joints (none named: all, known at activation)."""
        return Claim(state=tuple(f"{j}/{i}" for j in self.params.joints for i in INTERFACES),
                     every_state=True)

    def notes(self) -> list[str]:
        """frame_id, when given, is not applied."""
        if "frame_id" in self.params.model_fields_set:
            return [f"{self.name}: frame_id is not applied: /joint_states carries no frame."]
        return []

    def publications(self) -> dict[str, type]:
        """``/joint_states`` and, unless turned off, ``/dynamic_joint_states``."""
        out: dict[str, type] = {self._topic("joint_states"): JointState}
        if self.params.publish_dynamic_joint_states:
            out[self._topic("dynamic_joint_states")] = DynamicJointState
        return out

    def on_activate(self) -> Update:
        """Its joints (all the hardware's when none are named) and topics, for every
        update until it is deactivated."""
        self.names = list(self.params.joints) or list(self.state)
        self.topics = (self._topic("joint_states"),
                       self._topic("dynamic_joint_states")
                       if self.params.publish_dynamic_joint_states else None)
        # a system interface's every joint in its order: its lists as they are
        self.whole = (isinstance(self.state, JointStates)
                      and tuple(self.names) == self.state.joints)
        self.packer = fast.BroadcasterPacker(self.names) if self.names else None
        return Update()

    def update(self, time_ns: int, period_ns: int) -> Update:
        """The joints' states as they are now."""
        names = self.names
        state = self.state
        if self.whole:
            positions, velocities, efforts = state.positions, state.velocities, state.efforts
        else:
            readings = [state[n] for n in names]
            positions = [r.position for r in readings]
            velocities = [r.velocity for r in readings]
            efforts = [r.effort for r in readings]
        joint_states, dynamic = self.topics
        packer = self.packer
        msg = fast.joint_state(names, positions, velocities, efforts)
        if packer is not None:
            encoded_message(msg, packer.pack_joint_state(positions, velocities, efforts))
        out = {joint_states: msg}
        if dynamic is not None:
            msg = fast.dynamic_joint_state(names, positions, velocities, efforts)
            if packer is not None:
                encoded_message(msg, packer.pack_dynamic(positions, velocities, efforts))
            out[dynamic] = msg
        return Update(published=out)
