"""The discrepancy workflow (issue 11): find where simulation and measurement
disagree (localised, noise-scaled), separate miscalibration from missing
physics, name the missing effect from the effect library, add it to the
design and show the held-out gap shrink.

``entry.main`` is the CLI / stage entry (the only file I/O);
``workflow.run`` works on prepared records (``features.Unit``); its
records problem is in ``problem``, the refits (the calibration core's
Gauss-Newton) in ``refits``, the statistics and decisions in ``decision``."""

from .workflow import Candidate, Problem, catalogue, run, verdict_document

__all__ = ["Candidate", "Problem", "catalogue", "run", "verdict_document"]
