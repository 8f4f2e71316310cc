"""Parameter declarations and default parameter files (ROS-free).

Every tunable has its default in a ROS 2 parameter file under ``config/`` (with a comment giving its
source); code declares only the name, type, meaning and valid range (:class:`ParamSpec`), in the
spirit of generate_parameter_library. Nodes load the defaults, let ``--params-file``/``-p`` override
them, and refuse out-of-range values at start-up with a one-line message.
"""
from __future__ import annotations

import fnmatch
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import yaml


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader reading numbers as ROS 2 does: YAML 1.1 (PyYAML) takes ``1e-3`` and ``2E5``,
    written without a decimal point, for strings, while ROS 2's parameter parser takes them for doubles."""


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9]+[eE][-+]?[0-9]+$"),
                              list("-+0123456789"))


def yaml_load(text: str) -> Any:
    """A YAML document as ROS 2 reads it (:class:`_Loader`); raises ``yaml.YAMLError``."""
    return yaml.load(text, Loader=_Loader)


class ParameterFileError(ValueError):
    """A parameter file is missing, unreadable or malformed."""


class ParameterValueError(ValueError):
    """A parameter value has the wrong type or is out of range."""


@dataclass(frozen=True)
class ParamSpec:
    """Declaration of one parameter: its type, meaning (with unit) and valid closed range."""

    name: str
    type: type  # float, int, bool, str, or list (of floats)
    description: str
    low: float | None = None
    high: float | None = None
    length: int | None = None  # required length for list parameters
    choices: tuple | None = None  # allowed values of a str parameter

    def check(self, value: Any) -> Any:
        """Return ``value`` coerced to the declared type, or raise :class:`ParameterValueError`."""
        value = self._coerce(value)
        if self.choices is not None and value not in self.choices:
            raise ParameterValueError(f"parameter '{self.name}' = {value!r} is not one of "
                                      f"{', '.join(map(str, self.choices))} ({self.description})")
        items = value if isinstance(value, list) else [value]
        if self.length is not None and len(items) != self.length:
            raise ParameterValueError(f"parameter '{self.name}' needs {self.length} values, got {len(items)}")
        if self.type in (float, int, list):
            for item in items:
                if not math.isfinite(item):
                    raise ParameterValueError(f"parameter '{self.name}' must be finite, got {item}")
                if self.low is not None and item < self.low or self.high is not None and item > self.high:
                    raise ParameterValueError(
                        f"parameter '{self.name}' = {item} is outside [{self.low}, {self.high}] ({self.description})")
        return value

    def _coerce(self, value: Any) -> Any:
        kind = self.type
        if kind is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if kind is int and isinstance(value, int) and not isinstance(value, bool):
            return value
        if kind is bool and isinstance(value, bool):
            return value
        if kind is str and isinstance(value, str):
            return value
        if kind is list and isinstance(value, (list, tuple)) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return [float(v) for v in value]
        wanted = "a list of numbers" if kind is list else f"of type {kind.__name__}"
        raise ParameterValueError(f"parameter '{self.name}' must be {wanted}, got {type(value).__name__} {value!r}")


def _node_sections(document: Mapping[str, Any], fq_name: str) -> Iterable[Mapping[str, Any]]:
    """Yield the ``ros__parameters`` blocks of a parameter document that apply to node ``fq_name``.

    Keys follow the ROS 2 convention: ``/**`` (every node), ``/**/name`` (any namespace), an exact
    fully qualified name, or a bare node name. Wildcards are applied first so that exact keys win.
    """
    def rank(key: str) -> int:
        return 0 if "*" in key else 1

    for key in sorted(document, key=rank):
        block = document[key]
        pattern = key if key.startswith("/") else "/" + key
        name_only = fq_name.rsplit("/", 1)[-1]
        if (fnmatch.fnmatchcase(fq_name, pattern.replace("/**", "*"))
                or (not key.startswith("/") and key == name_only)):
            if not isinstance(block, Mapping) or "ros__parameters" not in block:
                raise ParameterFileError(f"section '{key}' has no 'ros__parameters' mapping")
            yield block["ros__parameters"] or {}


