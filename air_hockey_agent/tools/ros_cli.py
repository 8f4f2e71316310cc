"""``air-hockey topic|service|param|shoot``: what a ROS user does with ``ros2``, without ``ros2``
(ros2cli is not installable from the package registry).

Same names and argument shapes as ``ros2 topic list|echo|hz``, ``ros2 service list|call`` (the request as
YAML) and ``ros2 param list|get|set``, on the DDS domain and middleware settings the nodes use
(``ROS_DOMAIN_ID`` from the environment or ``--domain-id``), for our message types and the standard
ones. ``air-hockey shoot`` sets the puck in the running simulation moving in one command.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import yaml

from air_hockey_agent.params import yaml_load
from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.argtypes import count, number

DISCOVERY = 1.5  # [s] wait for the DDS graph before listing (discovery takes about a second here)


class CliError(Exception):
    """Bad input or an unreachable node: one line, exit code 2 (1 for a failed call)."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code


# --- a probe node ---------------------------------------------------------------------------------
class Probe:
    """An rclpy node in this process on the nodes' domain, for one command."""

    def __init__(self, domain_id: int | None) -> None:
        from air_hockey_agent.tools.ros_env import ros_environment
        try:
            env = ros_environment(domain_id=domain_id)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        for key in ("ROS_DOMAIN_ID", "FASTRTPS_DEFAULT_PROFILES_FILE", "RMW_IMPLEMENTATION"):
            if key in env:
                os.environ[key] = env[key]
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(f"air_hockey_cli_{os.getpid()}", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_for(self, seconds: float, until=lambda: False) -> bool:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and not until():
            self.executor.spin_once(timeout_sec=min(0.05, max(deadline - time.monotonic(), 0.0)))
            interrupt.check()
        return until()

    def topic_type(self, topic: str, wait: float) -> str:
        def known():
            return any(name == topic for name, _ in self.node.get_topic_names_and_types())
        if not self.spin_for(wait, known):
            raise CliError(f"topic {topic} is not published on ROS_DOMAIN_ID {os.environ.get('ROS_DOMAIN_ID', '0')} "
                           f"(air-hockey topic list shows what is)")
        return dict(self.node.get_topic_names_and_types())[topic][0]

    def topic_class(self, topic: str, wait: float):
        """The rclpy message class of a topic in the graph."""
        from air_hockey_agent.nodes.message_fields import FieldError, interface_class
        try:
            return interface_class(self.topic_type(topic, wait), "msg")
        except FieldError as exc:
            raise CliError(str(exc)) from None

    def call(self, srv_type, name: str, request, timeout: float):
        client = self.node.create_client(srv_type, name)
        if not client.wait_for_service(timeout_sec=timeout):
            raise CliError(f"service {name} is not available (air-hockey service list shows what is)")
        future = client.call_async(request)
        if not self.spin_for(timeout, future.done):
            raise CliError(f"service {name} did not answer within {timeout:g} s", 1)
        return future.result()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def _with_probe(action):
    def run(args: argparse.Namespace) -> int:
        probe = None
        try:
            probe = Probe(args.domain_id)
            return int(action(probe, args) or 0)
        except CliError as exc:
            print(f"air-hockey {args.command}: error: {exc}", file=sys.stderr)
            return exc.code
        except KeyboardInterrupt:
            return 0
        finally:
            if probe is not None:
                probe.close()
    return run


def _yaml(data) -> str:
    return yaml.safe_dump(data, default_flow_style=False, sort_keys=False).rstrip()


# --- topic ----------------------------------------------------------------------------------------
def topic_list(probe: Probe, args) -> int:
    probe.spin_for(args.wait)
    for name, types in sorted(probe.node.get_topic_names_and_types()):
        print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def topic_echo(probe: Probe, args) -> int:
    """Until Ctrl-C (or --once / --count); an error when nothing arrives within --timeout."""
    from air_hockey_agent.nodes.message_fields import to_plain
    received = []

    def show(message) -> None:
        received.append(message)
        print(_yaml(to_plain(message)) + "\n---", flush=True)
    probe.node.create_subscription(probe.topic_class(args.topic, args.wait), args.topic, show, 10)
    limit = 1 if args.once else args.count
    first_by = time.monotonic() + args.timeout
    while not limit or len(received) < limit:
        probe.executor.spin_once(timeout_sec=0.05)
        interrupt.check()
        if not received and time.monotonic() > first_by:
            raise CliError(f"no message on {args.topic} within {args.timeout:g} s", 1)
    return 0


def topic_hz(probe: Probe, args) -> int:
    stamps: list[float] = []
    probe.node.create_subscription(probe.topic_class(args.topic, args.wait), args.topic, lambda _: stamps.append(time.monotonic()), 100, raw=True)
    start, last_report = time.monotonic(), time.monotonic()
    while not args.duration or time.monotonic() - start < args.duration:
        probe.executor.spin_once(timeout_sec=0.05)
        interrupt.check()
        if time.monotonic() - last_report >= 1.0:
            last_report = time.monotonic()
            recent = stamps[-args.window:]
            if len(recent) >= 2:
                gaps = [b - a for a, b in zip(recent, recent[1:])]
                mean = sum(gaps) / len(gaps)
                std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
                print(f"average rate: {1.0 / mean:.3f}\n\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s "
                      f"std dev: {std:.5f}s window: {len(recent)}", flush=True)
            else:
                print("no new messages", flush=True)
    return 0


# --- service --------------------------------------------------------------------------------------
def service_list(probe: Probe, args) -> int:
    probe.spin_for(args.wait)
    for name, types in sorted(probe.node.get_service_names_and_types()):
        print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def _request_data(text: str):
    try:
        return yaml_load(text) if text.strip() else {}
    except yaml.YAMLError as exc:
        raise CliError(f"the request is not valid YAML ({exc.__class__.__name__}): {text!r}") from None


def service_call(probe: Probe, args) -> int:
    from air_hockey_agent.nodes.message_fields import FieldError, fill, interface_class, to_plain
    try:
        cls = interface_class(args.service_type, "srv")
        request = fill(cls.Request(), _request_data(args.values))
    except FieldError as exc:
        raise CliError(str(exc)) from None
    print(f"requester: making request: {type(request).__name__}({_yaml(to_plain(request))})\n", flush=True)
    response = probe.call(cls, args.service_name, request, args.timeout)
    print("response:\n" + _yaml(to_plain(response)))
    return 0


# --- param ----------------------------------------------------------------------------------------
def _param_services(probe: Probe, node: str, wait: float) -> str:
    node = node if node.startswith("/") else "/" + node
    wanted = f"{node}/list_parameters"
    if not probe.spin_for(wait, lambda: any(n == wanted for n, _ in probe.node.get_service_names_and_types())):
        raise CliError(f"node {node} is not running (or has no parameter services) on ROS_DOMAIN_ID "
                       f"{os.environ.get('ROS_DOMAIN_ID', '0')}")
    return node


def _parameter_value(value) -> object:
    from rclpy.parameter import Parameter
    return Parameter.from_parameter_msg(type("P", (), {"name": "", "value": value})()).value


def param_list(probe: Probe, args) -> int:
    from rcl_interfaces.srv import ListParameters
    if args.node:
        nodes = [_param_services(probe, args.node, args.wait)]
    else:
        probe.spin_for(args.wait)
        nodes = sorted(n[:-len("/list_parameters")] for n, _ in probe.node.get_service_names_and_types()
                       if n.endswith("/list_parameters") and not n.startswith("/air_hockey_cli_"))
    for node in nodes:
        result = probe.call(ListParameters, f"{node}/list_parameters", ListParameters.Request(), args.timeout)
        print(f"{node}:")
        for name in sorted(result.result.names):
            print(f"  {name}")
    return 0


def param_get(probe: Probe, args) -> int:
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters
    node = _param_services(probe, args.node, args.wait)
    result = probe.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=[args.name]),
                        args.timeout)
    if not result.values or result.values[0].type == ParameterType.PARAMETER_NOT_SET:
        raise CliError(f"parameter {args.name} is not set on {node}", 1)
    value = _parameter_value(result.values[0])
    kind = {bool: "Boolean", int: "Integer", float: "Double", str: "String"}.get(type(value), "Array")
    print(f"{kind} value is: {value}")
    return 0


