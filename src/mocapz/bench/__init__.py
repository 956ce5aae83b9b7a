"""``mocapz bench``: every codec measured side by side on the same clips.

For each clip and codec a sweep of settings is encoded, decoded and scored with the figures of
``../shared/METRICS.md``; the results go to ``results.json`` (one record per clip x codec x setting),
``report.md`` (tables per clip and over the corpus, ratios at fixed error levels interpolated on each
codec's curve, published operating points) and PNG plots.

>>> from mocapz.bench import run, write_report
>>> doc = run(["../shared/data/cmu/bvh/09_06.bvh"], codecs=["quant"], quick=True, progress=False)
>>> paths = write_report(doc, "out/bench")  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mocapz.bench.curves import pareto, ratio_at
from mocapz.bench.measure import measure_codec, measure_generic
from mocapz.bench.runner import run_bench, write_results
from mocapz.bench.sweeps import DEFAULT_CODECS, GENERIC, settings_for

run = run_bench


def write_report(doc: dict[str, Any], out_dir: str | Path, plots: bool = True,
                 title: str = "mocapz benchmark") -> dict[str, Path]:
    """Write ``results.json``, ``report.md`` and (with ``plots``) the PNGs into ``out_dir``.

    Returns the paths written, by kind (``results``, ``report``, and one per plot).
    """
    from mocapz.bench.report import render

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {"results": out / "results.json", "report": out / "report.md"}
    write_results(doc, written["results"])
    images: dict[str, str] = {}
    if plots:
        from mocapz.bench.plots import write_plots

        images = write_plots(doc, out)
        written.update({t: out / f for t, f in images.items()})
    written["report"].write_text(render(doc, title, images), encoding="utf-8")
    return written


__all__ = ["DEFAULT_CODECS", "GENERIC", "measure_codec", "measure_generic", "pareto", "ratio_at", "run",
           "run_bench", "settings_for", "write_report", "write_results"]
