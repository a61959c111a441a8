"""The design description: 105 parameters, constants, effect switches and
the parameters of the optional effects (``effect_parameters:``).

A :class:`Design` is immutable. ``load`` reads and validates a YAML file;
``Design.with_overrides`` returns a validated copy (variants and calibration
results are overrides); ``Design.dump`` writes a file that loads back to an
equal design. Validation collects every problem and raises one
:class:`DesignError` listing each with the file, parameter number and name.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
import yaml

from ..errors import UserError
from . import architecture as _arch
from .adjusters import adjusters_doc, at_setting, current_setting, parse_adjusters
from .schema import (
    BY_NUMBER,
    CONSTANT_TYPES,
    CONSTANTS,
    EFFECT_PARAMETERS,
    EFFECTS,
    MAP_COLUMNS,
    ORDERED,
    PARAMETERS,
    POSITIVE_SUMS,
    RANGES,
    SI_UNITS,
    TYPES,
)

PARAM_FIELDS = ("no", "name", "symbol", "group", "description", "type", "value", "unit", "source")
CONST_FIELDS = ("name", "symbol", "description", "type", "value", "unit", "source")
TOP_KEYS = ("design", "description", "architecture", "parameters", "constants", "effects", "effect_parameters",
            "adjusters", "setting")
EFFECT_PARAM_FIELDS = ("name", "effect", "symbol", "description", "type", "value", "unit", "source", "typical")
EFFECT_PARAM_TYPES = ("C", "F")


class DesignError(UserError):
    """A design description is invalid; ``errors`` lists every problem."""

    def __init__(self, errors: list[str]):
        self.errors = list(errors)
        n = len(self.errors)
        ValueError.__init__(self, f"{n} problem{'s' * (n != 1)} in design description:\n  - " + "\n  - ".join(self.errors))


# --- YAML: accept 1e-6 as a float (YAML 1.2), which PyYAML reads as a string.
class _Loader(yaml.SafeLoader):
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
    k: [(tag, rx) for tag, rx in v if tag not in ("tag:yaml.org,2002:float", "tag:yaml.org,2002:bool")]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_RE, list("-+0123456789."))
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
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_Loader.construct_mapping = _construct_mapping_unique  # type: ignore[method-assign]


def yaml_load(text: str):
    """YAML with 1.2 numbers and booleans (``1e-6`` is a float, ``no`` a
    string) and unique mapping keys; used for every config file of the project."""
    return yaml.load(text, Loader=_Loader)


def yaml_error_line(e: Exception) -> str:
    """One line for a YAML error: 'line N: problem' (no echo of the file)."""
    mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
    problem = getattr(e, "problem", None) or getattr(e, "context", None) or type(e).__name__
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
        return yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as e:
        raise ConfigTextError(f"{path}: not valid YAML: {yaml_error_line(e)}") from None
    except RecursionError:
        raise ConfigTextError(f"{path}: YAML nested too deeply") from None


class _Dumper(yaml.SafeDumper):
    pass


def _repr_str(dumper: yaml.SafeDumper, s: str):
    style = "|" if "\n" in s else None
    return dumper.represent_scalar("tag:yaml.org,2002:str", s, style=style)


_Dumper.add_representer(str, _repr_str)


@dataclass(frozen=True)
class Parameter:
    """One numbered parameter of table 5.1 (value in SI ``unit``)."""

    no: int
    name: str
    symbol: str
    group: str
    description: str
    type: str
    value: Any  # float, tuple[float, ...] (vector) or str (table file)
    unit: str
    source: str
    bounds: tuple | None = None

    @property
    def key(self) -> str:
        return f"{self.group}.{self.name}"


@dataclass(frozen=True)
class Constant:
    """An unnumbered equation constant (DESIGN.md §3)."""

    name: str
    symbol: str
    description: str
    type: str
    value: float
    unit: str
    source: str


@dataclass(frozen=True)
class EffectParameter:
    """A parameter of an optional physical effect (design key
    ``effect_parameters:``), addressed as ``"<effect>.<name>"``. ``typical``
    is the magnitude a typical real part with this effect has (SI ``unit``);
    ``bounds`` (lower, upper) is required for type C, optional for F."""

    name: str
    effect: str
    symbol: str
    description: str
    type: str
    value: float
    unit: str
    source: str
    typical: float
    bounds: tuple | None = None

    @property
    def key(self) -> str:
        return f"{self.effect}.{self.name}"


@dataclass(frozen=True)
class PQMap:
    """Active-valve characteristic (no. 52): Q [m^3/s] on a current x dp grid.

    ``flow[i, j]`` is the flow at ``currents[i]`` [A] and ``dps[j]`` [Pa].
    """

    currents: np.ndarray
    dps: np.ndarray
    flow: np.ndarray

    def __post_init__(self):
        # read-only copies: a Design caches what it derives from the map (its hash), so the map cannot change
        for name in ("currents", "dps", "flow"):
            a = np.array(getattr(self, name), float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __reduce__(self):
        return (PQMap, (self.currents, self.dps, self.flow))

    def __eq__(self, other):
        return (
            isinstance(other, PQMap)
            and np.array_equal(self.currents, other.currents)
            and np.array_equal(self.dps, other.dps)
            and np.array_equal(self.flow, other.flow)
        )

    __hash__ = None  # type: ignore[assignment]


def _rebuild_design(name, description, parameters, constants, effects, pq_map, path, map_dirs, effect_params,
                    architecture=_arch.DEFAULT, adjusters=None):
    """``Design.__reduce__``'s constructor."""
    return Design(name, description, MappingProxyType(parameters), MappingProxyType(constants),
                  MappingProxyType(effects), pq_map, path, map_dirs, MappingProxyType(effect_params), architecture,
                  adjusters=MappingProxyType(adjusters or {}))


