"""Many runs: `cdpr-campaign` (a local pool or a Dask cluster) and `cdpr-calibrate`.

Rooms it may import: runs, scenario.
"""
