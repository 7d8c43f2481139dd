"""Fleet scale: the onboard sensor and the gap diagnosis over many trucks' CAN logs on Dask (docs/fleet.md).

``manifest`` (which log is which vehicle), ``summary`` (one row per log), ``store`` (the Parquet output folder),
``run`` (the Dask run), ``health`` (cooler and oil-level fits per vehicle and period, drift flags), ``report``
(Markdown with plots), ``synth`` (a synthetic fleet for tests and benchmarks).
"""
