"""Hydra launcher ``dask``: the jobs of a multirun as tasks on a Dask
cluster (``dampertwin sweep --scheduler ADDRESS``, or ``hydra/launcher=dask
hydra.launcher.scheduler=ADDRESS``). Each task runs the job exactly as the
local ``joblib`` launcher does (its ``execute_job``, in a worker process),
mapped through :class:`dampertwin.parallel.DaskMap`, so a variant gives the
same artifacts either way. Use process workers (``dask worker``, a SLURM
cluster): Hydra's job state is per process."""

from __future__ import annotations

import functools
import logging
from pathlib import Path
from typing import Any, Sequence

from hydra.plugins.launcher import Launcher

log = logging.getLogger(__name__)


def _job(item, **kw):
    """One job on a worker: ``item`` = (job index, overrides)."""
    from hydra_plugins.hydra_joblib_launcher._core import execute_job

    idx, overrides = item
    return execute_job(idx, overrides, **kw)


class DaskLauncher(Launcher):
    def __init__(self, scheduler: str | None = None, n_jobs: Any = None, **kwargs: Any) -> None:
        """``n_jobs`` (conf/sweep.yaml's, for the joblib launcher) is ignored: the cluster's workers set
        the parallelism."""
        from dampertwin.errors import UserError

        if not scheduler or not isinstance(scheduler, str):
            raise UserError("conf/hydra/launcher/dask.yaml: scheduler: expected a Dask scheduler address "
                            "(tcp://HOST:PORT; dampertwin sweep --scheduler ADDRESS)")
        if kwargs:
            raise UserError(f"conf/hydra/launcher/dask.yaml: unknown key(s) {sorted(kwargs)}; expected scheduler (n_jobs is ignored)")
        self.scheduler = scheduler
        self.config = self.task_function = self.hydra_context = None

    def setup(self, *, hydra_context, task_function, config) -> None:
        self.config, self.task_function, self.hydra_context = config, task_function, hydra_context

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int):
        from hydra.core.singleton import Singleton
        from hydra.core.utils import configure_log, filter_overrides, setup_globals

        from dampertwin.parallel import DaskMap

        setup_globals()
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        Path(str(self.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
        log.info("Dask launcher: %d jobs on %s", len(job_overrides), self.scheduler)
        for i, o in enumerate(job_overrides):
            log.info("\t#%d : %s", initial_job_idx + i, " ".join(filter_overrides(o)))
        job = functools.partial(_job, hydra_context=self.hydra_context, config=self.config,
                                task_function=self.task_function, singleton_state=Singleton.get_state())
        cluster = DaskMap(self.scheduler)
        try:
            return [r for r, _ in cluster(job, [(initial_job_idx + i, list(o)) for i, o in enumerate(job_overrides)])]
        finally:
            cluster.close()
