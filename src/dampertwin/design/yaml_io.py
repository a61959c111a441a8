"""YAML of the project's config files: YAML 1.2 numbers and booleans, unique
mapping keys, size and encoding checks, and the dumper of design files."""

from __future__ import annotations

import os
import re
from pathlib import Path

import yaml

from ..errors import UserError


# --- YAML: accept 1e-6 as a float (YAML 1.2), which PyYAML reads as a string.
# On libyaml's C parser where PyYAML has it (its wheels do): the same resolvers
# and constructors, ~9x faster on a design file than the pure-Python parser.
class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    pass


_FLOAT_RE = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""",
    re.X,
)
_Loader.yaml_implicit_resolvers = {
    k: [(tag, rx) for tag, rx in v if tag not in ("tag:yaml.org,2002:float", "tag:yaml.org,2002:bool",
                                                 "tag:yaml.org,2002:int")]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_RE, list("-+0123456789."))
# YAML 1.2 integers: decimal (017 is 17, not YAML 1.1's octal 15), 0x hex, 0o octal; no YAML 1.1
# sexagesimal (an unquoted 2:00:00 is the string "2:00:00", not 7200)
_INT_RE = re.compile(r"^(?:[-+]?[0-9][0-9_]*|0x[0-9a-fA-F][0-9a-fA-F_]*|0o[0-7][0-7_]*)$")
_Loader.add_implicit_resolver("tag:yaml.org,2002:int", _INT_RE, list("-+0123456789"))


def _construct_int(loader, node) -> int:
    v = loader.construct_scalar(node).replace("_", "")
    sign, v = (-1, v[1:]) if v[:1] == "-" else (1, v.lstrip("+"))
    base = 16 if v.startswith("0x") else 8 if v.startswith("0o") else 10
    return sign * int(v[2:] if base != 10 else v, base)


_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)
# YAML 1.2 booleans only: an unquoted `no: 1` key is the string "no".
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)


def _construct_mapping_unique(loader, node, deep=False):
    """A mapping whose keys are unique: a second ``value:`` in one entry is an
    error naming the key and both lines, never "last one wins"."""
    seen: dict = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=True)
        try:
            first = seen.get(key)
        except TypeError:  # unhashable key: the base constructor reports it
            continue
        if first is not None:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {first.line + 1})", key_node.start_mark)
        seen[key] = key_node.start_mark
    return yaml.constructor.SafeConstructor.construct_mapping(loader, node, deep=deep)


_Loader.construct_mapping = _construct_mapping_unique  # type: ignore[method-assign]


MAX_YAML_VALUES = 200_000  # values a config may expand to: aliases repeating aliases (a "billion laughs") stop here


def yaml_load(text: str):
    """YAML with 1.2 numbers and booleans (``1e-6`` is a float, ``no`` a
    string) and unique mapping keys; used for every config file of the project.
    A document expanding to more than MAX_YAML_VALUES values is a YAMLError."""
    doc = yaml.load(text, Loader=_Loader)
    stack, n = [doc], 0
    while stack:  # aliases share objects here; every later walk (a deep copy, JSON) would expand them
        o = stack.pop()
        n += 1
        if n > MAX_YAML_VALUES:
            raise yaml.YAMLError(f"the document expands to more than {MAX_YAML_VALUES} values (aliases of "
                                 f"aliases?); expected a config file")
        if isinstance(o, dict):
            stack.extend(o.values())
        elif isinstance(o, list):
            stack.extend(o)
    return doc


def yaml_error_line(e: Exception) -> str:
    """One line for a YAML error: 'line N: problem' (no echo of the file)."""
    mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
    problem = getattr(e, "problem", None) or getattr(e, "context", None) or str(e) or type(e).__name__
    return f"line {mark.line + 1}, column {mark.column + 1}: {problem}" if mark is not None else str(problem)


MAX_CONFIG_BYTES = 5 * 1024 * 1024  # design / variant / config files larger than this are refused


class ConfigTextError(UserError):
    """A config file that is not readable UTF-8 text (message names the file)."""


def read_config_text(path: str | os.PathLike, max_bytes: int = MAX_CONFIG_BYTES) -> str:
    """The text of a small UTF-8 config file; ConfigTextError naming the file
    if it is missing, too large, binary or not UTF-8."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise ConfigTextError(f"{path}: file is {size / 1e6:.1f} MB; expected a text file of at most "
                                  f"{max_bytes / 1e6:.0f} MB")
        data = path.read_bytes()
    except OSError as e:
        raise ConfigTextError(f"{path}: cannot read: {e.strerror or e}") from None
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ConfigTextError(f"{path}: binary file (NUL byte at offset {nul}); expected UTF-8 YAML text")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigTextError(f"{path}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start}); "
                              f"expected UTF-8 YAML text") from None


def yaml_load_file(path: str | os.PathLike, max_bytes: int = MAX_CONFIG_BYTES):
    """Read a YAML config file; ConfigTextError naming the file (and the line)
    for unreadable text or invalid YAML (duplicate keys included)."""
    text = read_config_text(path, max_bytes)
    try:
        return yaml_load(text)
    except yaml.YAMLError as e:
        raise ConfigTextError(f"{path}: not valid YAML: {yaml_error_line(e)}") from None
    except RecursionError:
        raise ConfigTextError(f"{path}: YAML nested too deeply") from None


class _Dumper(yaml.SafeDumper):
    pass


# a string our loader would read as a number ("09", "0o17", "1e-6") is written quoted, so it loads back a string
_Dumper.add_implicit_resolver("tag:yaml.org,2002:int", _INT_RE, list("-+0123456789"))
_Dumper.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_RE, list("-+0123456789."))


def _repr_str(dumper: yaml.SafeDumper, s: str):
    style = "|" if "\n" in s else None
    return dumper.represent_scalar("tag:yaml.org,2002:str", s, style=style)


_Dumper.add_representer(str, _repr_str)
