"""Experiments beyond one scenario file: parameter sweeps.

- `sweep_spec`: the sweep file (schema, loading, expansion into cases with stable ids);
- `sweep_worker`: one case in a worker process, returning a table row;
- `sweep_exec`: the backends, a local process pool or a Dask cluster;
- `sweep_store`: the Parquet parts and the consolidated results table (resume);
- `sweep_run`: a whole sweep, start to end (heat maps: `analysis.sweep_heatmaps`).
"""
