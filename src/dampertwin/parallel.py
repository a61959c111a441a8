"""Scale-out of batch work on a Dask cluster (optional dependency
``dask[distributed]``, ``pip install -e '.[dask]'``): the GA and concurrent-GA
evaluators, the approach-2 sensitivity runs, the discrepancy workflow's
records, the sweep's variants (the ``dask`` Hydra launcher) and the
discrepancy matrix map the same functions they run locally over chunks of
their inputs, on the scheduler a profile's ``scheduler:`` or a
``--scheduler`` option names. A cluster of SLURM jobs (dask-jobqueue) is
described by conf/cluster/slurm.yaml (:func:`check_cluster_config`,
:func:`slurm_cluster`; ``dampertwin cluster``)."""

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
            try:
                self._client = Client(self.scheduler)
            except (OSError, ValueError, TypeError) as e:  # nothing answers, or not an address
                from .errors import UserError

                raise UserError(f"scheduler {self.scheduler!r}: no Dask scheduler reached ({e}); expected the "
                                "address of a running one, tcp://HOST:PORT (--scheduler or the profile's "
                                "scheduler:)") from None
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

    def executor(self) -> "ClusterExecutor":
        """The same client as a ``concurrent.futures`` executor (``submit``, ``shutdown``): for work that
        submits tasks one by one and takes them as they finish (the discrepancy workflow's records)."""
        return ClusterExecutor(self)


def release(evaluator) -> None:
    """Close the cluster client of an evaluator (``Evaluator``, ``BatchScorer``) that has one, once its fit
    is over: no client is left connected to a cluster that stops."""
    m = getattr(evaluator, "_map", None)
    if m is not None:
        m.close()


class ClusterExecutor:
    """A :class:`DaskMap`'s client as an executor: ``submit(fn, *args)`` -> a
    ``concurrent.futures.Future``; ``shutdown(wait, cancel_futures)`` like a
    process pool's, then the client is closed."""

    def __init__(self, dask_map: DaskMap):
        self._map = dask_map
        self._ex = dask_map.client.get_executor(pure=False)

    def submit(self, fn: Callable, *args, **kwargs):
        return self._ex.submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        self._ex.shutdown(wait=wait and not cancel_futures)
        self._map.close()


# ------------------------------------------------------------ a Dask cluster of SLURM jobs
CLUSTER_KEYS = {  # key: (types, required, meaning)
    "cores": ((int,), True, "cores per SLURM job (an integer >= 1)"),
    "memory": ((str,), True, "memory per SLURM job, e.g. 4GB"),
    "walltime": ((str,), True, "wall-time limit of a job, HH:MM:SS"),
    "queue": ((str, type(None)), False, "SLURM partition (null: the cluster's default)"),
    "account": ((str, type(None)), False, "SLURM account (null: none)"),
    "processes": ((int,), False, "Dask worker processes per job (an integer >= 1, default 1)"),
    "jobs": ((int,), True, "SLURM jobs to start (an integer >= 1; workers = jobs x processes)"),
    "job_extra_directives": ((list,), False, "extra #SBATCH options, one line each starting with '-', "
                                             "e.g. ['--exclusive']"),
}


def check_cluster_config(doc, where: str) -> dict:
    """A SLURM cluster description (e.g. conf/cluster/slurm.yaml, read by the
    caller) checked: known keys, types and ranges; a UserError naming
    ``where`` and each bad key otherwise. Returns the mapping."""
    import re

    from .errors import UserError

    if not isinstance(doc, dict):
        raise UserError(f"{where}: expected a mapping with the keys {', '.join(CLUSTER_KEYS)}")
    errors = [f"{where}: unknown key {k!r}; expected one of {', '.join(CLUSTER_KEYS)}" for k in doc
              if k not in CLUSTER_KEYS]
    for k, (types, required, meaning) in CLUSTER_KEYS.items():
        if k not in doc:
            if required:
                errors.append(f"{where}: missing key {k!r}: {meaning}")
            continue
        v = doc[k]
        bad = isinstance(v, bool) or not isinstance(v, types)
        bad = bad or (int in types and isinstance(v, int) and v < 1)
        bad = bad or (k == "memory" and not re.fullmatch(r"\d+(\.\d+)?\s*[KMGT]i?B", str(v)))
        bad = bad or (k == "walltime" and not re.fullmatch(r"(\d+-)?\d{1,3}:\d{2}:\d{2}", str(v)))
        bad = bad or (k == "job_extra_directives" and not all(isinstance(x, str) and x.startswith("-") for x in v))
        # one line each: a line break would put a line of its own into the job script
        bad = bad or any(isinstance(x, str) and any(c in x for c in "\r\n") for x in (v if isinstance(v, list) else [v]))
        if bad:
            errors.append(f"{where}: {k}: {v!r}; expected {meaning}")
    if errors:
        raise UserError(errors)
    return doc


def slurm_cluster(cfg: dict, where: str):
    """A ``dask_jobqueue.SLURMCluster`` from a checked cluster description
    (not yet scaled: ``cluster.scale(jobs=cfg['jobs'])`` submits the jobs).
    A clear error when dask-jobqueue is not installed."""
    from .errors import UserError

    cfg = check_cluster_config(cfg, where)
    try:
        from dask_jobqueue import SLURMCluster
    except ImportError:
        raise UserError(f"{where}: a SLURM cluster needs dask-jobqueue, which is not installed "
                        "(pip install -e '.[slurm]')") from None
    return SLURMCluster(cores=cfg["cores"], memory=cfg["memory"], walltime=cfg["walltime"], queue=cfg.get("queue"),
                        account=cfg.get("account"), processes=cfg.get("processes", 1),
                        job_extra_directives=list(cfg.get("job_extra_directives", [])))
