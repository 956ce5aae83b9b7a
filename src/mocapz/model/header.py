"""What a decoder is told about a clip: everything but its values.

A :class:`ClipHeader` is built from a motion (:meth:`ClipHeader.of`, on the encoder side) or from the
container's layout header (:func:`mocapz.format.layout.decode_layout`, on the decoder side); codecs see
only this typed object, never the container's JSON. :meth:`ClipHeader.motion` turns decoded values back
into a :class:`~mocapz.model.motion.Motion` or :class:`~mocapz.model.motion.MarkerMotion`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from mocapz.model.motion import AnyMotion, MarkerMotion, Motion
from mocapz.model.skeleton import Skeleton

#: metadata keys carried through compression (a writer may need them to write the file back)
KEPT_METADATA = ("frame_time", "file_bytes", "first_frame", "trc_header", "amc_header", "amc_first_frame",
                 "trc_path_fields", "trc_newline", "trc_blank_line", "trc_trailing_tab", "trc_time_decimals")


@dataclass
class ClipHeader:
    """A clip's layout without its values.

    Attributes:
        kind: ``"skeleton"`` (a :class:`Skeleton` and channel values) or ``"markers"``.
        frames: number of frames.
        frame_rate: frames per second.
        name: clip name.
        source_format: ``"bvh"``, ``"asfamc"``, ``"c3d"`` or ``"trc"``.
        skeleton: the skeleton (skeletal clips), else ``None``.
        labels: marker labels (marker clips), else empty.
        units: marker length unit as in the file (``"mm"``...), marker clips only.
        decimals: skeletal clips: ``(channels,)`` decimals of each column in the source, or ``None``;
            marker clips: the decimals of the values (TRC text), or ``None``.
        metadata: the source metadata a writer needs (:data:`KEPT_METADATA`).
        quantum: marker clips: the source's storage step (integer C3D: ``|POINT:SCALE|``), else ``None``;
            a motion made by :meth:`motion` keeps it only if its values are multiples of it.
        before: a block of a stream that continues the block before it: that block's decoded values of its
            last frames, ``(frames, columns)`` (:func:`mocapz.blocking.last_frames`; the values of
            :attr:`value_shape`'s last axes, flattened), or of its last frame, ``(columns,)``; else ``None``.
        batch_frames: a block decoded as part of a longer read (:func:`mocapz.blocking.iter_spans`): the frames
            of every block that read decodes, the work ahead a decoder may prepare for; else ``None``.
    """

    kind: Literal["skeleton", "markers"]
    frames: int
    frame_rate: float
    name: str
    source_format: str
    skeleton: Skeleton | None = None
    labels: list[str] = field(default_factory=list)
    units: str = "mm"
    decimals: Any = None
    metadata: dict[str, Any] = field(default_factory=dict)
    quantum: float | None = None
    before: np.ndarray | None = field(default=None, compare=False, repr=False)
    batch_frames: int | None = field(default=None, compare=False, repr=False)

    @classmethod
    def of(cls, motion: AnyMotion) -> ClipHeader:
        """The header a decoder of ``motion``'s container would see."""
        meta = {k: motion.metadata[k] for k in KEPT_METADATA if k in motion.metadata}
        if isinstance(motion, Motion):
            dec = None if motion.decimals is None else np.asarray(motion.decimals, dtype=np.int64)
            return cls("skeleton", motion.n_frames, motion.frame_rate, motion.name, motion.source_format,
                       skeleton=motion.skeleton, decimals=dec, metadata=meta)
        return cls("markers", motion.n_frames, motion.frame_rate, motion.name, motion.source_format,
                   labels=list(motion.labels), units=motion.units, decimals=motion.decimals, metadata=meta,
                   quantum=motion.quantum)

    # ------------------------------------------------------------------ columns
    @property
    def n_columns(self) -> int:
        """Values per frame: channels (skeleton) or ``3 * markers``."""
        return self.skeleton.n_channels if self.skeleton is not None else 3 * len(self.labels)

    @property
    def value_shape(self) -> tuple[int, ...]:
        """Shape of the clip's values: ``(frames, channels)`` or ``(frames, markers, 3)``."""
        if self.skeleton is not None:
            return (self.frames, self.skeleton.n_channels)
        return (self.frames, len(self.labels), 3)

    @property
    def rotation_mask(self) -> np.ndarray:
        """``(columns,)`` True for rotation channels (never for markers)."""
        if self.skeleton is not None:
            return self.skeleton.rotation_columns()
        return np.zeros(self.n_columns, dtype=bool)

    @property
    def period(self) -> float:
        """A full turn in the rotation channels' unit (360 or 2 pi); 0 for markers."""
        if self.skeleton is None:
            return 0.0
        return 360.0 if self.skeleton.angle_unit == "deg" else 2 * math.pi

    @property
    def unit_cm(self) -> float | None:
        """Centimetres per file length unit, if known."""
        if self.skeleton is not None:
            return self.skeleton.unit_cm
        from mocapz.model.motion import UNIT_CM

        return UNIT_CM.get(self.units.strip().lower())

    # ------------------------------------------------------------------- motion
    def motion(self, values: np.ndarray) -> AnyMotion:
        """A motion with this layout and the given values (:attr:`value_shape`)."""
        if self.kind == "skeleton":
            assert self.skeleton is not None
            return Motion(skeleton=self.skeleton, channels=values, frame_rate=float(self.frame_rate),
                          name=self.name, source_format=self.source_format,
                          decimals=None if self.decimals is None else np.array(self.decimals, dtype=np.int64),
                          metadata=dict(self.metadata))
        q = self.quantum
        if q is not None:  # decoded values keep the quantum only if they still are its multiples
            v = np.asarray(values, dtype=np.float64)
            v = v[np.isfinite(v)]
            q = q if np.array_equal(np.round(v / q) * q, v) else None
        return MarkerMotion(labels=list(self.labels), positions=values, frame_rate=float(self.frame_rate),
                            units=self.units, name=self.name, source_format=self.source_format,
                            decimals=self.decimals, metadata=dict(self.metadata), quantum=q)
