"""The progress display of a batch: a rich progress bar on stderr (clips, clips/s, frames/s, failures)."""

from __future__ import annotations

from typing import Any

from mocapz.parallel.clip import ClipResult


class BatchProgress:
    """A rich progress bar on stderr: clips done / total, clips/s, frames/s, failures, ETA.

    Disabled (a no-op) when ``enabled`` is false or stderr is not a terminal.
    """

    def __init__(self, total: int, description: str = "compressing", enabled: bool = True) -> None:
        self.total = total
        self.frames = 0
        self.failed = 0
        self._progress: Any = None
        self._task: Any = None
        if not enabled:
            return
        from rich.console import Console

        console = Console(stderr=True)
        if not console.is_terminal:
            return
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            ProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.text import Text

        class _Rates(ProgressColumn):
            """Clips per second and frames per second since the start."""

            def render(self, task: Any) -> Text:
                el = task.elapsed or 0.0
                if el <= 0:
                    return Text("- clips/s, - frames/s", style="progress.data.speed")
                frames = task.fields.get("frames", 0)
                return Text(f"{task.completed / el:,.1f} clips/s, {frames / el:,.0f} frames/s",
                            style="progress.data.speed")

        self._progress = Progress(TextColumn("[progress.description]{task.description}"), BarColumn(bar_width=24),
                                  MofNCompleteColumn(), _Rates(), TextColumn("{task.fields[failed_text]}", style="red"),
                                  TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=console,
                                  transient=False)
        self._task = self._progress.add_task(description, total=total, frames=0, failed_text="")

    def __enter__(self) -> BatchProgress:
        if self._progress is not None:
            self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def update(self, result: ClipResult) -> None:
        """Count one finished clip."""
        self.frames += result.frames
        self.failed += 0 if result.ok else 1
        if self._progress is not None:
            self._progress.update(self._task, advance=1, frames=self.frames,
                                  failed_text=f"{self.failed} failed" if self.failed else "")

