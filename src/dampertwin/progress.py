"""Progress reporting: a tqdm bar on a terminal, one plain line per step
otherwise (a log file or a CI job gets no carriage-return redraws).

``progress(...)`` takes tqdm's arguments (``iterable``, ``total``, ``desc``,
``initial``, ``disable``, ``leave``) and supports the calls the project makes:
iteration, ``update(n)``, ``set_postfix(**kw)`` and ``close()``.
"""

from __future__ import annotations

import sys
import time


class LineProgress:
    """tqdm's interface, writing ``desc: k/total [elapsed] key=value`` once per step."""

    def __init__(self, iterable=None, total=None, desc: str = "", initial: int = 0, file=None):
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)
        self.total, self.desc, self.n = total, desc or "progress", int(initial)
        self.file = file if file is not None else sys.stderr
        self.postfix = ""
        self.t0 = time.monotonic()

    def __iter__(self):
        for x in self.iterable:
            yield x
            self.update(1)

    def set_postfix(self, **kw) -> None:
        self.postfix = ", ".join(f"{k}={v}" for k, v in kw.items())

    def update(self, n: int = 1) -> None:
        self.n += n
        of = f"/{self.total}" if self.total is not None else ""
        line = f"{self.desc}: {self.n}{of} [{time.monotonic() - self.t0:.1f} s]"
        print(line + (f" {self.postfix}" if self.postfix else ""), file=self.file, flush=True)

    def close(self) -> None:
        pass


class _Silent(LineProgress):
    def update(self, n: int = 1) -> None:
        self.n += n


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress(iterable=None, total=None, desc: str = "", *, initial: int = 0, disable: bool = False,
             leave: bool = True, file=None):
    """A tqdm bar when ``file`` (default stderr) is a terminal, else a
    :class:`LineProgress`; nothing at all when ``disable``."""
    stream = file if file is not None else sys.stderr
    if disable:
        return _Silent(iterable, total, desc, initial, stream)
    if _is_terminal(stream):
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, initial=initial, leave=leave, file=stream)
    return LineProgress(iterable, total, desc, initial, stream)


__all__ = ["progress", "LineProgress"]
