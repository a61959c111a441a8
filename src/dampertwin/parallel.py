"""Scale-out of batch work on a Dask cluster (optional dependency
``dask[distributed]``, ``pip install -e '.[dask]'``): the GA and concurrent-GA
evaluators and the discrepancy matrix map the same functions they run
locally over chunks of their inputs."""

from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np


class DaskMap:
    """``DaskMap(address)(fn, items)``: ``fn`` mapped over ``chunks`` chunks of
    the rows of ``items`` (an array) or over each element (a list) on the
    scheduler at ``address``; the client connects on first use. Returns
    [(result, chunk)] in input order."""

    def __init__(self, scheduler: str, chunks: int = 4):
        self.scheduler = scheduler
        self.chunks = chunks
        self._client = None

    @property
    def client(self):
        if self._client is None:
            try:
                from dask.distributed import Client
            except ImportError as e:
                raise RuntimeError("a Dask scheduler is configured but dask.distributed is not installed "
                                   "(pip install -e '.[dask]')") from e
            self._client = Client(self.scheduler)
        return self._client

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    def __call__(self, fn: Callable[[Any], Any], items: np.ndarray | Sequence) -> list[tuple[Any, Any]]:
        if isinstance(items, np.ndarray):
            parts = np.array_split(items, min(self.chunks, len(items)))
        else:
            parts = list(items)
        futures = self.client.map(fn, parts, pure=False)
        return list(zip(self.client.gather(futures), parts))
