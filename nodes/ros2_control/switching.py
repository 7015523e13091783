"""What a controller_manager/switch_controller request does, decided as ros2_control's
controller manager (Jazzy) decides it, from the controllers' states and claims alone.

Strictness: ``STRICT`` (2) refuses the whole request at the first controller that cannot be
switched (a name not loaded, an unconfigured or already active controller to activate, an
inactive one to deactivate); ``BEST_EFFORT`` (1) leaves such controllers out and switches the
rest; 0 (unset) is the manager's default, ``best_effort``; ``AUTO`` (3) and ``FORCE_AUTO``
(4) are not implemented upstream either and act as ``BEST_EFFORT``. Two active controllers
claiming one command interface is refused whatever the strictness, and so are two claiming
two command interfaces of one joint (its position and velocity: cosim's hardware takes one
per joint at a time, as upstream's rejects it in ``prepare_command_mode_switch``). The
messages are upstream's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from nodes.ros2_control.hardware import joint_mode_conflict

BEST_EFFORT, STRICT, AUTO, FORCE_AUTO = 1, 2, 3, 4
STRICTNESS = {BEST_EFFORT: "BEST_EFFORT", STRICT: "STRICT", AUTO: "AUTO",
              FORCE_AUTO: "FORCE_AUTO"}
NOTHING_TO_DO = ("After checking the controllers, no controllers need to be activated or "
                 "deactivated.")


@dataclass
class SwitchPlan:
    """The outcome: ``ok``, upstream's ``message``, and the controllers actually switched
    (deactivations first, then activations, at one update)."""

    ok: bool
    message: str
    activate: list[str] = field(default_factory=list)
    deactivate: list[str] = field(default_factory=list)


def effective_strictness(strictness: int) -> int:
    """STRICT stays STRICT; everything else (unset, AUTO, FORCE_AUTO) is BEST_EFFORT."""
    return STRICT if strictness == STRICT else BEST_EFFORT


def plan_switch(states: Mapping[str, str], claims: Mapping[str, tuple[str, ...]],
                activate: list[str], deactivate: list[str], strictness: int,
                unrunnable: Mapping[str, str] | None = None) -> SwitchPlan:
    """The switch of ``activate``/``deactivate`` given each loaded controller's state
    (``unconfigured``, ``inactive``, ``active``) and the command interfaces each claims when
    active. ``unrunnable``: controller -> why cosim cannot activate it (a type it does not
    run), refused as an activation that fails."""
    strict = effective_strictness(strictness) == STRICT
    unrunnable = unrunnable or {}
    lists: dict[str, list[str]] = {}
    for action, names in (("deactivate", deactivate), ("activate", activate)):
        found: list[str] = []
        missing: list[str] = []
        for name in names:
            if name in states:
                found.append(name)
                continue
            missing.append(f"Could not {action} controller with name '{name}' because no "
                           "controller with this name exists")
            if strict:
                return SwitchPlan(False, missing[-1])
        if names and not found:
            return SwitchPlan(False, "\n".join(missing))
        lists[action] = found
    for action in ("activate", "deactivate"):
        kept = []
        for name in lists[action]:
            why = _why_not(action, name, states, lists["deactivate"], unrunnable)
            if why is None:
                kept.append(name)
            elif strict:
                return SwitchPlan(False, why)
        lists[action] = kept
    on, off = lists["activate"], lists["deactivate"]
    if not on and not off:
        return SwitchPlan(True, NOTHING_TO_DO)
    staying = {i for n, s in states.items() if s == "active" and n not in off
               for i in claims.get(n, ())}
    coming: set[str] = set()
    for name in on:
        for interface in claims.get(name, ()):
            if interface in staying:
                return SwitchPlan(False, f"Unable to activate controller '{name}' since the "
                                  f"command interface '{interface}' is currently claimed by "
                                  "another controller.")
            if interface in coming:
                return SwitchPlan(False, f"Unable to activate controller '{name}' since the "
                                  f"command interface '{interface}' will be used by another "
                                  "controller that is being activated.")
            coming.add(interface)
    after = [(n, claims.get(n, ())) for n, s in states.items() if s == "active"
             and n not in off] + [(n, claims.get(n, ())) for n in on]
    both = joint_mode_conflict(after)
    if both is not None:
        joint, first, by, second, by_second = both
        return SwitchPlan(False, "Could not switch controllers since prepare command mode "
                          f"switch was rejected: joint '{joint}' would be commanded through "
                          f"'{first}' by '{by}' and '{second}' by '{by_second}' (one command "
                          "interface per joint at a time).")
    message = "Successfully switched controllers!"
    if not strict:
        if off:
            message += f"\nDeactivated controllers: [ {' '.join(off)} ]"
        if on:
            message += f"\nActivated controllers: [ {' '.join(on)} ]"
    return SwitchPlan(True, message, on, off)


def _why_not(action: str, name: str, states: Mapping[str, str], deactivating: list[str],
             unrunnable: Mapping[str, str]) -> str | None:
    state = states[name]
    if action == "deactivate":
        if state != "active":
            return f"Controller with name '{name}' can not be deactivated since it is not active."
        return None
    if name in unrunnable:
        return f"Could not activate controller '{name}': {unrunnable[name]}"
    if state == "unconfigured":
        return (f"Controller with name '{name}' is in 'unconfigured' state. The controller "
                "needs to be configured to be in 'inactive' state before it can be checked "
                "and activated.")
    if state == "active" and name not in deactivating:
        return f"Controller with name '{name}' is already active."
    return None
