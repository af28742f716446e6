"""Band-optimisation sweeps: planning, tables, the fused kernel, the engine (chunks, resume, Dask), budget and
report.
"""
