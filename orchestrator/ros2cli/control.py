"""cosim-ros2 control: ros2controlcli's list_controllers, switch_controllers and
list_hardware_interfaces (ros2controlcli is not on PyPI), with its arguments and its output.

``-c/--controller-manager`` names the manager node as ros2controlcli takes it
(``controller_manager``, ``/robot_2/controller_manager``); its services are
``<manager>/list_controllers`` and so on. Colours follow RCUTILS_COLORIZED_OUTPUT (0 off,
1 on, unset: when stdout is a terminal), as controller_manager's ``bcolors`` do.
"""

from __future__ import annotations

import argparse
import os
import sys

from orchestrator.ros2cli.session import ros_session, spin_for, spin_until


def _colour_enabled() -> bool:
    env = os.environ.get("RCUTILS_COLORIZED_OUTPUT")
    return env == "1" or (env != "0" and sys.stdout.isatty())


class Colours:
    """controller_manager's bcolors, decided when a verb runs."""

    def __init__(self):
        on = _colour_enabled()
        codes = {"OKBLUE": "94", "OKCYAN": "96", "OKGREEN": "92", "WARNING": "93",
                 "FAIL": "91", "ENDC": "0"}
        for name, code in codes.items():
            setattr(self, name, f"\033[{code}m" if on else "")


def add_verbs(sub: argparse._SubParsersAction, common: argparse.ArgumentParser) -> None:
    """The control verbs on ``sub``."""
    p = sub.add_parser("list_controllers", parents=[common],
                       help="Output the list of loaded controllers, their type and status")
    for flag, what in (("--claimed-interfaces", "claimed interfaces"),
                       ("--required-state-interfaces", "required state interfaces"),
                       ("--required-command-interfaces", "required command interfaces"),
                       ("--chained-interfaces", "interfaces the controllers are chained to"),
                       ("--reference-interfaces", "exported references (deprecated)"),
                       ("--exported-interfaces", "exported state and reference interfaces")):
        p.add_argument(flag, action="store_true", help=f"List controller's {what}")
    p.add_argument("--verbose", "-v", action="store_true",
                   help="List controller's claimed interfaces, required state interfaces and "
                        "required command interfaces")
    _manager(p)
    p.set_defaults(func=list_controllers)

    p = sub.add_parser("switch_controllers", parents=[common],
                       help="Switch controllers in a controller manager")
    p.add_argument("--deactivate", nargs="*", default=[],
                   help="Name of the controllers to be deactivated")
    p.add_argument("--activate", nargs="*", default=[],
                   help="Name of the controllers to be activated")
    strictness = p.add_mutually_exclusive_group(required=False)
    strictness.add_argument("--strict", action="store_true",
                            help="Set the switch_controllers service strictness to strict")
    strictness.add_argument("--best-effort", action="store_true",
                            help="Set the switch_controllers service strictness to best effort")
    p.add_argument("--activate-asap", action="store_true", help="Start asap controllers")
    p.add_argument("--switch-timeout", type=float, default=5.0,
                   help="Timeout for switching controllers")
    _manager(p)
    p.set_defaults(func=switch_controllers)

    p = sub.add_parser("list_hardware_interfaces", parents=[common],
                       help="Output the list of available command and state interfaces")
    p.add_argument("--verbose", "-v", action="store_true",
                   help="List hardware interfaces and their data types")
    _manager(p)
    p.set_defaults(func=list_hardware_interfaces)


def _manager(p: argparse.ArgumentParser) -> None:
    """ros2controlcli's -c/--controller-manager, and how long to wait for its services."""
    p.add_argument("-c", "--controller-manager", default="controller_manager",
                   help="Name of the controller manager ROS node (default: controller_manager)")
    p.add_argument("--include-hidden-nodes", action="store_true",
                   help="Consider hidden nodes as well (accepted; cosim's are not hidden)")
    p.add_argument("--service-timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for the controller manager's services (default 10)")


def call(args: argparse.Namespace, service: str, srv_type, request):
    """The response of ``<manager>/<service>``; None (said on stderr) when no server
    answers within --service-timeout."""
    manager = args.controller_manager
    name = f"{manager}/{service}" if manager.startswith("/") else f"/{manager}/{service}"
    with ros_session(args.domain) as (node, executor):
        client = node.create_client(srv_type, name)
        if not spin_until(executor, client.service_is_ready, args.service_timeout):
            print(f"Could not contact service {name}", file=sys.stderr)
            return None
        spin_for(executor, 0.2)  # the server's reply path may be matched a moment later
        future = client.call_async(request)
        if not spin_until(executor, future.done, args.service_timeout):
            print(f"Failed getting a result from calling {name} in "
                  f"{args.service_timeout:g} s", file=sys.stderr)
            return None
        return future.result()


