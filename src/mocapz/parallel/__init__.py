"""Many clips at once: folder discovery, the process pool or Dask cluster, and progress."""
