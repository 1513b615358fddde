"""Batch jobs on Dask: many heads rigged, stimulus sets, long renders in frame chunks (``pdeface batch``)."""
