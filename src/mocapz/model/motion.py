"""In-memory motion models: :class:`Motion` (skeletal) and :class:`MarkerMotion` (marker clouds).

Every reader produces one of these, every codec consumes and returns one, every writer takes one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from mocapz.model.skeleton import Skeleton


@dataclass
class Motion:
    """A skeleton animated by channel values.

    Attributes:
        skeleton: the joint hierarchy and channel layout.
        channels: ``(frames, channels)`` float64, values as in the file (file length unit; degrees or
            radians as ``skeleton.angle_unit`` says).
        frame_rate: frames per second.
        name: clip name (file stem by default).
        source_format: ``"bvh"`` or ``"asfamc"``: the format the data came from.
        decimals: ``(channels,)`` number of decimals each column was stored with in the source, or
            ``None`` if unknown (then lossless coding keeps the float64 values bit-exactly).
        metadata: free-form source information (path, file size...).
    """

    skeleton: Skeleton
    channels: np.ndarray
    frame_rate: float
    name: str = "motion"
    source_format: str = "bvh"
    decimals: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.channels = np.ascontiguousarray(self.channels, dtype=np.float64)
        if self.channels.ndim != 2 or self.channels.shape[1] != self.skeleton.n_channels:
            raise ValueError(
                f"channels must be (frames, {self.skeleton.n_channels}), got {self.channels.shape}"
            )
        if self.decimals is not None:
            self.decimals = np.asarray(self.decimals, dtype=np.int64)

    @property
    def n_frames(self) -> int:
        return int(self.channels.shape[0])

    @property
    def duration(self) -> float:
        """Clip length in seconds (frames / frame rate)."""
        return self.n_frames / self.frame_rate

    @property
    def raw_bytes(self) -> int:
        """METRICS.md ``raw_bytes``: float32 size of the channel data."""
        return int(self.channels.size * 4)

    def positions(self) -> np.ndarray:
        """Global positions of all joints and end sites, ``(frames, points, 3)``, file units."""
        from mocapz.model.kinematics import forward_positions

        return forward_positions(self.skeleton, self.channels)

    def with_channels(self, channels: np.ndarray, decimals: np.ndarray | None = None) -> Motion:
        """Same clip and skeleton with other channel values (e.g. decoded ones)."""
        return replace(self, channels=np.asarray(channels, dtype=np.float64), decimals=decimals)

    def slice(self, start: int, stop: int | None = None) -> Motion:
        return replace(self, channels=self.channels[start:stop].copy())

    # ------------------------------------------------- what Motion and MarkerMotion share
    @property
    def kind(self) -> str:
        """``"skeleton"``."""
        return "skeleton"

    @property
    def unit_cm(self) -> float | None:
        """Centimetres per file length unit (the skeleton's), or ``None`` if unknown."""
        return self.skeleton.unit_cm

    @property
    def values(self) -> np.ndarray:
        """The sample values: ``(frames, channels)``."""
        return self.channels

    def with_values(self, values: np.ndarray) -> Motion:
        """Same clip with other values (decimals unknown)."""
        return self.with_channels(values)


@dataclass
class MarkerMotion:
    """Labelled 3D marker trajectories (C3D, TRC).

    Attributes:
        labels: marker names.
        positions: ``(frames, markers, 3)`` float64 in ``units``; NaN marks a missing sample (gap).
        frame_rate: samples per second.
        units: length unit string as in the file (``"mm"``, ``"m"``, ``"cm"``).
        name: clip name.
        source_format: ``"c3d"`` or ``"trc"``.
        decimals: decimals the values were stored with, if known (TRC text), else ``None``.
        metadata: format-specific extras needed to write the file back (first frame number; for C3D,
            ``metadata["c3d"]``, a :class:`~mocapz.model.c3d_extras.C3DExtras`: parameters, analogs,
            residuals, model outputs...).
        quantum: the storage step of the positions when they are exact multiples of it (integer C3D:
            ``|POINT:SCALE|``, units per step), else ``None``.
    """

    labels: list[str]
    positions: np.ndarray
    frame_rate: float
    units: str = "mm"
    name: str = "markers"
    source_format: str = "c3d"
    decimals: int | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    quantum: float | None = None

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64)
        if self.positions.ndim != 3 or self.positions.shape[2] != 3:
            raise ValueError(f"positions must be (frames, markers, 3), got {self.positions.shape}")
        if self.positions.shape[1] != len(self.labels):
            raise ValueError("one label per marker is required")

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_markers(self) -> int:
        return int(self.positions.shape[1])

    @property
    def duration(self) -> float:
        return self.n_frames / self.frame_rate

    @property
    def raw_bytes(self) -> int:
        """METRICS.md ``raw_bytes``: ``frames * markers * 3 * 4``."""
        return int(self.positions.size * 4)

    @property
    def unit_cm(self) -> float | None:
        return UNIT_CM.get(self.units.strip().lower())

    @property
    def missing(self) -> np.ndarray:
        """``(frames, markers)`` True where a sample is missing."""
        return ~np.isfinite(self.positions).all(axis=2)

    def with_positions(self, positions: np.ndarray) -> MarkerMotion:
        """Same clip with other positions (decimals and quantum unknown)."""
        return replace(self, positions=np.asarray(positions, dtype=np.float64), decimals=None, quantum=None)

    @property
    def kind(self) -> str:
        """``"markers"``."""
        return "markers"

    @property
    def values(self) -> np.ndarray:
        """The sample values: ``(frames, markers, 3)``, NaN where missing."""
        return self.positions

    def with_values(self, values: np.ndarray) -> MarkerMotion:
        """Same clip with other values (decimals unknown)."""
        return self.with_positions(values)

    def slice(self, start: int, stop: int | None = None) -> MarkerMotion:
        """Frames ``start:stop`` (the C3D extras in ``metadata["c3d"]`` sliced alike)."""
        meta = self.metadata
        extras = meta.get("c3d")
        if extras is not None and hasattr(extras, "slice") and extras.frames == self.n_frames:
            meta = {**meta, "c3d": extras.slice(start, stop)}
        return replace(self, positions=self.positions[start:stop].copy(), metadata=meta)


@dataclass
class BlockOf:
    """What an encoder may know about the clip a block comes from (``metadata["block_of"]`` of a block,
    set by :mod:`mocapz.blocking`): the block is frames ``[start, stop)`` of ``clip``. Encoders use it to
    decide as they would on the whole clip (foot contacts, energy budgets) and memoise what they compute on
    the whole clip in ``cache``."""

    clip: Any
    start: int
    stop: int
    cache: dict[str, Any] = field(default_factory=dict)


UNIT_CM = {"mm": 0.1, "cm": 1.0, "m": 100.0, "dm": 10.0, "in": 2.54, "inch": 2.54}

AnyMotion = Motion | MarkerMotion
