"""Which clips a benchmark runs on: discovery of motion files, the default corpus, the quick selection."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from mocapz.errors import MocapzError
from mocapz.io import MOTION_EXTENSIONS

#: Marker formats (everything else in :data:`MOTION_EXTENSIONS` is skeletal).
MARKER_EXTENSIONS = (".c3d", ".trc")


@dataclass(frozen=True)
class ClipFile:
    """One clip of the corpus.

    Attributes:
        path: the motion file (``.bvh``, ``.amc``, ``.c3d``, ``.trc``).
        clip_id: a name unique in the corpus: the path relative to the corpus root, without extension
            with its extension (``cmu/bvh/09_06.bvh``), or the file name when outside a common root.
    """

    path: Path
    clip_id: str

    @property
    def ext(self) -> str:
        return self.path.suffix.lower()

    @property
    def is_markers(self) -> bool:
        return self.ext in MARKER_EXTENSIONS


def default_data_dir() -> Path:
    """``$MOCAPZ_DATA``, else ``../shared/data`` from the working folder, else beside the checkout."""
    env = os.environ.get("MOCAPZ_DATA")
    if env:
        return Path(env)
    here = Path.cwd() / ".." / "shared" / "data"
    if here.is_dir():
        return here.resolve()
    return (Path(__file__).resolve().parents[3].parent / "shared" / "data").resolve()


def default_paths() -> list[Path]:
    """The default corpus: every CMU motion file under the shared data folder (``<data>/cmu``)."""
    root = default_data_dir() / "cmu"
    if not root.is_dir():
        raise MocapzError(f"default corpus not found: {root} (give files or folders, or set MOCAPZ_DATA)")
    return [root]


def discover(paths: list[Path]) -> list[ClipFile]:
    """Motion files named by ``paths`` (files, or folders searched recursively), sorted, de-duplicated.

    Raises MocapzError for a path that does not exist, a file of an unknown extension, or an empty result.
    """
    files: list[Path] = []
    for p in paths:
        p = Path(p)
        if not p.exists():
            raise MocapzError(f"{p}: no such file or folder")
        if p.is_dir():
            files += sorted(f for f in p.rglob("*") if f.is_file() and f.suffix.lower() in MOTION_EXTENSIONS)
        elif p.suffix.lower() in MOTION_EXTENSIONS:
            files.append(p)
        else:
            raise MocapzError(f"{p}: not a motion file (expected {', '.join(MOTION_EXTENSIONS)})")
    seen: set[Path] = set()
    unique = []
    for f in files:
        r = f.resolve()
        if r not in seen:
            seen.add(r)
            unique.append(r)
    if not unique:
        raise MocapzError("no motion files found in " + ", ".join(str(p) for p in paths))
    unique.sort()
    root = Path(os.path.commonpath([str(f.parent) for f in unique]))
    data = default_data_dir()
    if data in (root, *root.parents):
        root = data  # ids relative to the shared data folder: cmu/bvh/09_06
    out = []
    for f in unique:
        rel = f.relative_to(root) if root in f.parents else Path(f.name)
        out.append(ClipFile(f, rel.as_posix()))
    return out


def frame_count(path: Path) -> int:
    """Cheap frame count from a file header (BVH ``Frames:``, AMC frame records), else the file size
    as a proxy (used only to order clips by length)."""
    ext = path.suffix.lower()
    try:
        if ext == ".bvh":
            with path.open("r", encoding="utf-8", errors="replace") as fh:
                for line in fh:
                    if line.strip().lower().startswith("frames:"):
                        return int(line.split(":", 1)[1])
        if ext == ".amc":
            with path.open("r", encoding="utf-8", errors="replace") as fh:
                return sum(1 for line in fh if line.strip().isdigit())
    except (OSError, ValueError):
        pass
    return path.stat().st_size // 1000


def quick_selection(clips: list[ClipFile], explicit: bool) -> list[ClipFile]:
    """The clips of a ``--quick`` run.

    Files given explicitly are all kept. From the default corpus: the three shortest cgspeed BVH clips,
    the shortest ASF/AMC clip and the shortest marker clip (a handful of formats, short clips).
    """
    if explicit:
        return clips
    by_len = sorted(clips, key=lambda c: (frame_count(c.path), c.clip_id))
    bvh = [c for c in by_len if c.ext == ".bvh" and "iclone" not in c.clip_id][:3]
    amc = [c for c in by_len if c.ext == ".amc"][:1]
    markers = [c for c in by_len if c.is_markers][:1]
    chosen = {c.clip_id for c in bvh + amc + markers}
    return [c for c in clips if c.clip_id in chosen]
