"""Design descriptions: the 105 parameters of thesis table 5.1 (see schema)."""

from .description import (ConfigTextError, Constant, Design, DesignError, EffectParameter, Parameter, PQMap, load, loads, write_map,
                          yaml_load, yaml_load_file)
from .schema import CONSTANTS, EFFECT_PARAMETERS, EFFECTS, PARAMETERS, SI_UNITS, TYPES

__all__ = [
    "Constant", "Design", "DesignError", "EffectParameter", "EFFECT_PARAMETERS", "Parameter", "PQMap", "load", "loads", "write_map", "yaml_load", "yaml_load_file",
    "ConfigTextError",
    "CONSTANTS", "EFFECTS", "PARAMETERS", "SI_UNITS", "TYPES",
]
