"""The design description: 105 parameters, constants, effect switches and
the parameters of the optional effects (``effect_parameters:``).

A :class:`Design` is immutable. ``load`` reads and validates a YAML file;
``Design.with_overrides`` returns a validated copy (variants and calibration
results are overrides); ``Design.dump`` writes a file that loads back to an
equal design. Validation collects every problem and raises one
:class:`DesignError` listing each with the file, parameter number and name.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
import yaml

from . import architecture as _arch
from .adjusters import adjusters_doc, at_setting, current_setting, parse_adjusters
from .entries import Constant, DesignError, EffectParameter, Parameter
from .parse_effects import _parse_effect_parameters, _parse_effects
from .parse_params import _check_physics, _fill_placeholders, _parse_constants, _parse_parameters
from .pqmap import PQMap, map_from_rows, write_map
from .schema import BY_NUMBER, EFFECT_PARAMETERS, EFFECTS, PARAMETERS, TYPES
from .yaml_io import (MAX_CONFIG_BYTES, ConfigTextError, _Dumper, read_config_text, yaml_error_line, yaml_load,
                      yaml_load_file)

TOP_KEYS = ("design", "description", "architecture", "parameters", "constants", "effects", "effect_parameters",
            "adjusters", "setting")


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

    def with_pq_map(self, pq: PQMap, name: str, source: str) -> "Design":
        """A new design whose active valve (no. 52) is ``pq`` (currents [A] x
        pressure drops [Pa] -> flow [m^3/s]), held in memory: ``name`` is the
        file it is written to beside the design (``write_map``), ``source``
        its source line (how the map was found)."""
        where = f"{self.path or '<design>'}: no. 52 (active_valve.pq_map)"
        if self.pq_map is None:
            raise DesignError([f"{self.path or '<design>'}: a {self.architecture} design has no active valve (no. 52)"])
        errors: list[str] = []
        rows = np.array([(c, dp, pq.flow[i, j]) for i, c in enumerate(pq.currents) for j, dp in enumerate(pq.dps)])
        if map_from_rows(rows, where, name, errors) is None:
            raise DesignError(errors)
        doc = self._doc(self.path.parent if self.path else None)
        for p in doc["parameters"]:
            if p["no"] == 52:
                p["value"], p["source"] = name, source
        return _from_doc(doc, self.path, base_dir=self.path.parent if self.path else Path.cwd(), known_map=pq,
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
        raise DesignError([f"{where}: " + ("a folder; expected a design YAML file" if path.is_dir() else "file not found")])
    try:
        doc = yaml_load_file(path)
    except ConfigTextError as e:
        raise DesignError([str(e)]) from None
    return _from_doc(doc, path, base_dir=path.parent, map_dirs=tuple(Path(d) for d in map_dirs))


def loads(text: str, base_dir: str | os.PathLike = ".", where: str = "<string>", *,
          map_dirs: tuple | list = ()) -> Design:
    try:
        doc = yaml_load(text)
    except yaml.YAMLError as e:
        raise DesignError([f"{where}: not valid YAML: {yaml_error_line(e)}"]) from None
    except RecursionError:
        raise DesignError([f"{where}: YAML nested too deeply"]) from None
    return _from_doc(doc, None, base_dir=Path(base_dir), where=where, map_dirs=tuple(Path(d) for d in map_dirs))


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


__all__ = ["Design", "DesignError", "EffectParameter", "Parameter", "Constant", "PQMap", "load", "loads", "write_map", "yaml_load",
           "yaml_load_file", "read_config_text", "ConfigTextError", "MAX_CONFIG_BYTES"]