def param_set(probe: Probe, args) -> int:
    from rclpy.parameter import Parameter
    from rcl_interfaces.srv import SetParameters
    node = _param_services(probe, args.node, args.wait)
    try:
        value = yaml_load(args.value)
    except yaml.YAMLError:
        value = args.value
    request = SetParameters.Request(parameters=[Parameter(args.name, value=value).to_parameter_msg()])
    result = probe.call(SetParameters, f"{node}/set_parameters", request, args.timeout)
    outcome = result.results[0]
    if not outcome.successful:
        raise CliError(f"setting parameter failed: {outcome.reason or 'refused by the node'}", 1)
    print("Set parameter successful")
    return 0


# --- shoot ----------------------------------------------------------------------------------------
def shoot(probe: Probe, args) -> int:
    """Set the puck moving in the running simulation (table_sim's /set_puck_state)."""
    from air_hockey_msgs.msg import PuckState
    from air_hockey_msgs.srv import SetPuckState
    x, y = args.x, args.y
    if x is None or y is None:  # from where the puck is now
        seen = []
        probe.node.create_subscription(PuckState, "/sim/puck_true_state", seen.append, 10)
        if not probe.spin_for(args.timeout, lambda: bool(seen)):
            raise CliError("no /sim/puck_true_state: is table_sim running? (or give --x and --y)")
        x = seen[-1].x if x is None else x
        y = seen[-1].y if y is None else y
    angle = math.radians(args.angle)
    request = SetPuckState.Request(x=float(x), y=float(y), vx=args.speed * math.cos(angle),
                                   vy=args.speed * math.sin(angle), omega=float(args.spin))
    answer = probe.call(SetPuckState, "/set_puck_state", request, args.timeout)
    if not answer.success:
        raise CliError(f"table_sim refused: {answer.message}", 1)
    print(f"puck at ({x:.3f}, {y:.3f}) m shot at {args.speed:g} m/s, {args.angle:g} deg (table frame)")
    return 0


