"""The results of a whole batch: :class:`BatchReport` (per-clip results in input order, totals, rates)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from mocapz.parallel.clip import ClipResult


@dataclass
class BatchReport:
    """Results of a batch, in input order, with totals.

    ``seconds`` is the wall time of the whole batch as a user sees it (listing, pool or cluster start,
    work, shutdown); ``startup_seconds`` the pool or cluster start alone; ``work_seconds`` the time from
    the pool being ready to the last result. Rates are per ``seconds``.
    """

    results: list[ClipResult]
    seconds: float
    startup_seconds: float
    mode: str
    workers: int
    description: str
    codec: str = "lossless"
    work_seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[ClipResult]:
        return [r for r in self.results if not r.ok]

    @property
    def frames(self) -> int:
        return sum(r.frames for r in self.results if r.ok)

    @property
    def raw_bytes(self) -> int:
        return sum(r.raw_bytes for r in self.results if r.ok)

    @property
    def input_bytes(self) -> int:
        return sum(r.input_bytes for r in self.results if r.ok)

    @property
    def compressed_bytes(self) -> int:
        return sum(r.bytes for r in self.results if r.ok)

    @property
    def cpu_seconds(self) -> float:
        """CPU time spent in the workers on the clips (all clips, failed ones included)."""
        return sum(r.cpu_seconds for r in self.results)

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def clips_per_second(self) -> float:
        return len(self.results) / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self, with_results: bool = True) -> dict[str, Any]:
        comp = self.compressed_bytes
        d: dict[str, Any] = {
            "codec": self.codec, "mode": self.mode, "workers": self.workers, "parallelism": self.description,
            "clips": len(self.results), "ok": len(self.results) - len(self.failed), "failed": len(self.failed),
            "frames": self.frames, "raw_bytes": self.raw_bytes, "input_bytes": self.input_bytes,
            "compressed_bytes": comp, "ratio": self.raw_bytes / comp if comp else None,
            "ratio_file": self.input_bytes / comp if comp else None,
            "seconds": self.seconds, "startup_seconds": self.startup_seconds, "work_seconds": self.work_seconds,
            "cpu_seconds": self.cpu_seconds,
            "frames_per_second": self.frames_per_second, "clips_per_second": self.clips_per_second,
            "failures": [{"name": r.name, "error": r.error, "error_type": r.error_type} for r in self.failed],
        }
        d.update(self.extra)
        if with_results:
            d["results"] = [asdict(r) for r in self.results]
        return d
