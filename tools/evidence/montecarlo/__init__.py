"""Robustness campaigns: Monte Carlo over dispersed scenarios, as tasks on Dask distributed.

``python -m tools.evidence.montecarlo --scenario paper --runs 1000`` (docs/montecarlo.md). Modules:
``dispersions`` (the TOML files and their sampling), ``apply`` (a case's values onto the
plant's scenario, the in-process closed loop), ``case`` (one case, the Dask task),
``campaign`` (the Dask driver), ``results`` (Parquet rows), ``summary``, ``plots``,
``rerun`` (one case again with full logs), ``hil`` (cases through the two processes).
"""
