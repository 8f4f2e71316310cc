"""Shared start-up of every air_hockey_agent node: parameters, ``--help``, clean shutdown.

A node subclasses :class:`AirHockeyNode`, lists its default parameter files and its
:class:`~air_hockey_agent.params.ParamSpec` declarations, and its console script calls :func:`run`.
"""
from __future__ import annotations

import signal
import sys
from typing import Any, ClassVar, Sequence

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy._rclpy_pybind11 import RCLError
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile

from air_hockey_agent.params import (ParameterFileError, ParameterValueError, ParamSpec, check_command_line,
                                     check_parameter_file, load_defaults, ros_param_args)
from air_hockey_agent.paths import config_file
from air_hockey_agent.start_up import READY_MARKER, freeze_start_up

EXIT_BAD_PARAMETERS = 2


class NodeStartupError(Exception):
    """A node cannot start (bad input named in the message); it exits with code 2 and one line."""


class NodeFailure(Exception):
    """A node with a job of its own (an optimisation, a replay) could not finish it; it exits with code 1
    and one line saying why."""


EXIT_FAILURE = 1


def _descriptor(spec: ParamSpec) -> ParameterDescriptor:
    # dynamic typing: a whole number given for a float (-p rate:=0, "restitution: 1" in YAML) reaches
    # ParamSpec.check, which turns it into a float, instead of rclpy refusing it for its type
    descriptor = ParameterDescriptor(description=spec.description, dynamic_typing=True)
    if spec.type is float and spec.low is not None and spec.high is not None:
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))]
    elif spec.type is int and spec.low is not None and spec.high is not None:
        descriptor.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)]
    return descriptor


def _latched(qos_profile: QoSProfile | int) -> bool:
    return isinstance(qos_profile, QoSProfile) and qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL


class AirHockeyNode(Node):
    """rclpy node whose parameters are declared from specs with defaults from ``config/``."""

    NAME: ClassVar[str] = ""
    DESCRIPTION: ClassVar[str] = ""
    PARAM_FILES: ClassVar[Sequence[str]] = ()
    PARAMS: ClassVar[Sequence[ParamSpec]] = ()

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.NAME, **kwargs)
        defaults = load_defaults([config_file(f) for f in self.PARAM_FILES],
                                 self.get_fully_qualified_name(), self.PARAMS)
        self.params: dict[str, Any] = {}
        retyped = []
        for spec in self.PARAMS:
            value = self.declare_parameter(spec.name, defaults[spec.name], _descriptor(spec)).value
            self.params[spec.name] = spec.check(value)
            if type(self.params[spec.name]) is not type(value):
                retyped.append(Parameter(spec.name, value=self.params[spec.name]))
        if retyped:  # the parameter server reports what the node runs with (1 -> 1.0)
            self.set_parameters(retyped)
        self._specs = {spec.name: spec for spec in self.PARAMS}
        self.add_on_set_parameters_callback(self._check_parameter_update)
        # the executor exists before the node says it is ready: a Ctrl-C right after that finds a
        # complete executor (one constructed after a shutdown printed rclpy's __del__ tracebacks)
        self.executor_ = SingleThreadedExecutor(context=self.context)
        self.executor_.add_node(self)
        self.changed_params = {k: v for k, v in self.params.items() if v != defaults[k]}

    # rclpy gives every publisher and subscription two QoS event handlers (incompatible QoS and type
    # warnings) by default, and the executor rebuilds and polls all of them in Python on every wake-up:
    # with 14 publishers and subscriptions a received message cost 365-650 us of CPU instead of 111-117 us
    # (measured here: a 100 Hz /clock publisher, one subscriber node with 8 extra publishers and 5 extra
    # subscriptions; it even fell behind and lost messages). Our nodes wake up about 2000 times per
    # simulated second between them, so only latched (transient-local) endpoints, where a QoS mismatch is
    # the usual mistake and which are few, keep rclpy's warnings.
    def create_publisher(self, msg_type, topic, qos_profile, *, event_callbacks=None, **kwargs):
        if event_callbacks is None and not _latched(qos_profile):
            event_callbacks = PublisherEventCallbacks(use_default_callbacks=False)
        return super().create_publisher(msg_type, topic, qos_profile, event_callbacks=event_callbacks, **kwargs)

    def create_subscription(self, msg_type, topic, callback, qos_profile, *, event_callbacks=None, **kwargs):
        if event_callbacks is None and not _latched(qos_profile):
            event_callbacks = SubscriptionEventCallbacks(use_default_callbacks=False)
        return super().create_subscription(msg_type, topic, callback, qos_profile,
                                           event_callbacks=event_callbacks, **kwargs)

    def _check_parameter_update(self, parameters: list) -> SetParametersResult:
        """Refuse run-time parameter changes that fail their spec; apply the rest."""
        checked = {}
        for parameter in parameters:
            spec = self._specs.get(parameter.name)
            if spec is None:
                continue
            try:
                checked[parameter.name] = spec.check(parameter.value)
            except ParameterValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        self.params.update(checked)
        self.on_parameters_changed(checked)
        return SetParametersResult(successful=True)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Hook for nodes that react to parameter changes at run time."""

    def spin(self) -> None:
        """Process callbacks until shutdown; nodes with their own main loop (the simulation) override it."""
        self.executor_.spin()


def format_help(node_cls: type[AirHockeyNode]) -> str:
    """Usage text of a node: description and its parameters with defaults from ``config/``."""
    from air_hockey_agent.tools.argtypes import plain
    lines = [f"usage: {node_cls.NAME} [-h] [--ros-args [--params-file FILE] [-p NAME:=VALUE] [-r FROM:=TO] ...]",
             "", plain(node_cls.DESCRIPTION.strip()), ""]
    try:
        defaults = load_defaults([config_file(f) for f in node_cls.PARAM_FILES], "/" + node_cls.NAME,
                                 node_cls.PARAMS)
    except (ParameterFileError, ParameterValueError) as exc:
        defaults = {}
        lines.append(f"(defaults unavailable: {exc})")
    files = ", ".join(str(config_file(f)) for f in node_cls.PARAM_FILES)
    lines.append(f"parameters (defaults from {files or 'none'}):")
    for spec in node_cls.PARAMS:
        bounds = f" [{spec.low}, {spec.high}]" if spec.low is not None or spec.high is not None else ""
        lines.append(f"  {spec.name} ({spec.type.__name__}{bounds}) = {defaults.get(spec.name, '?')!r}")
        lines.append(f"      {spec.description}")
    return "\n".join(lines)


def _user_args(argv: Sequence[str]) -> list[str]:
    args = list(argv[1:])
    return args[:args.index("--ros-args")] if "--ros-args" in args else args


def check_names(node_cls: type[AirHockeyNode], argv: Sequence[str]) -> None:
    """Refuse ``-p`` names the node does not declare and parameter files with unknown sections or keys
    (rclpy would ignore both silently), before rcl reads the files (a missing or malformed file then
    gets our one-line error, not rcl's)."""
    from air_hockey_agent.param_registry import node_parameters
    own = [spec.name for spec in node_cls.PARAMS]
    check_command_line(argv, node_cls.NAME, own)
    for path in ros_param_args(argv)[1]:
        check_parameter_file(path, node_cls.NAME, own, node_parameters())


def run(node_cls: type[AirHockeyNode], argv: Sequence[str] | None = None) -> int:
    """Run a node until shutdown (Ctrl-C, SIGTERM, or the node itself). Returns the exit code."""
    argv = list(sys.argv if argv is None else argv)
    if any(a in ("-h", "--help") for a in _user_args(argv)):
        print(format_help(node_cls))
        return 0
    # rclpy's own handlers (installed by init, chaining to the Python ones set here) shut the context
    # down and wake the executor, which ends spin() with ExternalShutdownException; the Python handlers
    # raise nothing, so no KeyboardInterrupt surfaces at an arbitrary line inside rclpy.
    try:
        check_names(node_cls, argv)
    except (ParameterFileError, ParameterValueError) as exc:
        print(f"[{node_cls.NAME}] error: {exc}", file=sys.stderr)
        return EXIT_BAD_PARAMETERS
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: None)
    try:
        rclpy.init(args=argv)
    except RCLError as exc:  # e.g. an argument rcl cannot parse
        print(f"[{node_cls.NAME}] error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return EXIT_BAD_PARAMETERS
    node = None
    try:
        node = node_cls()
        if node.changed_params:  # once the node stands (a refused start stays one line)
            node.get_logger().info("parameters other than the defaults: "
                                   + ", ".join(f"{k}={v!r}" for k, v in sorted(node.changed_params.items())))
        node.get_logger().info(f"{READY_MARKER} {node.get_fully_qualified_name()}")
        freeze_start_up()
        node.spin()
    except (ParameterFileError, ParameterValueError, ParameterException, NodeStartupError) as exc:
        print(f"[{node_cls.NAME}] error: {exc}", file=sys.stderr)
        return EXIT_BAD_PARAMETERS
    except NodeFailure as exc:
        print(f"[{node_cls.NAME}] error: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (RCLError, RuntimeError):
        if rclpy.ok():
            raise
        # handles invalidated by the shutdown while a callback was being taken: a normal stop
    finally:
        if node is not None:
            node.executor_.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