# --- parsers --------------------------------------------------------------------------------------
def _common(parser: argparse.ArgumentParser, wait: bool = True) -> None:
    parser.add_argument("--domain-id", type=count(1, 101), default=None,
                        help="ROS_DOMAIN_ID (1..101; default: the environment's)")
    parser.add_argument("--timeout", type=number(0.0, low_open=True), default=5.0,
                        help="seconds to wait for a node or an answer (default 5)")
    if wait:
        parser.add_argument("--wait", type=number(0.0), default=DISCOVERY,
                            help=f"seconds of discovery before looking at the graph (default {DISCOVERY:g})")


def _group(subparsers, name: str, help_text: str, commands) -> None:
    parser = subparsers.add_parser(name, help=help_text, description=help_text)
    inner = parser.add_subparsers(title="commands", metavar="COMMAND")
    for command, text, action, setup in commands:
        sub = inner.add_parser(command, help=text, description=text)
        setup(sub)
        _common(sub)
        sub.set_defaults(run=_with_probe(action), command=f"{name} {command}")
    parser.set_defaults(run=lambda args: parser.print_help() or 2)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    def types_flag(p):
        p.add_argument("-t", "--show-types", action="store_true", help="also print each one's type")

    def echo_args(p):
        p.add_argument("topic", help="topic name, e.g. /iiwa_front/puck/state")
        p.add_argument("--once", action="store_true", help="print one message and exit")
        p.add_argument("--count", type=count(0), default=0, help="exit after this many messages (0: never)")

    def hz_args(p):
        p.add_argument("topic", help="topic name")
        p.add_argument("--window", type=count(2), default=1000, help="messages the rate is computed over")
        p.add_argument("--duration", type=number(0.0), default=0.0, help="seconds to measure (0: until Ctrl-C)")

    def call_args(p):
        p.add_argument("service_name", help="service name, e.g. /set_puck_state")
        p.add_argument("service_type", help="service type, e.g. air_hockey_msgs/srv/SetPuckState")
        p.add_argument("values", nargs="?", default="", help='request fields as YAML, e.g. "{x: -0.5, vx: 2.0}"')

    def node_opt(p):
        p.add_argument("node", nargs="?", default="", help="node name, e.g. /iiwa_front/puck_tracker (default: all)")

    def get_args(p):
        p.add_argument("node", help="node name, e.g. /iiwa_front/puck_tracker")
        p.add_argument("name", help="parameter name")

    def set_args(p):
        get_args(p)
        p.add_argument("value", help="new value (YAML: 0.3, true, [1, 2], text)")

    _group(subparsers, "topic", "ros2 topic, for this package's domain: list, echo, hz", [
        ("list", "topics in the graph", topic_list, types_flag),
        ("echo", "print a topic's messages as YAML", topic_echo, echo_args),
        ("hz", "a topic's message rate (wall clock)", topic_hz, hz_args)])
    _group(subparsers, "service", "ros2 service, for this package's domain: list, call", [
        ("list", "services in the graph", service_list, types_flag),
        ("call", "call a service with a YAML request", service_call, call_args)])
    _group(subparsers, "param", "ros2 param, for this package's domain: list, get, set", [
        ("list", "parameters of a node (or of every node)", param_list, node_opt),
        ("get", "one parameter's value", param_get, get_args),
        ("set", "change a parameter of a running node", param_set, set_args)])

    parser = subparsers.add_parser("shoot", help="set the puck moving in the running simulation",
                                   description=shoot.__doc__ + " Example: air-hockey shoot --speed 3 --angle 150")
    parser.add_argument("--speed", type=number(0.0), required=True, help="[m/s] puck speed")
    parser.add_argument("--angle", type=number(-360.0, 360.0), required=True,
                        help="[deg] direction in the table frame (0: toward iiwa_back's goal, 180: toward iiwa_front's)")
    parser.add_argument("--x", type=number(), default=None, help="[m] start x (default: where the puck is)")
    parser.add_argument("--y", type=number(), default=None, help="[m] start y (default: where the puck is)")
    parser.add_argument("--spin", type=number(), default=0.0, help="[rad/s] spin (default 0)")
    _common(parser, wait=False)
    parser.set_defaults(run=_with_probe(shoot), command="shoot")