@dataclass(frozen=True, eq=False)
class Design:
    """A validated damper design. Index by ``"group.name"``, a unique bare
    name, or table-5.1 number to get the SI value."""

    name: str
    description: str
    parameters: Mapping[int, Parameter]
    constants: Mapping[str, Constant]
    effects: Mapping[str, bool]
    pq_map: PQMap | None  # None: an architecture without the active valve (design/architecture.py)
    path: Path | None = field(default=None, compare=False)
    map_dirs: tuple = field(default=(), compare=False)  # extra folders the P/Q map may live in
    effect_params: Mapping[str, EffectParameter] = field(default_factory=lambda: MappingProxyType({}))
    architecture: str = _arch.DEFAULT  # design key ``architecture:`` (design/architecture.py)
    adjusters: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))  # name -> adjusters.Adjuster
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        # read-only views of private copies: a Design never changes, so what is derived from it
        # (hash, the packed parameter vector) is computed once and kept in _memo
        for name in ("parameters", "constants", "effects", "effect_params", "adjusters"):
            object.__setattr__(self, name, MappingProxyType(dict(getattr(self, name))))

    def memo(self, key, compute):
        """``compute()`` once per design and key (the design is immutable)."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def __reduce__(self):
        """Picklable (process pools run designs in other processes): the
        read-only mappings travel as dicts and come back read-only."""
        return (_rebuild_design, (self.name, self.description, dict(self.parameters), dict(self.constants),
                                  dict(self.effects), self.pq_map, self.path, self.map_dirs, dict(self.effect_params),
                                  self.architecture, dict(self.adjusters)))

    def effect_parameters(self, effect: str | None = None) -> list[EffectParameter]:
        """The effect parameters (all, or those of one effect), in file order."""
        if effect is not None and effect not in EFFECTS:
            raise KeyError(f"unknown effect {effect!r}; expected one of {', '.join(EFFECTS)}")
        return [e for e in self.effect_params.values() if effect is None or e.effect == effect]

    # ---- access -----------------------------------------------------------
    def param(self, key: int | str) -> Parameter:
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            if int(key) not in self.parameters:
                raise KeyError(f"no parameter number {key} (expected 1..105)")
            return self.parameters[int(key)]
        if not isinstance(key, str):
            raise KeyError(f"parameter key must be a number or a name, got {key!r}")
        no = _resolve_name(key)
        if no is None:
            raise KeyError(f"unknown parameter {key!r} (use 'group.name', e.g. 'piston_rebound.a')")
        return self.parameters[no]

    def __getitem__(self, key: int | str):
        if isinstance(key, str) and key.startswith("constants."):
            return self.constants[key.split(".", 1)[1]].value
        if isinstance(key, str) and key.startswith("effects."):
            return self.effects[key.split(".", 1)[1]]
        if isinstance(key, str) and key in self.effect_params:
            return self.effect_params[key].value
        if isinstance(key, str) and key in EFFECT_PARAMETERS:
            raise KeyError(f"design {self.name!r} has no effect parameter {key!r} (section effect_parameters)")
        return self.param(key).value

    def constant(self, name: str) -> float:
        return self.constants[name].value

    def by_type(self, t: str) -> list[Parameter]:
        if t not in TYPES:
            raise ValueError(f"unknown type {t!r}; expected one of {', '.join(TYPES)}")
        return [p for p in self.parameters.values() if p.type == t]

    def group(self, g: str) -> dict[str, Any]:
        """Values of one group keyed by name (e.g. ``design.group('top_mount')``)."""
        return {p.name: p.value for p in self.parameters.values() if p.group == g}

    def __eq__(self, other):
        """Equal content and documentation (the P/Q map compares by data)."""
        return isinstance(other, Design) and self.hash() == other.hash() and self._doc_no_map() == other._doc_no_map()

    def _doc_no_map(self) -> dict:
        doc = self._doc(None)
        for p in doc["parameters"]:
            if BY_NUMBER[p["no"]].kind == "table":
                p["value"] = None
        return doc

    __hash__ = None  # type: ignore[assignment]

    # ---- adjusters (design/adjusters.py) -----------------------------------
    @property
    def setting(self) -> dict[str, int]:
        """The click of each adjuster (0 = fully closed); {} without ``adjusters:``."""
        return current_setting(self)

    def at_setting(self, setting: Mapping[str, int], source: str | os.PathLike | None = None) -> "Design":
        """A new design with its adjusters at ``setting`` (e.g. ``{"rebound": 3}``), through ``with_overrides``."""
        return at_setting(self, setting, source)

    # ---- variants ---------------------------------------------------------
    def with_overrides(self, overrides: Mapping[Any, Any], source: str | os.PathLike | None = None) -> "Design":
        """A new validated design with some values replaced.

        Keys: a number, ``"group.name"``, a unique bare name,
        ``"constants.NAME"`` or ``"effects.NAME"``. A string value for no. 52
        names another P/Q map file (relative to this design's folder).
        ``source`` (e.g. the variant file) is named in every error.
        """
        base = str(self.path) if self.path else "<design>"
        where = f"{source} (overrides of {base})" if source is not None else (str(self.path) if self.path else "<overrides>")
        if not isinstance(overrides, Mapping):
            raise DesignError([f"{where}: overrides must be a mapping of parameter -> value, got {type(overrides).__name__}"])
        doc = self._doc(self.path.parent if self.path else None)
        doc.pop("setting", None)  # the adjusters' setting follows the overridden values (design/adjusters.py)
        errors: list[str] = []
        pindex = {p["no"]: p for p in doc["parameters"]}
        cindex = {c["name"]: c for c in doc["constants"]}
        eindex = {f"{e['effect']}.{e['name']}": e for e in doc.get("effect_parameters", [])}
        for key, val in overrides.items():
            if isinstance(key, str) and key in EFFECT_PARAMETERS:
                if key not in eindex:
                    errors.append(f"{where}: override of effect parameter {key!r}, which the design does not "
                                  f"declare (section effect_parameters)")
                else:
                    eindex[key]["value"] = _plain(val)
                continue
            if isinstance(key, str) and key.startswith("constants."):
                cname = key.split(".", 1)[1]
                if cname not in cindex:
                    errors.append(f"{where}: override of unknown constant {cname!r}")
                else:
                    cindex[cname]["value"] = _plain(val)
                continue
            if isinstance(key, str) and key.startswith("effects."):
                ename = key.split(".", 1)[1]
                if ename not in doc["effects"]:
                    errors.append(f"{where}: override of unknown effect {ename!r}; expected one of {', '.join(EFFECTS)}")
                else:
                    doc["effects"][ename] = val
                continue
            try:
                no = self.param(key).no
            except KeyError as e:
                errors.append(f"{where}: override of unknown parameter {key!r}: {e.args[0]}")
                continue
            pindex[no]["value"] = _plain(val)
        if errors:
            raise DesignError(errors)
        keep_map = not any(_is_map_key(k) for k in overrides)
        return _from_doc(doc, self.path, base_dir=self.path.parent if self.path else Path.cwd(),
                         known_map=self.pq_map if keep_map else None, where=where if source is not None else None,
                         map_dirs=self.map_dirs)

    # ---- output -----------------------------------------------------------
    def _doc(self, rel_to: Path | None) -> dict:
        params = []
        for no in sorted(self.parameters):
            p = self.parameters[no]
            if _arch.is_placeholder(p.source, self.architecture):
                continue
            value = p.value
            if isinstance(value, tuple):
                value = list(value)
            if BY_NUMBER[no].kind == "table":
                value = _rel(value, rel_to, self.path)
            d = {
                "no": p.no, "name": p.name, "symbol": p.symbol, "group": p.group,
                "description": p.description, "type": p.type, "value": value,
                "unit": p.unit, "source": p.source,
            }
            if p.bounds is not None:
                d["bounds"] = [list(b) if isinstance(b, tuple) else b for b in p.bounds]
            params.append(d)
        consts = [
            {"name": c.name, "symbol": c.symbol, "description": c.description, "type": c.type,
             "value": c.value, "unit": c.unit, "source": c.source}
            for c in self.constants.values() if not _arch.is_placeholder(c.source, self.architecture)
        ]
        doc = {
            "design": self.name,
            "description": self.description,
            **({"architecture": self.architecture} if self.architecture != _arch.DEFAULT else {}),
            "parameters": params,
            "constants": consts,
            "effects": dict(self.effects),
        }
        if self.effect_params:
            doc["effect_parameters"] = [_effect_param_doc(e) for e in self.effect_params.values()]
        doc.update(adjusters_doc(self))
        return doc

    def dumps(self, rel_to: Path | None = None) -> str:
        return yaml.dump(self._doc(rel_to), Dumper=_Dumper, sort_keys=False, width=100, allow_unicode=True)

    def dump(self, path: str | os.PathLike) -> Path:
        """Write the design as YAML (atomically). The P/Q map file is
        referenced relative to the new file's folder."""
        path = Path(path)
        text = self.dumps(path.resolve().parent)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        tmp.write_text(text)
        os.replace(tmp, path)
        return path

    def hash(self) -> str:
        """Stable content hash (hex sha256, 16 chars) of everything that
        affects results: values, types, units, bounds, constants, effects and
        the P/Q map data (not its file name, not descriptions)."""
        return self.memo("hash", self._content_hash)

    def _content_hash(self) -> str:
        content = {
            "p": [
                [p.no, p.type, p.unit, None if BY_NUMBER[p.no].kind == "table" else _canon(p.value), _canon(p.bounds)]
                for p in (self.parameters[n] for n in sorted(self.parameters))
            ],
            "c": sorted([c.name, c.type, c.unit, _canon(c.value)] for c in self.constants.values()),
            "e": sorted(self.effects.items()),
            **({"ep": sorted([e.key, e.type, e.unit, _canon(e.value), _canon(e.bounds)]
                             for e in self.effect_params.values())} if self.effect_params else {}),
            "m": None if self.pq_map is None else [_canon(tuple(self.pq_map.currents)), _canon(tuple(self.pq_map.dps)),
                                                   _canon(tuple(self.pq_map.flow.ravel()))],
            **({"a": self.architecture} if self.architecture != _arch.DEFAULT else {}),
        }
        blob = json.dumps(content, sort_keys=True, separators=(",", ":")).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


def _effect_param_doc(e: EffectParameter) -> dict:
    d = {"name": e.name, "effect": e.effect, "symbol": e.symbol, "description": e.description, "type": e.type,
         "value": e.value, "unit": e.unit, "source": e.source}
    if e.bounds is not None:
        d["bounds"] = list(e.bounds)
    d["typical"] = e.typical
    return d


def _canon(v):
    if v is None:
        return None
    if isinstance(v, (tuple, list)):
        return [_canon(x) for x in v]
    return repr(float(v))


def _plain(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return v


def _rel(value: str, rel_to: Path | None, src: Path | None) -> str:
    if rel_to is None or src is None:
        return value
    absolute = (src.parent / value).resolve() if not os.path.isabs(value) else Path(value)
    return os.path.relpath(absolute, rel_to)


_NAME_INDEX: dict[str, int] = {}
for _s in PARAMETERS:
    _NAME_INDEX[f"{_s.group}.{_s.name}"] = _s.no
_BARE_COUNT: dict[str, list[int]] = {}
for _s in PARAMETERS:
    _BARE_COUNT.setdefault(_s.name, []).append(_s.no)
for _n, _nos in _BARE_COUNT.items():
    if len(_nos) == 1:
        _NAME_INDEX.setdefault(_n, _nos[0])


def _resolve_name(key: str) -> int | None:
    return _NAME_INDEX.get(key)


# ---------------------------------------------------------------- loading
def _env_map_dirs() -> tuple[Path, ...]:
    return tuple(Path(p) for p in os.environ.get("DAMPERTWIN_MAP_DIRS", "").split(os.pathsep) if p)


def load(path: str | os.PathLike, *, map_dirs: tuple | list = ()) -> Design:
    """Read and validate a design YAML file (raises DesignError). The P/Q
    map must lie in the design's folder, in one of ``map_dirs`` or in a
    folder of the environment variable DAMPERTWIN_MAP_DIRS."""
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise DesignError([f"{where}: file not found"])
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise DesignError([str(e)]) from None
    return _from_doc(doc, path, base_dir=path.parent, map_dirs=tuple(Path(d) for d in map_dirs))


def loads(text: str, base_dir: str | os.PathLike = ".", where: str = "<string>", *,
          map_dirs: tuple | list = ()) -> Design:
    try:
        doc = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as e:
        raise DesignError([f"{where}: not valid YAML: {yaml_error_line(e)}"]) from None
    except RecursionError:
        raise DesignError([f"{where}: YAML nested too deeply"]) from None
    return _from_doc(doc, None, base_dir=Path(base_dir), where=where, map_dirs=tuple(Path(d) for d in map_dirs))


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_map_key(key) -> bool:
    try:
        return _resolve_name(key) == 52 if isinstance(key, str) else int(key) == 52
    except (TypeError, ValueError):
        return False


def _from_doc(doc: Any, path: Path | None, base_dir: Path, where: str | None = None,
              known_map: PQMap | None = None, map_dirs: tuple = ()) -> Design:
    where = where or (str(path) if path else "<design>")
    errors: list[str] = []
    if not isinstance(doc, dict):
        raise DesignError([f"{where}: expected a mapping with keys {', '.join(TOP_KEYS)}, got {type(doc).__name__}"])
    for k in doc:
        if k not in TOP_KEYS:
            errors.append(f"{where}: unknown top-level key {k!r}; expected {', '.join(TOP_KEYS)}")
    name = doc.get("design")
    if not isinstance(name, str) or not name:
        errors.append(f"{where}: 'design' must be a non-empty name string")
        name = str(name)
    description = doc.get("description", "")
    if not isinstance(description, str):
        errors.append(f"{where}: 'description' must be a string")
        description = str(description)

    arch = _arch.parse(doc, where, errors)
    params, pq_map = _parse_parameters(doc.get("parameters"), where, base_dir, errors, known_map,
                                       (base_dir, *map_dirs, *_env_map_dirs()), _arch.UNUSED_NUMBERS[arch])
    constants = _parse_constants(doc.get("constants"), where, errors, _arch.UNUSED_CONSTANTS[arch])
    effects = _parse_effects(doc.get("effects"), where, errors)
    _arch.check_effects(arch, effects, where, errors)
    effect_params = _parse_effect_parameters(doc.get("effect_parameters", []), effects, where, errors)
    _fill_placeholders(arch, params, constants)
    _check_physics(params, constants, where, errors)
    _arch.check_gas_volume(arch, {p.key: p.value for p in params.values()}, {c.name: c.value for c in constants.values()},
                           where, errors)
    adjusters = parse_adjusters(doc.get("adjusters"), doc.get("setting"), params, where, errors)
    _arch.check_adjusters(arch, adjusters, where, errors)
    if errors:
        raise DesignError(errors)
    return Design(
        name=name,
        description=description,
        parameters=MappingProxyType(params),
        constants=MappingProxyType(constants),
        effects=MappingProxyType(effects),
        pq_map=pq_map,
        path=path,
        map_dirs=tuple(map_dirs),
        effect_params=MappingProxyType(effect_params),
        architecture=arch,
        adjusters=MappingProxyType(adjusters),
    )


def _fill_placeholders(arch: str, params: dict, constants: dict) -> None:
    """Add the numbers / constants of parts ``arch`` lacks that the file left out (design/architecture.py)."""
    nos, cons = _arch.placeholder_values(arch, {n: p.value for n, p in params.items()},
                                         {n: c.value for n, c in constants.items()})
    src = _arch.PLACEHOLDER.format(arch=arch)
    for no, v in nos.items():
        s = BY_NUMBER[no]
        params[no] = Parameter(no=no, name=s.name, symbol=s.name, group=s.group, description=src, type="F",
                               value=v, unit=s.unit, source=src)
    for name, v in cons.items():
        constants[name] = Constant(name, name, src, "F", float(v), CONSTANTS[name], src)


def _parse_parameters(items, where, base_dir, errors, known_map=None,
                      allowed_dirs=(), optional=()) -> tuple[dict[int, Parameter], PQMap | None]:
    out: dict[int, Parameter] = {}
    pq_map = None
    if not isinstance(items, list):
        errors.append(f"{where}: 'parameters' must be a list of parameter entries (nos. 1..105)")
        return out, None
    seen: dict[int, int] = {}
    for idx, item in enumerate(items):
        label = f"{where}: parameters[{idx}]"
        if not isinstance(item, dict):
            errors.append(f"{label}: expected a mapping, got {type(item).__name__}")
            continue
        no = item.get("no")
        nm = item.get("name")
        if "no" not in item:
            errors.append(f"{label} (name {nm!r}): missing number 'no' (expected an integer 1..105)")
            continue
        if not isinstance(no, int) or isinstance(no, bool) or no not in BY_NUMBER:
            errors.append(f"{label} no. {no!r} ({nm!r}): number outside 1..105 or not an integer")
            continue
        spec = BY_NUMBER[no]
        label = f"{where}: no. {no} ({spec.group}.{spec.name})"
        if no in seen:
            errors.append(f"{label}: duplicated number (entries {seen[no]} and {idx})")
            continue
        seen[no] = idx
        n_err = len(errors)
        for k in item:
            if k not in PARAM_FIELDS + ("bounds",):
                errors.append(f"{label}: unknown field {k!r}; expected {', '.join(PARAM_FIELDS)}, bounds")
        for k in PARAM_FIELDS:
            if k not in item:
                errors.append(f"{label}: missing field {k!r}")
        if nm is not None and nm != spec.name:
            errors.append(f"{label}: name {nm!r} does not match table 5.1 no. {no}; expected {spec.name!r}")
        if item.get("group") is not None and item.get("group") != spec.group:
            errors.append(f"{label}: group {item.get('group')!r}; expected {spec.group!r}")
        for k in ("symbol", "description", "source"):
            if k in item and not isinstance(item[k], str):
                errors.append(f"{label}: field {k!r} must be a string")
        ptype = item.get("type")
        if "type" in item and ptype not in TYPES:
            errors.append(f"{label}: unknown type {ptype!r}; expected one of D, F, C, T")
        unit = item.get("unit")
        if "unit" in item:
            if not isinstance(unit, str) or unit not in SI_UNITS:
                errors.append(f"{label}: unit {unit!r} is unknown or not SI; expected {spec.unit!r}")
            elif unit != spec.unit:
                errors.append(f"{label}: unit {unit!r}; expected the SI unit {spec.unit!r}")
        value = item.get("value")
        bounds = item.get("bounds")
        if spec.kind == "table":
            if bounds is not None:
                errors.append(f"{label}: a P/Q map takes no bounds")
            if not isinstance(value, str) or not value:
                errors.append(f"{label}: value must be the file name of the P/Q map CSV, got {value!r}")
            else:
                map_path = Path(value) if os.path.isabs(value) else _find_map(value, base_dir, allowed_dirs)
                if known_map is not None:
                    pq_map = known_map
                elif _inside(map_path, allowed_dirs or (base_dir,)):
                    pq_map = _read_map(map_path, label, errors)
                else:
                    errors.append(f"{label}: P/Q map {value!r} lies outside the design's folder {str(base_dir)!r}; "
                                  f"expected a file name in that folder (other folders: load(..., map_dirs=[...]) "
                                  f"or DAMPERTWIN_MAP_DIRS)")
        else:
            value = _check_value(value, spec, label, errors)
            bounds = _check_bounds(bounds, ptype, value, spec, label, errors)
        if len(errors) == n_err:
            out[no] = Parameter(
                no=no, name=nm, symbol=item["symbol"], group=item["group"],
                description=item["description"], type=ptype, value=value, unit=unit,
                source=item["source"], bounds=bounds,
            )
    for no in BY_NUMBER:
        if no not in seen and no not in optional:
            s = BY_NUMBER[no]
            errors.append(f"{where}: no. {no} ({s.group}.{s.name}): missing number (table 5.1 has it)")
    return out, pq_map


def _check_value(value, spec, label, errors):
    if spec.kind == "vector":
        if not isinstance(value, list) or not value or not all(_is_num(v) for v in value):
            errors.append(f"{label}: value must be a non-empty list of numbers, got {value!r}")
            return None
        if not all(math.isfinite(v) for v in value):
            errors.append(f"{label}: value has a non-finite entry: {value!r}")
            return None
        return tuple(float(v) for v in value)
    if value is None:
        errors.append(f"{label}: missing value (expected a finite number in {spec.unit})")
        return None
    if not _is_num(value):
        errors.append(f"{label}: value {value!r} is not a number (expected a finite number in {spec.unit})")
        return None
    if not math.isfinite(value):
        errors.append(f"{label}: value {value!r} is not finite")
        return None
    return float(value)


def _check_bounds(bounds, ptype, value, spec, label, errors):
    if bounds is None:
        if ptype == "C":
            errors.append(f"{label}: calibrated (C) parameter has no bounds; expected [lower, upper] in {spec.unit}")
        return None
    if ptype != "C":
        errors.append(f"{label}: bounds given on a type-{ptype} parameter; only C parameters take bounds")
        return None
    if not isinstance(bounds, list) or len(bounds) != 2:
        errors.append(f"{label}: bounds must be [lower, upper], got {bounds!r}")
        return None
    lo, hi = bounds
    if spec.kind == "vector":
        n = len(value) if value is not None else None
        ok = all(isinstance(b, list) and (n is None or len(b) == n) and all(_is_num(x) and math.isfinite(x) for x in b) for b in (lo, hi))
        if not ok:
            errors.append(f"{label}: bounds must be [[lower...], [upper...]] with one finite number per coefficient")
            return None
        pairs = list(zip(lo, hi))
        out = (tuple(float(x) for x in lo), tuple(float(x) for x in hi))
    else:
        if not (_is_num(lo) and _is_num(hi) and math.isfinite(lo) and math.isfinite(hi)):
            errors.append(f"{label}: bounds must be two finite numbers, got {bounds!r}")
            return None
        pairs = [(lo, hi)]
        out = (float(lo), float(hi))
    for k, (a, b) in enumerate(pairs):
        if not a < b:
            errors.append(f"{label}: bounds lower {a!r} >= upper {b!r}")
            return None
    rng = RANGES.get(f"{spec.group}.{spec.name}")
    if rng is not None:
        for end, b in (("lower", out[0]), ("upper", out[1])):
            if not rng.contains(b):
                errors.append(f"{label}: {end} bound {b!r} {spec.unit}; expected the physical range {rng.describe()} "
                              f"(bounds [{out[0]!r}, {out[1]!r}] must lie inside it)")
                return None
    if value is not None:
        vals = value if spec.kind == "vector" else (value,)
        for v, (a, b) in zip(vals, pairs):
            if not a <= v <= b:
                errors.append(f"{label}: value {v!r} outside bounds [{a!r}, {b!r}] {spec.unit}")
                return None
    return out


def _parse_constants(items, where, errors, optional=()) -> dict[str, Constant]:
    out: dict[str, Constant] = {}
    if not isinstance(items, list):
        errors.append(f"{where}: 'constants' must be a list of entries")
        return out
    for idx, item in enumerate(items):
        if not isinstance(item, dict):
            errors.append(f"{where}: constants[{idx}]: expected a mapping")
            continue
        nm = item.get("name")
        label = f"{where}: constant {nm!r}"
        if not isinstance(nm, str) or nm not in CONSTANTS:
            errors.append(f"{label}: unknown constant; expected one of {', '.join(CONSTANTS)}")
            continue
        if nm in out:
            errors.append(f"{label}: duplicated")
            continue
        n_err = len(errors)
        for k in item:
            if k not in CONST_FIELDS:
                errors.append(f"{label}: unknown field {k!r}; expected {', '.join(CONST_FIELDS)}")
        for k in CONST_FIELDS:
            if k not in item:
                errors.append(f"{label}: missing field {k!r}")
        if "type" in item and item["type"] not in CONSTANT_TYPES:
            errors.append(f"{label}: type {item['type']!r}; constants are D or F")
        unit = item.get("unit")
        if "unit" in item and unit != CONSTANTS[nm]:
            kind = "unknown or not SI" if not isinstance(unit, str) or unit not in SI_UNITS else "not the declared SI unit"
            errors.append(f"{label}: unit {unit!r} is {kind}; expected {CONSTANTS[nm]!r}")
        v = item.get("value")
        if "value" in item and (not _is_num(v) or not math.isfinite(v)):
            errors.append(f"{label}: value {v!r} is not a finite number")
        for k in ("symbol", "description", "source"):
            if k in item and not isinstance(item[k], str):
                errors.append(f"{label}: field {k!r} must be a string")
        if len(errors) == n_err:
            out[nm] = Constant(nm, item["symbol"], item["description"], item["type"], float(v), unit, item["source"])
    for nm in CONSTANTS:
        if nm not in out and nm not in optional and not any(isinstance(i, dict) and i.get("name") == nm for i in items):
            errors.append(f"{where}: constant {nm!r} missing (expected in {CONSTANTS[nm]})")
    return out


def _parse_effects(eff, where, errors) -> dict[str, bool]:
    out: dict[str, bool] = {}
    if not isinstance(eff, dict):
        errors.append(f"{where}: 'effects' must be a mapping of switch -> true/false")
        return out
    for k, v in eff.items():
        if k not in EFFECTS:
            errors.append(f"{where}: effects.{k}: unknown effect switch; expected one of {', '.join(EFFECTS)}")
        elif not isinstance(v, bool):
            errors.append(f"{where}: effects.{k}: value {v!r} must be true or false")
        else:
            out[k] = v
    for k in EFFECTS:
        if k not in eff:
            errors.append(f"{where}: effects.{k}: missing switch (expected true or false)")
    return {k: out[k] for k in EFFECTS if k in out}


def _parse_effect_parameters(items, effects, where, errors) -> dict[str, EffectParameter]:
    """The optional ``effect_parameters:`` list: each entry's effect and name
    declared in schema.EFFECT_PARAMETERS, SI unit, type C (bounds required,
    value and typical inside) or F (bounds optional), physical range."""
    out: dict[str, EffectParameter] = {}
    if not isinstance(items, list):
        errors.append(f"{where}: 'effect_parameters' must be a list of entries")
        return out
    for idx, item in enumerate(items):
        if not isinstance(item, dict):
            errors.append(f"{where}: effect_parameters[{idx}]: expected a mapping, got {type(item).__name__}")
            continue
        eff, nm = item.get("effect"), item.get("name")
        key = f"{eff}.{nm}"
        label = f"{where}: effect parameter {key!r}"
        if not isinstance(eff, str) or eff not in EFFECTS:
            errors.append(f"{label}: unknown effect {eff!r}; expected one of {', '.join(EFFECTS)}")
            continue
        if key not in EFFECT_PARAMETERS:
            known = [k.split('.', 1)[1] for k in EFFECT_PARAMETERS if k.startswith(eff + ".")]
            errors.append(f"{label}: unknown parameter {nm!r} of effect {eff!r}; expected one of {', '.join(known) or '(none)'}")
            continue
        if key in out:
            errors.append(f"{label}: duplicated")
            continue
        n_err = len(errors)
        for k in item:
            if k not in EFFECT_PARAM_FIELDS + ("bounds",):
                errors.append(f"{label}: unknown field {k!r}; expected {', '.join(EFFECT_PARAM_FIELDS)}, bounds")
        for k in EFFECT_PARAM_FIELDS:
            if k not in item:
                errors.append(f"{label}: missing field {k!r}")
        for k in ("symbol", "description", "source"):
            if k in item and not isinstance(item[k], str):
                errors.append(f"{label}: field {k!r} must be a string")
        unit_decl, rng = EFFECT_PARAMETERS[key]
        ptype = item.get("type")
        if "type" in item and ptype not in EFFECT_PARAM_TYPES:
            errors.append(f"{label}: type {ptype!r}; effect parameters are C (calibrated, with bounds) or F (fixed)")
        if "unit" in item and item["unit"] != unit_decl:
            errors.append(f"{label}: unit {item['unit']!r}; expected the SI unit {unit_decl!r}")
        vals = {}
        for k in ("value", "typical"):
            v = item.get(k)
            if k not in item:
                continue
            if not _is_num(v) or not math.isfinite(v):
                errors.append(f"{label}: {k} {v!r} is not a finite number (in {unit_decl})")
            elif not rng.contains(v):
                errors.append(f"{label}: {k} {v!r}; expected {rng.describe()} {unit_decl}")
            else:
                vals[k] = float(v)
        bounds = item.get("bounds")
        if bounds is None:
            if ptype == "C":
                errors.append(f"{label}: calibrated (C) effect parameter has no bounds; expected [lower, upper] in {unit_decl}")
        elif not (isinstance(bounds, list) and len(bounds) == 2 and all(_is_num(b) and math.isfinite(b) for b in bounds)):
            errors.append(f"{label}: bounds must be [lower, upper] (two finite numbers), got {bounds!r}")
            bounds = None
        else:
            lo, hi = float(bounds[0]), float(bounds[1])
            bounds = (lo, hi)
            if not lo < hi:
                errors.append(f"{label}: bounds lower {lo!r} >= upper {hi!r}")
            elif not (rng.contains(lo) and rng.contains(hi)):
                errors.append(f"{label}: bounds [{lo!r}, {hi!r}] must lie inside the physical range {rng.describe()} {unit_decl}")
            else:
                for k, v in vals.items():
                    if not lo <= v <= hi:
                        errors.append(f"{label}: {k} {v!r} outside bounds [{lo!r}, {hi!r}] {unit_decl}")
        if len(errors) == n_err:
            out[key] = EffectParameter(name=nm, effect=eff, symbol=item["symbol"], description=item["description"],
                                       type=ptype, value=vals["value"], unit=unit_decl, source=item["source"],
                                       typical=vals["typical"], bounds=bounds)
    for eff, on in effects.items():
        if on:
            missing = [k for k in EFFECT_PARAMETERS if k.startswith(eff + ".") and k not in out
                       and not any(isinstance(i, dict) and f"{i.get('effect')}.{i.get('name')}" == k for i in items)]
            if missing:
                errors.append(f"{where}: effects.{eff} is on but its parameter(s) {', '.join(missing)} are not "
                              f"declared in effect_parameters")
    return out


_KEY_NO = {f"{sp.group}.{sp.name}": sp.no for sp in PARAMETERS}


def _label(key: str) -> str:
    """'no. 3 (geometry.D_R)' or "constant 'P_atm'"."""
    if key.startswith("constants."):
        return f"constant {key.split('.', 1)[1]!r}"
    return f"no. {_KEY_NO[key]} ({key})"


def _check_physics(params: dict, constants: dict, where: str, errors: list[str]) -> None:
    """Physical ranges, ordered pairs and positive sums of schema.RANGES /
    ORDERED / POSITIVE_SUMS, on the entries that parsed."""
    vals: dict[str, float] = {}
    for no, p in params.items():
        if BY_NUMBER[no].kind == "scalar" and isinstance(p.value, float):
            vals[f"{p.group}.{p.name}"] = p.value
    for c in constants.values():
        vals[f"constants.{c.name}"] = c.value
    bad = set()
    for key, rng in RANGES.items():
        if key in vals and not rng.contains(vals[key]):
            errors.append(f"{where}: {_label(key)}: value {vals[key]!r}; expected {rng.describe()} {_unit(key)}")
            bad.add(key)
    for small, large, strict, why in ORDERED:
        if small in vals and large in vals and not bad & {small, large}:
            a, b = vals[small], vals[large]
            if not (a < b if strict else a <= b):
                errors.append(f"{where}: {_label(small)}: value {a!r}; expected {'<' if strict else '<='} "
                              f"{_label(large)} = {b!r} {_unit(small)} ({why})")
    for keys, why in POSITIVE_SUMS:
        if all(k in vals for k in keys) and not bad & set(keys) and not sum(vals[k] for k in keys) > 0:
            errors.append(f"{where}: {_label(keys[0])}: value {vals[keys[0]]!r}; expected "
                          f"{' + '.join(_label(k) for k in keys)} > 0 ({why})")


def _unit(key: str) -> str:
    if key.startswith("constants."):
        return CONSTANTS[key.split(".", 1)[1]]
    return BY_NUMBER[_KEY_NO[key]].unit


def _inside(path: Path, folders) -> bool:
    """True if ``path`` (symlinks resolved) lies in one of ``folders``."""
    try:
        rp = path.resolve()
    except (OSError, RuntimeError):
        return False
    for f in folders:
        try:
            rp.relative_to(Path(f).resolve())
            return True
        except (ValueError, OSError, RuntimeError):
            continue
    return False


def _find_map(name: str, base_dir: Path, folders) -> Path:
    """A relative P/Q map file name: the design's folder first, then the
    other allowed folders in order (``map_dirs``, DAMPERTWIN_MAP_DIRS), e.g.
    a calibrated design whose case names the nominal design's alternative
    map. The design's folder when no folder has it (the error names it)."""
    for f in (base_dir, *folders):
        if (Path(f) / name).is_file():
            return Path(f) / name
    return base_dir / name


def _read_map(path: Path, label: str, errors: list[str]) -> PQMap | None:
    """Read and check the active-valve P/Q map CSV (tidy: current, dp, flow)."""
    if not path.is_file():
        errors.append(f"{label}: P/Q map file {str(path)!r} not found")
        return None
    n0 = len(errors)
    # never echo the file's content: a wrong path may point at anything
    try:
        text = read_config_text(path)
        rows = list(csv.reader(io.StringIO(text)))
    except (ConfigTextError, csv.Error) as e:
        msg = str(e).split(": ", 1)[-1] if isinstance(e, ConfigTextError) else "not a CSV file"
        errors.append(f"{label}: cannot read P/Q map {str(path)!r}: {msg}")
        return None
    if not rows or tuple(c.strip() for c in rows[0]) != MAP_COLUMNS:
        errors.append(f"{label}: P/Q map {str(path)!r}: first line is not the expected header; "
                      f"expected columns {list(MAP_COLUMNS)}")
        return None
    data = []
    for i, r in enumerate(rows[1:], start=2):
        try:
            vals = [float(x) for x in r]
        except ValueError:
            errors.append(f"{label}: P/Q map {str(path)!r} line {i}: non-numeric entry; expected 3 numbers")
            continue
        if len(vals) != 3 or not all(math.isfinite(x) for x in vals):
            errors.append(f"{label}: P/Q map {str(path)!r} line {i}: expected 3 finite numbers, got {len(vals)} "
                          f"value(s)" + (" with NaN/inf" if len(vals) == 3 else ""))
            continue
        data.append(vals)
    if len(errors) > n0:
        return None
    arr = np.array(data, dtype=float).reshape(-1, 3)
    currents = np.unique(arr[:, 0])
    dps = np.unique(arr[:, 1])
    if len(currents) < 2 or len(dps) < 2 or len(arr) != len(currents) * len(dps):
        errors.append(f"{label}: P/Q map {str(path)!r} must be a full grid of >= 2 currents x >= 2 dp values, each pair once")
        return None
    if currents[0] < 0 or dps[0] != 0.0:
        errors.append(f"{label}: P/Q map {str(path)!r}: currents must be >= 0 A and dp must start at 0 Pa (negative dp is the odd extension)")
        return None
    flow = np.full((len(currents), len(dps)), np.nan)
    ci = np.searchsorted(currents, arr[:, 0])
    di = np.searchsorted(dps, arr[:, 1])
    flow[ci, di] = arr[:, 2]
    if np.isnan(flow).any():
        errors.append(f"{label}: P/Q map {str(path)!r}: grid has duplicated (current, dp) pairs")
        return None
    if np.any(flow[:, 0] != 0.0):
        errors.append(f"{label}: P/Q map {str(path)!r}: flow at dp = 0 must be 0")
    if np.any(np.diff(flow, axis=1) <= 0):
        i = int(np.argwhere(np.diff(flow, axis=1) <= 0)[0, 0])
        errors.append(f"{label}: P/Q map {str(path)!r} is not monotone: flow must rise with dp (current {currents[i]} A)")
    if np.any(np.diff(flow, axis=0) > 0):
        errors.append(f"{label}: P/Q map {str(path)!r} is not monotone: flow must not rise with current at fixed dp (higher current = more restriction)")
    if len(errors) > n0:
        return None
    return PQMap(currents, dps, flow)


def write_map(path: str | os.PathLike, pq: PQMap) -> None:
    """Write a P/Q map in the tidy CSV layout read by :func:`load`."""
    lines = [",".join(MAP_COLUMNS)]
    for i, c in enumerate(pq.currents):
        for j, dp in enumerate(pq.dps):
            lines.append(f"{float(c)!r},{float(dp)!r},{float(pq.flow[i, j])!r}")
    Path(path).write_text("\n".join(lines) + "\n")


__all__ = ["Design", "DesignError", "EffectParameter", "Parameter", "Constant", "PQMap", "load", "loads", "write_map", "yaml_load",
           "yaml_load_file", "read_config_text", "ConfigTextError", "MAX_CONFIG_BYTES"]
