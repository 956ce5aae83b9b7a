"""Options of the PGA codec: their declarations and the fixed settings they give.

Options not given are left to the encoder (with a target, rate control searches them); those given are
fixed. Lengths of the targets are resolved against the clip's unit in :class:`~mocapz.codecs.target.Target`.
"""

from __future__ import annotations

from typing import Any

from mocapz.codecs.options import Option
from mocapz.codecs.pga.params import MAX_ITERATIONS, MAX_LOD, PGASettings
from mocapz.codecs.target import TARGET_OPTIONS

DEFAULT = PGASettings()
DEFAULT_VARIANCE = 0.995
SEARCHED = "; searched with a target"

OPTIONS: tuple[Option, ...] = TARGET_OPTIONS + (
    Option("geodesics", "int", "number of principal geodesics k", low=1,
           default_text=f"explaining --variance of the pose variance, at most 20{SEARCHED}"),
    Option("variance", "float", "without --geodesics: share of the pose variance the geodesics explain", low=0.0,
           high=1.0, low_open=True, default_text=str(DEFAULT_VARIANCE)),
    Option("lod_root", "int", "levels of detail dropped from the root trajectory", low=0, high=MAX_LOD,
           default_text=f"{DEFAULT.lod_root}{SEARCHED}"),
    Option("lod_effectors", "int", "levels of detail dropped from the end-effector trajectories", low=0, high=MAX_LOD,
           default_text=f"{DEFAULT.lod_effectors}{SEARCHED}"),
    Option("lod_coords", "int", "levels of detail dropped from the coded geodesic coordinates", low=0, high=MAX_LOD,
           default_text=f"{DEFAULT.lod_coords}{SEARCHED}"),
    Option("effectors", "names", "end-effector joint or end-site names", default_text="the tree's extremities"),
    Option("bits", "int", "bits of the principal directions' loadings", low=2, high=24,
           default_text=f"{DEFAULT.basis_bits}{SEARCHED}"),
    Option("iterations", "int", "inverse-kinematics iterations when decoding", low=0, high=MAX_ITERATIONS,
           default_text=f"{DEFAULT.iterations}; fewer when the target still holds"),
    Option("paper", "bool", "decode from the end effectors alone, as in the paper (no coded coordinates)",
           default=False),
    Option("pos_step", "float", "quantisation step of root and effector positions (file units)", low=0.0,
           low_open=True, cli=False, default_text=f"{DEFAULT.pos_step}{SEARCHED}"),
    Option("coord_step", "float", "quantisation step of the geodesic coordinates (radians)", low=0.0,
           low_open=True, cli=False, default_text=f"{DEFAULT.coord_step}{SEARCHED}"),
    Option("rot_step", "float", "quantisation step of the root orientation details (radians)", low=0.0,
           low_open=True, cli=False, default_text=f"{DEFAULT.rot_step}{SEARCHED}"),
    Option("outliers", "indices", "frames coded apart, exactly", cli=False, default_text="isolated pose spikes"),
)

_SETTING = {"geodesics": "k", "lod_root": "lod_root", "lod_effectors": "lod_effectors", "lod_coords": "lod_coords",
            "bits": "basis_bits", "iterations": "iterations", "pos_step": "pos_step", "coord_step": "coord_step",
            "rot_step": "rot_step"}


def fixed_settings(options: dict[str, Any]) -> dict[str, Any]:
    """The :class:`PGASettings` fields the user fixed, from checked options."""
    fixed = {_SETTING[name]: options[name] for name in _SETTING if options.get(name) is not None}
    if options.get("paper"):
        # the paper's decoder: IK from end effectors alone, with its temporal regulariser
        fixed["use_coords"] = False
        fixed["lam_temporal"] = 1e-3
    return fixed
