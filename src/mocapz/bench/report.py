"""``report.md``: tables of a benchmark's results (per clip, over the corpus, published points, speed)."""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from typing import Any

from mocapz.bench.curves import corpus_ratio, metric_points, ratio_at
from mocapz.bench.published import PUBLISHED, Published, same_clip
from mocapz.bench.sweeps import GENERIC

#: Error levels of the fixed-error tables: (metric, level, column title).
LEVELS: tuple[tuple[str, float, str], ...] = (
    ("distortion_pct", 0.05, "d 0.05 %"),
    ("distortion_pct", 0.1, "d 0.1 %"),
    ("distortion_pct", 0.36, "d 0.36 %"),
    ("distortion_pct", 1.0, "d 1 %"),
    ("max_err_cm", 1.0, "max 1 cm"),
    ("max_err_cm", 3.0, "max 3 cm"),
)
LOSSY_OURS = ("pga", "patterns", "quant", "subsample", "pca", "segpca")


def fmt(v: float | None, digits: int = 3) -> str:
    """Number with ``digits`` significant digits ("—" for None)."""
    if v is None:
        return "—"
    if v == 0:
        return "0"
    if abs(v) >= 10 ** digits:
        return f"{v:,.0f}"
    return f"{v:.{digits}g}"


def _median(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], align: str | None = None) -> list[str]:
    align = align or "l" + "r" * (len(header) - 1)
    sep = ["---:" if a == "r" else "---" for a in align]
    out = ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def ok_records(doc: dict[str, Any]) -> list[dict[str, Any]]:
    return [r for r in doc["records"] if r.get("status") == "ok"]


