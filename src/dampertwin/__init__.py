"""dampertwin: a calibrated digital twin of a semi-active shock absorber."""

__version__ = "0.1.0"

from .excitation import Excitation
from .simulation import Result, simulate, simulate_batch

__all__ = ["Excitation", "Result", "simulate", "simulate_batch"]