def _flatten(block: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in block.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(_flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def _read_document(path: Path) -> Mapping[str, Any] | None:
    """A parameter file's YAML document (None when empty), or :class:`ParameterFileError` naming the file."""
    try:
        document = yaml_load(Path(path).read_text())
    except OSError as exc:
        raise ParameterFileError(f"{path}: cannot read parameter file ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise ParameterFileError(f"{path}: not valid YAML ({exc.__class__.__name__})") from exc
    if document is not None and not isinstance(document, Mapping):
        raise ParameterFileError(f"{path}: a parameter file must map node names to 'ros__parameters'")
    return document


def load_parameter_file(path: Path, fq_name: str) -> dict[str, Any]:
    """Return the parameters in one ROS 2 parameter file that apply to node ``fq_name``."""
    return _document_values(_read_document(path), path, fq_name)


def _document_values(document: Mapping[str, Any] | None, path: Path, fq_name: str) -> dict[str, Any]:
    """The parameters in ``path``'s read ``document`` that apply to node ``fq_name``."""
    if document is None:
        return {}
    values: dict[str, Any] = {}
    try:
        for block in _node_sections(document, fq_name):
            values.update(_flatten(block))
    except ParameterFileError as exc:
        raise ParameterFileError(f"{path}: {exc}") from exc
    return values


def load_defaults(paths: Iterable[Path], fq_name: str, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Merge parameter files (later files win) and check every declared parameter has a valid default."""
    paths = list(paths)
    values: dict[str, Any] = {}
    sources: dict[str, Path] = {}
    for path in paths:
        read = load_parameter_file(path, fq_name)
        values.update(read)
        sources.update(dict.fromkeys(read, path))
    return _with_defaults(values, paths, fq_name, specs, sources)


def _with_defaults(values: Mapping[str, Any], paths: Sequence[Path], fq_name: str,
                   specs: Iterable[ParamSpec], sources: Mapping[str, Path]) -> dict[str, Any]:
    """Every declared parameter's value from the merged ``values`` of ``paths``, checked against its spec; a
    bad value's error names the file it came from (``sources``: name -> file)."""
    result = {}
    for spec in specs:
        if spec.name not in values:
            raise ParameterFileError(
                f"no default for parameter '{spec.name}' of {fq_name} in {', '.join(str(p) for p in paths)}")
        try:
            result[spec.name] = spec.check(values[spec.name])
        except ParameterValueError as exc:
            raise ParameterValueError(f"{sources[spec.name]}: {fq_name}: {exc}") from None
    return result


def load_node_params(default_files: Iterable[str], fq_name: str, specs: Iterable[ParamSpec],
                     extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """A node's parameters outside ROS: the defaults in ``config/<default_files>``, overridden by
    ``extra_files`` in order (as ``--params-file`` does for a running node)."""
    from air_hockey_agent.param_registry import node_parameters
    from air_hockey_agent.paths import config_file
    specs = list(specs)
    files = [config_file(name) for name in default_files] + [Path(f) for f in extra_files]
    node, own, nodes = fq_name.rsplit("/", 1)[-1], [spec.name for spec in specs], node_parameters()
    values: dict[str, Any] = {}
    sources: dict[str, Path] = {}
    for path in files:  # each read once; a misspelled section or key is an error, not a silently ignored
        document = _read_document(path)  # line: in an edited config/ (or AIR_HOCKEY_CONFIG_DIR's) as in a
        _check_document(document, path, node, own, nodes)  # --params-file
        read = _document_values(document, path, fq_name)
        values.update(read)
        sources.update(dict.fromkeys(read, path))
    return _with_defaults(values, files, fq_name, specs, sources)


def yaml_float(value: float) -> str:
    """A float as YAML 1.1 (PyYAML, ROS 2) reads back as a float: ``1e-06`` would be a string there."""
    text = f"{float(value):.9g}"
    if "e" in text and "." not in text.split("e")[0]:
        text = text.replace("e", ".0e")
    elif "." not in text and "e" not in text and text.lstrip("-").isdigit():
        text += ".0"
    return text


def yaml_value(value: float | list[float] | tuple[float, ...]) -> str:
    """A float, or a list of them as a flow sequence, as YAML that reads back as floats (:func:`yaml_float`)."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(yaml_float(v) for v in value) + "]"
    return yaml_float(value)


def validate(specs: Iterable[ParamSpec], values: Mapping[str, Any]) -> dict[str, Any]:
    """Check a complete set of values against their specs; raise on the first bad one."""
    return {spec.name: spec.check(values[spec.name]) for spec in specs}


# --- names: a misspelled parameter or node section is an error, not silence ------------------------
ROS_BUILTIN = ("use_sim_time", "qos_overrides.", "start_type_description_service")  # rclpy's own (prefixes)


def closest(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known`` to ``name``, or an empty string."""
    import difflib
    match = difflib.get_close_matches(name, sorted(set(known)), n=1, cutoff=0.6)
    return f" (did you mean '{match[0]}'?)" if match else ""


def _builtin(name: str) -> bool:
    return any(name == b or (b.endswith(".") and name.startswith(b)) for b in ROS_BUILTIN)


def ros_param_args(argv: Iterable[str]) -> tuple[list[str], list[str]]:
    """Parameter names given with ``-p NAME:=VALUE`` and files given with ``--params-file FILE`` in the
    ``--ros-args`` parts of ``argv`` (up to ``--`` or the next ``--ros-args``)."""
    names, files, inside, pending = [], [], False, None
    for arg in argv:
        if arg == "--ros-args":
            inside, pending = True, None
        elif arg == "--":
            inside, pending = False, None
        elif not inside:
            continue
        elif pending == "p":
            names.append(arg.split(":=", 1)[0].split(":", 1)[-1] if ":=" in arg else arg)
            pending = None
        elif pending == "file":
            files.append(arg)
            pending = None
        elif arg in ("-p", "--param"):
            pending = "p"
        elif arg == "--params-file":
            pending = "file"
    return names, files


def _section_node(key: str) -> str | None:
    """The node name a parameter file section is for; None for every node (``/**``, ``/*``)."""
    last = key.rstrip("/").rsplit("/", 1)[-1]
    return None if last in ("**", "*", "") else last


def check_parameter_file(path: Path, node: str, own: Iterable[str], nodes: Mapping[str, Iterable[str]]) -> None:
    """Raise :class:`ParameterFileError` naming the file, section and key when ``path`` has a section
    for no node in ``nodes`` (name -> its parameter names), a key the node it is for does not declare,
    or, in a section for every node, a key no node declares. ``node`` with its names ``own`` is the one
    reading the file."""
    _check_document(_read_document(path), path, node, own, nodes)


def _check_document(document: Mapping[str, Any] | None, path: Path, node: str, own: Iterable[str],
                    nodes: Mapping[str, Iterable[str]]) -> None:
    """:func:`check_parameter_file` on ``path``'s read ``document``."""
    if document is None:
        return
    known = {name: set(names) for name, names in nodes.items()}
    known[node] = set(own)
    everything = set().union(*known.values())
    for key, block in document.items():
        target = _section_node(str(key))
        if target is not None and target not in known:
            raise ParameterFileError(f"{path}: section '{key}' names no node of air_hockey_agent"
                                     f"{closest(target, known)}")
        if not isinstance(block, Mapping) or "ros__parameters" not in block:
            raise ParameterFileError(f"{path}: section '{key}' has no 'ros__parameters' mapping")
        names = known[target] if target is not None else everything
        for name in _flatten(block["ros__parameters"] or {}):
            if name not in names and not _builtin(name):
                whose = f"node '{target}'" if target is not None else "any node"
                raise ParameterFileError(f"{path}: section '{key}': '{name}' is not a parameter of {whose}"
                                         f"{closest(name, names)}")


def file_nodes(path: Path) -> set[str | None]:
    """The nodes a parameter YAML's sections name (None for a '/**' section, which every node reads)."""
    return {_section_node(str(key)) for key in (_read_document(path) or {})}


def check_only_nodes(path: Path, allowed: Sequence[str], what: str,
                     why: str = "the variant's robot is chosen per game") -> None:
    """Raise :class:`ParameterFileError` naming ``path``, the section and the key when the file sets a
    parameter of a node other than ``allowed`` (a section named for another node, or in a section for
    every node a name none of ``allowed`` declares), or a section for one namespace only (the robot a
    variant plays changes from game to game: ``why``); ``what`` says where the file was given, e.g. '--versus'.
    The names themselves are checked by :func:`check_parameter_file`."""
    from air_hockey_agent.param_registry import node_parameters
    document = _read_document(path) or {}
    nodes = node_parameters()
    names = set().union(*(nodes[n] for n in allowed))
    for key, block in document.items():
        target = _section_node(str(key))
        if target is not None and target not in allowed:
            raise ParameterFileError(f"{path}: section '{key}': {what} sets only {_listed(allowed)} parameters")
        if key not in ("/**", f"/**/{target}"):  # rcl matches these in every namespace, as the in-process game does
            raise ParameterFileError(f"{path}: section '{key}': {what} takes sections for any namespace, "
                                     f"'/**/{target or allowed[0]}' or '/**' ({why})")
        params = block.get("ros__parameters") if isinstance(block, Mapping) else None
        for name in _flatten(params or {}) if target is None else ():
            if name not in names and not _builtin(name):
                raise ParameterFileError(f"{path}: section '{key}': '{name}' is not a parameter of "
                                         f"{' or '.join(allowed)} ({what} sets only theirs){closest(name, names)}")


def check_files_read(paths: Iterable[Path], readers: Sequence[str], flag: str = "--params-file") -> None:
    """Raise :class:`ParameterFileError` naming the first of ``paths`` that sets no parameter of any of
    ``readers`` (the node sections a command reads): a file meant for another node or command, which would
    otherwise change nothing without a word. A section for every node ('/**') counts with the keys one of
    ``readers`` declares. Names are checked by :func:`check_parameter_file`."""
    from air_hockey_agent.param_registry import node_parameters
    nodes = node_parameters()
    names = set().union(*(nodes[n] for n in readers))
    for path in paths:
        document = _read_document(path) or {}
        read = False
        for key, block in document.items():
            params = block.get("ros__parameters") if isinstance(block, Mapping) else None
            keys = set(_flatten(params or {}))
            target = _section_node(str(key))
            read = read or bool(keys & names if target is None else keys and target in readers)
        if not read:
            sections = _listed([f"'{key}'" for key in document]) if document else "none"
            raise ParameterFileError(f"{path}: {flag} sets no parameter of {_listed(readers)}, which this command "
                                     f"reads (its sections: {sections})")


def file_problem(path: Path, flag: str, check: Callable[[Path, str], Any]) -> str:
    """What is wrong with the parameter file ``path`` given as ``flag`` as one line naming the file (no such
    file, or what ``check(path, flag)`` raised: :class:`ParameterFileError`, :class:`ParameterValueError`);
    '' when it passes."""
    if not path.is_file():
        return f"{flag} {path}: no such file"
    try:
        check(path, flag)
    except (ParameterFileError, ParameterValueError) as exc:
        return f"{flag}: {exc}" if str(path) in str(exc) else f"{flag} {path}: {exc}"
    return ""


def _listed(names: Sequence[str]) -> str:
    """'a', 'a and b', 'a, b and c'."""
    return " and ".join(names) if len(names) < 3 else f"{', '.join(names[:-1])} and {names[-1]}"


def check_command_line(argv: Iterable[str], node: str, own: Iterable[str]) -> None:
    """Raise :class:`ParameterValueError` for a ``-p NAME:=VALUE`` whose name the node does not declare."""
    own = set(own)
    for name in ros_param_args(argv)[0]:
        if name not in own and not _builtin(name):
            raise ParameterValueError(f"-p {name}: '{name}' is not a parameter of {node}{closest(name, own)}")
