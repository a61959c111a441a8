"""Hydra launcher ``dask`` of dampertwin's sweeps (conf/hydra/launcher/dask.yaml)."""
