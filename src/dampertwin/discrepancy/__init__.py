"""The discrepancy workflow (issue 11): find where simulation and measurement
disagree (localised, noise-scaled), separate miscalibration from missing
physics, name the missing effect from the effect library, add it to the
design and show the held-out gap shrink.

``entry.main`` is the CLI / stage entry (the only file I/O);
``workflow.run`` works on prepared records (``features.Unit``)."""

from .workflow import Candidate, FitParam, Problem, catalogue, run, verdict_document

__all__ = ["Candidate", "FitParam", "Problem", "catalogue", "run", "verdict_document"]
