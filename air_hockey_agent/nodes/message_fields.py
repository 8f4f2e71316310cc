"""rclpy messages to and from plain Python data, by their own field introspection (what ``ros2 topic
echo`` and ``ros2 service call`` do with rosidl_runtime_py, which is not among the ROS wheels)."""
from __future__ import annotations

import importlib
from typing import Any

FLOATS = ("double", "float", "float32", "float64")
INTEGERS = ("int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "octet", "byte", "char")


class FieldError(ValueError):
    """A value that does not fit the message (unknown field, wrong type)."""


def interface_class(type_name: str, kind: str):
    """The rclpy class of ``pkg/<kind>/Type`` (also accepted: ``pkg/Type``); ``kind`` is msg or srv."""
    parts = type_name.strip("/").split("/")
    if len(parts) == 2:
        parts = [parts[0], kind, parts[1]]
    if len(parts) != 3 or parts[1] != kind:
        raise FieldError(f"'{type_name}' is not a {kind} type (expected pkg/{kind}/Type)")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.{kind}"), parts[2])
    except (ImportError, AttributeError):
        raise FieldError(f"unknown {kind} type '{type_name}' (not installed in this environment)") from None


def to_plain(value: Any) -> Any:
    """A message (or field value) as dicts, lists and scalars."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: to_plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    if isinstance(value, bytes):
        return list(value)
    return value


def _scalar(kind: str, value: Any, where: str) -> Any:
    try:
        if kind in FLOATS:
            if isinstance(value, bool):
                raise TypeError
            return float(value)
        if kind in INTEGERS:
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise TypeError
            return int(value)
        if kind == "boolean":
            if not isinstance(value, bool):
                raise TypeError
            return value
        if kind.startswith("string") or kind.startswith("wstring"):
            return str(value)
    except (TypeError, ValueError):
        raise FieldError(f"{where}: expected {kind}, got {value!r}") from None
    raise FieldError(f"{where}: fields of type {kind} cannot be set from the command line")


def fill(message: Any, data: Any, where: str = "") -> Any:
    """Set the fields of ``message`` named in the mapping ``data`` (nested for sub-messages); others keep
    their defaults. Raises :class:`FieldError` naming the field."""
    if data is None:
        return message
    if not isinstance(data, dict):
        raise FieldError(f"{where or 'message'}: expected a mapping of field names, got {data!r}")
    fields = message.get_fields_and_field_types()
    for name, value in data.items():
        path = f"{where}.{name}" if where else str(name)
        if name not in fields:
            from air_hockey_agent.params import closest
            raise FieldError(f"{path}: no such field in {type(message).__name__}{closest(str(name), fields)}")
        kind = fields[name]
        current = getattr(message, name)
        if hasattr(current, "get_fields_and_field_types"):
            fill(current, value, path)
        elif kind.startswith("sequence<") or kind.endswith("]"):
            inner = kind[len("sequence<"):].split(",")[0].rstrip(">") if kind.startswith("sequence<") else kind.split("[")[0]
            if not isinstance(value, (list, tuple)):
                raise FieldError(f"{path}: expected a list of {inner}, got {value!r}")
            try:
                setattr(message, name, [_scalar(inner, v, path) for v in value])
            except AssertionError as exc:
                raise FieldError(f"{path}: {exc}") from None
        else:
            setattr(message, name, _scalar(kind, value, path))
    return message
