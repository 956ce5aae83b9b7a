"""Settings of the PGA codec and their compact binary form (stored in the ``params`` section)."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, fields

import numpy as np

from mocapz.errors import FormatError, OptionError
from mocapz.format.entropy import read_uvarint, write_uvarint

MAX_ITERATIONS = 1000  # the most the iterations option allows
MAX_LOD = 16  # the most levels of detail the lod options drop


@dataclass
class PGASettings:
    """Everything the decoder needs besides the data, and the encoder's knobs.

    Lengths in file units, angles in radians.

    Attributes:
        k: number of principal geodesics.
        lod_root: finest levels of detail dropped from the root position and orientation.
        lod_effectors: levels dropped from the end-effector trajectories.
        lod_coords: levels dropped from the coded geodesic coordinates (the IK's prior / warm start).
        use_coords: code the geodesic coordinates too (beyond the paper: the IK then starts from them).
        eff_mode: 0 = end-effector trajectories coded globally (the paper); 1 = coded in the root frame as
            the residual against the effector positions the coded coordinates already give (needs
            ``use_coords``; much smaller, but root errors then move the feet too); 2 = no end effectors at
            all: the pose is the coded coordinates (needs ``use_coords``; rate control picks it when the
            bytes buy more as geodesics and finer coordinates than as IK targets).
        pos_step: quantisation step of root and effector positions.
        rot_step: quantisation step of the root orientation details.
        coord_step: quantisation step of the geodesic coordinates (radians).
        basis_bits: the directions' loadings (direction x standard deviation, radians) are stored on a
            grid of step 2**-basis_bits.
        mean_step: quantisation step of the mean pose's rotation vectors.
        lam_temporal: weight of the temporal regulariser.
        lam_prior: weight of the coded coordinates in the IK.
        iterations: Levenberg-Marquardt iterations.
        effectors: FK point indices given by the user (empty: found from the tree).
        outliers: frame indices coded apart (e.g. an added T-pose).
    """

    k: int = 12
    lod_root: int = 2
    lod_effectors: int = 2
    lod_coords: int = 2
    use_coords: bool = True
    eff_mode: int = 0
    pos_step: float = 0.01
    rot_step: float = 1e-3
    coord_step: float = 5e-3
    basis_bits: int = 12
    mean_step: float = 2e-4
    lam_temporal: float = 0.0
    lam_prior: float = 1e-2
    iterations: int = 2  # from the coded warm start, 2 Levenberg-Marquardt steps reach the targets' rounding
    effectors: list[int] = field(default_factory=list)
    outliers: list[int] = field(default_factory=list)

    def validate(self, dim: int, frames: int) -> None:
        if not 1 <= self.k <= max(dim, 1):
            raise OptionError(f"geodesics must be between 1 and {dim} (the pose dimension), got {self.k}")
        for name in ("lod_root", "lod_effectors", "lod_coords"):
            v = getattr(self, name)
            if v < 0:
                raise OptionError(f"{name.replace('_', '-')} must be >= 0, got {v}")
        for name in ("pos_step", "rot_step", "coord_step", "mean_step"):
            if not getattr(self, name) > 0:
                raise OptionError(f"{name} must be positive")
        if self.eff_mode not in (0, 1, 2) or (self.eff_mode > 0 and not self.use_coords):
            raise OptionError("effector modes 1 and 2 need coded coordinates")
        if not 2 <= self.basis_bits <= 24:
            raise OptionError(f"basis bits must be 2..24, got {self.basis_bits}")

    def check_decoded(self, dim: int, points: int) -> None:
        """FormatError unless these settings, read from a file, are ones an encoder writes for a skeleton of
        pose dimension ``dim`` with ``points`` FK points: they bound what the decoder allocates (``k``,
        ``basis_bits``, levels of detail) and how long it runs (``iterations``)."""
        try:
            self.validate(dim, 0)
        except OptionError as exc:
            raise FormatError(None, f"corrupted PGA parameters ({exc.message})") from None
        floats = [getattr(self, name) for name in self._FLOATS]
        if not all(np.isfinite(floats)) or self.lam_temporal < 0 or self.lam_prior < 0:
            raise FormatError(None, "corrupted PGA parameters (steps and weights must be finite)")
        if self.iterations > MAX_ITERATIONS or max(self.lod_root, self.lod_effectors, self.lod_coords) > MAX_LOD:
            raise FormatError(None, "corrupted PGA parameters (iterations or levels of detail)")
        if any(not 0 <= e < points for e in self.effectors):
            raise FormatError(None, "corrupted PGA parameters (effector on an unknown joint)")

    # --------------------------------------------------------------- bytes
    _INTS = ("k", "lod_root", "lod_effectors", "lod_coords", "use_coords", "eff_mode", "basis_bits", "iterations")
    _FLOATS = ("pos_step", "rot_step", "coord_step", "mean_step", "lam_temporal", "lam_prior")

    def to_bytes(self) -> bytes:
        out = bytearray()
        for name in self._INTS:
            out += write_uvarint(int(getattr(self, name)))
        out += struct.pack(f"<{len(self._FLOATS)}f", *(getattr(self, n) for n in self._FLOATS))
        for lst in (self.effectors, self.outliers):
            out += write_uvarint(len(lst))
            for v in lst:
                out += write_uvarint(int(v))
        return bytes(out)

    @classmethod
    def from_bytes(cls, data: bytes) -> PGASettings:
        try:
            pos = 0
            vals: dict[str, object] = {}
            for name in cls._INTS:
                vals[name], pos = read_uvarint(data, pos)
            nf = len(cls._FLOATS)
            floats = struct.unpack_from(f"<{nf}f", data, pos)
            pos += 4 * nf
            vals.update({n: float(v) for n, v in zip(cls._FLOATS, floats, strict=True)})
            lists = []
            for _ in range(2):
                n, pos = read_uvarint(data, pos)
                lst = []
                for _ in range(n):
                    v, pos = read_uvarint(data, pos)
                    lst.append(v)
                lists.append(lst)
        except (struct.error, IndexError):
            raise FormatError(None, "corrupted PGA parameters") from None
        vals["use_coords"] = bool(vals["use_coords"])
        s = cls(**vals, effectors=lists[0], outliers=lists[1])  # type: ignore[arg-type]
        return s

    def roundtrip(self) -> PGASettings:
        """The settings as the decoder will see them (float32 steps)."""
        return PGASettings.from_bytes(self.to_bytes())

    def replace(self, **changes: object) -> PGASettings:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d.update(changes)
        return PGASettings(**d)  # type: ignore[arg-type]


def as_float32(v: float) -> float:
    return float(np.float32(v))
