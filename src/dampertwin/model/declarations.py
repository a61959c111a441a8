"""How a submodel declares what it brings to the assembled model.

Each physics file (``fluid.py``, ``chambers.py``, ``valves.py``, ...) lists
its ``STATES`` and ``PARAMETERS`` next to its equations; ``layout.py`` only
concatenates those lists, and the state scales, the initial state and (by
probing the compiled right-hand side) the Jacobian sparsity are derived from
them. Adding a state or a parameter to a submodel therefore touches that
submodel's file and, for a design parameter, the design description only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum


@dataclass(frozen=True)
class State:
    """One state of the ODE system.

    ``scale`` is its typical magnitude in SI (the integrator works on
    state/scale and measures errors there); ``initial`` is the rest value,
    either a number or a function of the packed parameters (a
    :class:`~dampertwin.model.layout.ParamView`)."""

    name: str
    unit: str
    scale: float
    initial: float | Callable = 0.0
    description: str = ""


@dataclass(frozen=True)
class Parameter:
    """One entry of the compiled parameter vector.

    ``source`` says where its value comes from: a design key (``"oil.K_oil"``,
    ``"constants.P_atm"``, ``"effects.gas_content"`` -> 1.0 / 0.0), a function
    of the :class:`~dampertwin.design.Design`, or ``None`` for a test
    condition that the simulation sets (current, bench, excitation grid)."""

    name: str
    unit: str
    source: str | Callable | None
    description: str = ""


def index_enum(name: str, names: list[str] | tuple[str, ...], module: str) -> type[IntEnum]:
    """An IntEnum numbering ``names`` 0..n-1. Numba freezes IntEnum members as
    compile-time integer constants, so ``y[S.P_r]`` costs nothing at run time."""
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if list(names).count(n) > 1})
        raise ValueError(f"{name}: duplicate declarations {dup}")
    return IntEnum(name, {n: i for i, n in enumerate(names)}, module=module)
