"""Many clips at once: compressing a folder serially, on a local process pool or on a Dask cluster.

One job per module, each usable on its own (import from the module; this package re-exports nothing):

* :mod:`mocapz.parallel.discover`: the motion files of a folder and the ``.mcz`` path of each
  (:func:`~mocapz.parallel.discover.discover`, :func:`~mocapz.parallel.discover.plan`).
* :mod:`mocapz.parallel.clip`: one clip as a unit of work (job, worker functions, result record, the
  modules its workers preload).
* :mod:`mocapz.parallel.pool`: :class:`~mocapz.parallel.pool.Pool`, which runs a picklable function over a
  stream of items, bounded in memory, through one of the engines :mod:`mocapz.parallel.processes` (local
  process pool) and :mod:`mocapz.parallel.dask_engine` (``dask.distributed``), or in this process;
  :mod:`mocapz.parallel.worker` is what runs inside their workers and the :class:`~mocapz.parallel.worker.Outcome`
  each item yields.
* :mod:`mocapz.parallel.folder`: :func:`~mocapz.parallel.folder.compress_folder`, the whole batch, with
  :mod:`mocapz.parallel.progress` (rich progress bar) and :mod:`mocapz.parallel.report` (the results).
* :mod:`mocapz.parallel.load`: :func:`~mocapz.parallel.load.load_many`, clips read in parallel and sent
  back to this process (``compress-db``).

Determinism: each clip is coded on its own, by the same function, with BLAS limited to one thread in
every mode (serial included), so the output bytes do not depend on ``jobs`` or on the scheduler.
"""