def by_clip_codec(doc: dict[str, Any]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in ok_records(doc):
        out.setdefault((r["clip"], r["codec"]), []).append(r)
    return out


def clip_ratio(records: Sequence[dict[str, Any]], metric: str, level: float) -> float | None:
    """Ratio of one codec on one clip at an error level (interpolated on its curve)."""
    return ratio_at(metric_points(records, metric), level)


def corpus_at(doc: dict[str, Any], codec: str, metric: str, level: float,
              kinds: tuple[str, ...] = ("skeleton", "markers")) -> tuple[float | None, int, int]:
    """Corpus ratio of ``codec`` at an error level, clips reaching it, clips measured."""
    groups = by_clip_codec(doc)
    per_clip = []
    for c in doc["clips"]:
        recs = groups.get((c["clip"], codec))
        if not recs or c["kind"] not in kinds:
            continue
        per_clip.append((c["raw_bytes"], clip_ratio(recs, metric, level)))
    ratio, used = corpus_ratio(per_clip)
    return ratio, used, len(per_clip)


def _published_cell(p: Published, metric: str, level: float, prev_level: float) -> bool:
    """Whether a published point belongs in the column of ``level``: its error is at most ``level`` and
    above the previous column's level (compared at an equal or lower error, METRICS.md)."""
    if p.metric != metric or p.error is None:
        return False
    return prev_level < p.error[1] <= level


def _published_rows(clip_id: str | None) -> list[list[str]]:
    rows = []
    for p in PUBLISHED:
        if clip_id is not None and not same_clip(p, clip_id):
            continue
        cells, prev = [], {"distortion_pct": 0.0, "max_err_cm": 0.0}
        for metric, level, _ in LEVELS:
            hit = _published_cell(p, metric, level, prev[metric])
            prev[metric] = level
            cells.append(f"*{fmt(p.ratio[0])}* (d {p.error[1]:g} %)" if hit and p.error else "")
        if not any(cells):
            continue
        mark = "published, same clip" if clip_id is not None else f"published, on {p.clip}"
        rows.append([f"*{p.system}* ({mark})", *cells])
    return rows


def corpus_table(doc: dict[str, Any]) -> list[str]:
    header = ["codec", *[t for _, _, t in LEVELS], "clips"]
    rows = []
    for codec in doc["codecs"]:
        cells, counts = [], []
        for metric, level, _ in LEVELS:
            ratio, used, total = corpus_at(doc, codec, metric, level)
            counts.append(total)
            cells.append(fmt(ratio) + (f" ({used}/{total})" if ratio is not None and used < total else ""))
        if not any(counts):
            continue
        rows.append([codec, *cells, str(max(counts))])
    rows += [[*r, ""] for r in _published_rows(None)]
    return _table(header, rows)


def published_table(doc: dict[str, Any]) -> list[str]:
    codecs = [c for c in doc["codecs"] if c in LOSSY_OURS]
    header = ["published point", "their clip", "their ratio", "their error", *codecs]
    rows = []
    names = {c["clip"] for c in doc["clips"]}
    for p in PUBLISHED:
        ratio = fmt(p.ratio[0]) if p.ratio[0] == p.ratio[1] else f"{fmt(p.ratio[0])}-{fmt(p.ratio[1])}"
        if p.metric is None or p.error is None:
            err = "not given"
            cells = ["—"] * len(codecs)
        else:
            unit = "d {} %" if p.metric == "distortion_pct" else "ARMS {} cm"
            span = f"{p.error[0]:g}" if p.error[0] == p.error[1] else f"{p.error[0]:g}-{p.error[1]:g}"
            err = unit.format(span)
            level = p.error[0]  # at an equal or lower error than theirs
            kinds = ("markers",) if p.metric == "arms_cm" else ("skeleton", "markers")
            same = [n for n in names if same_clip(p, n)]
            cells = []
            for codec in codecs:
                if same:
                    recs = by_clip_codec(doc).get((same[0], codec), [])
                    r = clip_ratio(recs, p.metric, level)
                    cells.append(fmt(r) + " (same clip)" if r is not None else "—")
                else:
                    r, used, total = corpus_at(doc, codec, p.metric, level, kinds)
                    cells.append(fmt(r) + (f" ({used}/{total})" if r is not None and used < total else ""))
        rows.append([f"*{p.system}*", p.clip, ratio, err, *cells])
    return _table(header, rows, "llll" + "r" * len(codecs))


def speed_table(doc: dict[str, Any]) -> list[str]:
    header = ["codec", "encode ms/frame", "decode ms/frame", "encode × lossless", "decode × lossless",
              "settings x clips", "failures"]
    rows = []
    for codec in doc["codecs"]:
        recs = [r for r in doc["records"] if r["codec"] == codec]
        ok = [r for r in recs if r.get("status") == "ok"]
        if not recs:
            continue
        rows.append([codec, fmt(_median([r.get("encode_ms_per_frame") for r in ok])),
                     fmt(_median([r.get("decode_ms_per_frame") for r in ok])),
                     fmt(_median([r.get("encode_vs_lossless") for r in ok])),
                     fmt(_median([r.get("decode_vs_lossless") for r in ok])),
                     str(len(ok)), str(len(recs) - len(ok))])
    return _table(header, rows)


def settings_table(doc: dict[str, Any], codec: str) -> list[str]:
    recs = [r for r in ok_records(doc) if r["codec"] == codec]
    labels: list[str] = []
    for r in recs:
        if r["label"] not in labels:
            labels.append(r["label"])
    header = ["setting", "clips", "ratio", "ratio_file", "distortion % (median)", "max_err cm (median / max)",
              "arms cm", "p99 cm", "bone_len_err", "foot_skate cm/s", "skate 0.1 s cm/s", "jitter %",
              "enc ms/f", "dec ms/f"]
    rows = []
    for lab in labels:
        rs = [r for r in recs if r["label"] == lab]
        raw = sum(r["raw_bytes"] for r in rs)
        comp = sum(r["compressed_bytes"] for r in rs)
        src = [r for r in rs if r.get("ratio_file")]
        src_comp = sum(r["compressed_bytes"] for r in src)
        ratio_file = sum(r["ratio_file"] * r["compressed_bytes"] for r in src) / src_comp if src_comp else None
        mx = [r.get("max_err_cm") for r in rs if r.get("max_err_cm") is not None]
        rows.append([f"`{lab}`", str(len(rs)), fmt(raw / comp if comp else None), fmt(ratio_file),
                     fmt(_median([r.get("distortion_pct") for r in rs])),
                     f"{fmt(_median(mx))} / {fmt(max(mx) if mx else None)}",
                     fmt(_median([r.get("arms_cm") for r in rs])), fmt(_median([r.get("p99_err_cm") for r in rs])),
                     fmt(_median([r.get("bone_len_err") for r in rs])),
                     fmt(_median([r.get("foot_skate_cm_per_s") for r in rs])),
                     fmt(_median([r.get("foot_skate_window_cm_per_s") for r in rs])),
                     fmt(_median([r.get("jitter_pct") for r in rs])),
                     fmt(_median([r.get("encode_ms_per_frame") for r in rs])),
                     fmt(_median([r.get("decode_ms_per_frame") for r in rs]))])
    return _table(header, rows)


def clip_table(doc: dict[str, Any], clip_id: str) -> list[str]:
    groups = by_clip_codec(doc)
    header = ["codec", *[t for _, _, t in LEVELS], "enc ms/f", "dec ms/f", "dec × lossless"]
    rows = []
    for codec in doc["codecs"]:
        recs = groups.get((clip_id, codec))
        if not recs:
            continue
        cells = [fmt(clip_ratio(recs, m, lv)) for m, lv, _ in LEVELS]
        rows.append([codec, *cells, fmt(_median([r.get("encode_ms_per_frame") for r in recs])),
                     fmt(_median([r.get("decode_ms_per_frame") for r in recs])),
                     fmt(_median([r.get("decode_vs_lossless") for r in recs]))])
    rows += [[*r, "", "", ""] for r in _published_rows(clip_id)]
    return _table(header, rows)


def failures(doc: dict[str, Any]) -> list[str]:
    bad = [r for r in doc["records"] if r.get("status") != "ok"]
    if not bad:
        return ["None."]
    return _table(["clip", "codec", "setting", "error"],
                  [[r["clip"], r["codec"], f"`{r.get('label', '')}`", str(r.get("error", "")).replace("|", "/")]
                   for r in bad], "llll")


def describe_machine(m: dict[str, Any]) -> str:
    return (f"{m.get('cpu')}, {m.get('cores')} cores ({m.get('machine')}), {m.get('os')}, Python {m.get('python')},"
            f" numpy {m.get('numpy')}; one thread; load average {m.get('load_average_at_start')} at the start")


def render(doc: dict[str, Any], title: str = "mocapz benchmark", images: dict[str, str] | None = None,
           preamble: Sequence[str] = (), notes: Sequence[str] = ()) -> str:
    """The markdown report of a results document; ``images`` maps plot titles to relative PNG paths,
    ``preamble`` lines go under the title and ``notes`` lines (markdown) after the method paragraph."""
    clips = doc["clips"]
    frames = sum(c["frames"] for c in clips)
    lines = [f"# {title}", "", *preamble]
    lines += [
        f"- Command: `{doc['command']}`",
        f"- mocapz {doc['mocapz_version']}; run {doc['started']}, {doc.get('duration_s', 0):.0f} s"
        + (" (quick sweeps)" if doc.get("quick") else ""),
        f"- Machine: {describe_machine(doc['machine'])}",
        f"- Corpus: {len(clips)} clips, {frames} frames; codecs: {', '.join(doc['codecs'])}",
        "",
        "Figures as defined in `../shared/METRICS.md`: `ratio` = float32 size of the source's channels / "
        "compressed size (the whole `.mcz` file; for " + ", ".join(GENERIC) + ": the compressed source file, "
        "lossless); `d` = `distortion_pct`; `max` = `max_err` in cm. Ratios at a fixed error are interpolated "
        "on each codec's rate-distortion curve (Pareto front of its settings, log-log between the settings "
        "around the level, never extrapolated past its best setting); \"—\" means no setting reached that "
        "error. Over the corpus the ratio is size-weighted (sum of raw bytes / sum of compressed bytes) over "
        "the clips that reach the level, with (reached/measured) when some do not. Times are wall times of "
        "the codec call alone (no parsing or writing), one thread, fastest of 3 runs for calls under 50 ms, "
        "also given as a multiple of the lossless codec's time on the same clip in the same run. "
        "*Italic* rows are published figures, measured by their authors on other clips unless marked "
        "\"same clip\" (and compared at an equal or lower error, so each sits in the first column whose "
        "level is at or above its error).",
        "",
        *notes,
        "## Corpus: ratio at fixed error", "",
        *corpus_table(doc), "",
        "## Published operating points against this corpus", "",
        "Our codecs' ratio at the published point's error (the lower end of a range), on the same clip when "
        "the corpus has it, else over the corpus (ARMS points: over the marker clips).", "",
        *published_table(doc), "",
    ]
    if images:
        lines += ["## Plots", ""]
        lines += [f"![{t}]({p})" for t, p in images.items()]
        lines += [""]
    lines += ["## Speed", "", *speed_table(doc), ""]
    lines += ["## Settings (over the corpus)", "",
              "Per setting: ratio = sum of raw bytes / sum of compressed bytes over the clips; errors are "
              "medians over the clips (max_err also its maximum).", ""]
    for codec in doc["codecs"]:
        if any(r["codec"] == codec and r.get("status") == "ok" for r in doc["records"]):
            lines += [f"### {codec}", "", *settings_table(doc, codec), ""]
    lines += ["## Per clip", ""]
    for c in clips:
        shape = (f"{c['channels']} channels" if c["kind"] == "skeleton"
                 else f"{c['markers']} markers, {c.get('missing_pct', 0):.1f} % missing")
        lines += [f"### {c['clip']}", "",
                  f"{c['format']}, {c['frames']} frames at {c['frame_rate']:g} fps, {shape}, "
                  f"raw {c['raw_bytes']} bytes, file {c.get('file_bytes')} bytes", "",
                  *clip_table(doc, c["clip"]), ""]
    lines += ["## Failures", "", *failures(doc), ""]
    return "\n".join(lines)