def list_controllers(args: argparse.Namespace) -> int:
    """Print the loaded controllers as ros2controlcli's list_controllers does."""
    from controller_manager_msgs.srv import ListControllers

    response = call(args, "list_controllers", ListControllers, ListControllers.Request())
    if response is None:
        return 1
    if not response.controller:
        print("No controllers are currently loaded!")
        return 0
    c = Colours()
    width_name = max(len(x.name) for x in response.controller)
    width_type = max(len(x.type) for x in response.controller)
    width_state = max(len(x.state) for x in response.controller)
    for x in response.controller:
        colour = {"active": c.OKGREEN, "inactive": c.OKCYAN,
                  "unconfigured": c.WARNING}.get(x.state, "")
        print(f"{colour}{x.name:<{width_name}}{c.ENDC} {x.type:<{width_type}}  "
              f"{colour}{x.state:<{width_state}}{c.ENDC}")
        if args.verbose:
            print(f"\tupdate_rate: {x.update_rate} Hz")
            print(f"\tis_async: {x.is_async}")
        for flag, title, items in (
                (args.claimed_interfaces, "claimed interfaces", x.claimed_interfaces),
                (args.required_command_interfaces, "required command interfaces",
                 x.required_command_interfaces),
                (args.required_state_interfaces, "required state interfaces",
                 x.required_state_interfaces)):
            if flag or args.verbose:
                print(f"\t{title}:")
                for item in items:
                    print(f"\t\t{item}")
        if args.chained_interfaces or args.verbose:
            print("\tchained to interfaces:")
            for connection in x.chain_connections:
                for reference in connection.reference_interfaces:
                    print(f"\t\t{reference:20s}")
        if args.reference_interfaces or args.exported_interfaces or args.verbose:
            print("\texported reference interfaces:")
            for item in x.reference_interfaces:
                print(f"\t\t{item}")
            print("\texported state interfaces:")
            for item in x.exported_state_interfaces:
                print(f"\t\t{item}")
    return 0


def switch_controllers(args: argparse.Namespace) -> int:
    """Call switch_controller; print its message (exit 1 when it is not ok)."""
    from builtin_interfaces.msg import Duration
    from controller_manager_msgs.srv import SwitchController

    request = SwitchController.Request(
        activate_controllers=args.activate, deactivate_controllers=args.deactivate,
        strictness=(SwitchController.Request.STRICT if args.strict else
                    SwitchController.Request.BEST_EFFORT if args.best_effort else 0),
        activate_asap=args.activate_asap,
        timeout=Duration(sec=int(args.switch_timeout),
                         nanosec=round(args.switch_timeout % 1 * 1e9)))
    response = call(args, "switch_controller", SwitchController, request)
    if response is None:
        return 1
    c = Colours()
    if not response.ok:
        print(c.FAIL + response.message + c.ENDC)
        return 1
    print(c.OKBLUE + response.message + c.ENDC)
    return 0


def list_hardware_interfaces(args: argparse.Namespace) -> int:
    """Print the command and state interfaces as ros2controlcli's verb does."""
    from controller_manager_msgs.srv import ListHardwareInterfaces

    response = call(args, "list_hardware_interfaces", ListHardwareInterfaces,
                    ListHardwareInterfaces.Request())
    if response is None:
        return 1
    c = Colours()
    print("command interfaces")
    for x in sorted(response.command_interfaces, key=lambda i: i.name):
        kind = f" [{x.data_type}]" if args.verbose else ""
        if not x.is_available:
            print(f"\t{c.WARNING}{x.name}{kind} [unavailable] [unclaimed]{c.ENDC}")
        elif x.is_claimed:
            print(f"\t{c.OKBLUE}{x.name}{kind} [available] [claimed]{c.ENDC}")
        else:
            print(f"\t{c.OKCYAN}{x.name}{kind} [available] [unclaimed]{c.ENDC}")
    print("state interfaces")
    for x in sorted(response.state_interfaces, key=lambda i: i.name):
        kind = f" [{x.data_type}]" if args.verbose else ""
        print(f"\t{x.name}{kind}")
    return 0
