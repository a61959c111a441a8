"""The entries of a design description: numbered parameters, constants,
effect parameters, and the error listing every problem of a description."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..errors import UserError

TEXT_FIELDS = ("symbol", "description", "source")  # the free-text fields of an entry


class DesignError(UserError):
    """A design description is invalid; ``errors`` lists every problem."""

    def __init__(self, errors: list[str]):
        self.errors = list(errors)
        n = len(self.errors)
        ValueError.__init__(self, f"{n} problem{'s' * (n != 1)} in design description:\n  - " + "\n  - ".join(self.errors))


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


def check_fields(item: Mapping, required: tuple, label: str, errors: list[str], optional: tuple = ()) -> None:
    """Append to ``errors`` one problem per key of ``item`` that is neither in
    ``required`` nor in ``optional`` (naming the expected fields) and one per
    ``required`` field missing; ``label`` names the file and the entry."""
    for k in item:
        if k not in required and k not in optional:
            errors.append(f"{label}: unknown field {k!r}; expected {', '.join(required + optional)}")
    for k in required:
        if k not in item:
            errors.append(f"{label}: missing field {k!r}")


def check_strings(item: Mapping, keys: tuple, label: str, errors: list[str]) -> None:
    """Append to ``errors`` one problem per field of ``keys`` present in ``item`` but not a string."""
    for k in keys:
        if k in item and not isinstance(item[k], str):
            errors.append(f"{label}: field {k!r} must be a string")
