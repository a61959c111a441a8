"""Checkpoint stores of the optimisers (issue 33): a GA hands its state
(a dict of arrays and strings) to a store passed in and asks it back on a
restart; it does no file I/O itself.

- :class:`NpzStore`: one ``.npz`` file, written atomically (temporary file
  + rename), the layout the stages have always used;
- :class:`MemoryStore`: in memory (tests, notebooks);
- :func:`as_store`: None / a path / a store -> a store or None (the stage
  and CLI layer's conversion);
- :func:`require_store`: None / a store, what the GA accepts (a path is
  refused: the caller opens the file store).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Protocol

import numpy as np


class CheckpointStore(Protocol):
    def load(self) -> dict | None:
        """The last saved state, or None."""

    def save(self, state: dict) -> None:
        """Replace the saved state."""


class NpzStore:
    """A checkpoint in one .npz file (atomic replace on every save)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)

    def load(self) -> dict | None:
        if not self.path.is_file():
            return None
        with np.load(self.path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}

    def save(self, state: dict) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.stem}.tmp{os.getpid()}.npz")
        np.savez(tmp, **state)
        os.replace(tmp, self.path)


class MemoryStore:
    """A checkpoint held in memory (copies of the arrays)."""

    def __init__(self):
        self.state: dict | None = None
        self.saves = 0

    def load(self) -> dict | None:
        return None if self.state is None else {k: np.array(v) for k, v in self.state.items()}

    def save(self, state: dict) -> None:
        self.state = {k: np.array(v) for k, v in state.items()}
        self.saves += 1


def as_store(checkpoint) -> CheckpointStore | None:
    """None -> None; a path -> :class:`NpzStore`; a store -> itself."""
    if checkpoint is None or checkpoint == "":
        return None
    if isinstance(checkpoint, (str, os.PathLike)):
        return NpzStore(checkpoint)
    if not (hasattr(checkpoint, "load") and hasattr(checkpoint, "save")):
        raise TypeError(f"checkpoint: expected a path or a store with load() / save(), got {type(checkpoint).__name__}")
    return checkpoint


def require_store(checkpoint) -> CheckpointStore | None:
    """None -> None; a store (``load()`` / ``save(state)``) -> itself; a
    path or anything else -> TypeError (an optimiser does no file I/O: the
    stage or CLI layer passes e.g. ``NpzStore(path)``)."""
    if checkpoint is None:
        return None
    if isinstance(checkpoint, (str, os.PathLike)):
        raise TypeError(f"checkpoint: got the path {str(checkpoint)!r}; pass a store (e.g. "
                        f"dampertwin.checkpoint.NpzStore(path)): an optimiser does no file I/O")
    return as_store(checkpoint)


__all__ = ["CheckpointStore", "NpzStore", "MemoryStore", "as_store", "require_store"]
