"""dampertwin: a calibrated digital twin of a semi-active shock absorber."""

__version__ = "0.1.0"

from .excitation import Excitation

__all__ = ["Excitation", "Result", "simulate", "simulate_batch"]


def __getattr__(name):
    """``simulate``, ``simulate_batch`` and ``Result`` load the model on first
    use (PEP 562), so importing a subpackage that must not load the model
    (the lab's truth, dampertwin.truth) does not."""
    if name in ("Result", "simulate", "simulate_batch"):
        from . import simulation

        return getattr(simulation, name)
    raise AttributeError(f"module 'dampertwin' has no attribute {name!r}")
