"""The figures of ``../shared/METRICS.md`` (:func:`evaluate`, :func:`size_figures`) and error plots."""

from mocapz.metrics.figures import ErrorReport, evaluate, size_figures

__all__ = ["ErrorReport", "evaluate", "size_figures"]
