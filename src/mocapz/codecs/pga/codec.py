"""The PGA codec's encoder and decoder for single files (the model and the correction layer), and its version."""

from __future__ import annotations

from typing import Any

from mocapz.codecs.correction.wrap import corrected, native_targets, strip_targets
from mocapz.codecs.pga.decode import decode
from mocapz.codecs.pga.options import OPTIONS
from mocapz.codecs.pga.ratecontrol import encode
from mocapz.codecs.target import Target
from mocapz.model.motion import Motion

VERSION = 4  # 2: the correction layer (codecs/correction); 3: the fast IK solver (iksolve), values ~1e-8 rad apart;
# 4: 2 IK iterations by default (was 6), steps taken only when they lower the cost beyond rounding, Euler
# angles by the closed form (codecs/pga/channels.euler_angles), the compiled IK (numba) when installed; the
# correction's lifting integers in one stream per part

SEARCH_FRAMES = 300  # longer clips: the model at its own settings (its search takes minutes), then the correction


def _base_options(motion: Motion, options: dict[str, Any], target: Target) -> dict[str, Any]:
    """PGA's own rate control for a distortion / ARMS target on short clips, its default settings else."""
    if motion.n_frames <= SEARCH_FRAMES:
        return native_targets(motion, options, target)
    return strip_targets(motion, options, target)


ENCODE, DECODE = corrected(encode, decode, "pga", OPTIONS, _base_options, zero_base=False)
