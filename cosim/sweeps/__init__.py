"""Parameter sweeps and Monte Carlo on Dask: spec, store, cluster, plots."""
