"""Option parsing and rate control for the PGA codec.

With a target (``max_distortion`` in percent, ``max_error`` as a length) the encoder searches the
settings for the smallest file whose *decoded* result meets the target on this clip: it starts from a
fine setting, checks it meets the target, then greedily takes the coarsening step (fewer geodesics, more
levels of detail dropped, coarser quantisation) that saves the most bytes while still meeting the target,
until no step does. Every candidate is checked by decoding it with the real decoder.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mocapz.codecs.pga.decode import decode_channels, decode_rows
from mocapz.codecs.pga.encode import Prepared, encode_prepared, prepare
from mocapz.codecs.pga.model import k_for_variance
from mocapz.codecs.pga.params import PGASettings
from mocapz.errors import OptionError, TargetError
from mocapz.metrics.figures import distortion_pct
from mocapz.model.kinematics import forward_kinematics
from mocapz.model.motion import Motion
from mocapz.model.units import parse_length

_KNOWN = {"geodesics", "lod_root", "lod_effectors", "lod_coords", "effectors", "max_distortion", "max_error",
          "bits", "pos_step", "coord_step", "rot_step", "paper", "iterations", "variance", "outliers"}


@dataclass
class Target:
    max_distortion: float | None = None
    max_error: float | None = None  # file units

    def met(self, d: float, e: float) -> bool:
        return (self.max_distortion is None or d <= self.max_distortion) and (
            self.max_error is None or e <= self.max_error)

    @property
    def active(self) -> bool:
        return self.max_distortion is not None or self.max_error is not None


def _int_option(options: dict[str, Any], name: str, lo: int = 0) -> int | None:
    if options.get(name) is None:
        return None
    try:
        v = int(options[name])
    except (TypeError, ValueError):
        raise OptionError(f"{name.replace('_', '-')} must be an integer, got {options[name]!r}") from None
    if v < lo:
        raise OptionError(f"{name.replace('_', '-')} must be >= {lo}, got {v}")
    return v


def parse_options(motion: Motion, options: dict[str, Any]) -> tuple[dict[str, Any], Target, list[str] | None]:
    """Validate user options; return fixed settings, the target, and effector names."""
    unknown = set(options) - _KNOWN
    if unknown:
        raise OptionError(f"unknown PGA option(s): {', '.join(sorted(unknown))} (known: {', '.join(sorted(_KNOWN))})")
    fixed: dict[str, Any] = {}
    k = _int_option(options, "geodesics", 1)
    if k is not None:
        fixed["k"] = k
    for name in ("lod_root", "lod_effectors", "lod_coords"):
        v = _int_option(options, name, 0)
        if v is not None:
            fixed[name] = v
    bits = _int_option(options, "bits", 2)
    if bits is not None:
        fixed["basis_bits"] = bits
    it = _int_option(options, "iterations", 1)
    if it is not None:
        fixed["iterations"] = it
    for name in ("pos_step", "coord_step", "rot_step"):
        if options.get(name) is not None:
            v = float(options[name])
            if not v > 0:
                raise OptionError(f"{name} must be positive")
            fixed[name] = v
    if options.get("paper"):
        # the paper's decoder: IK from end effectors alone, with its temporal regulariser
        fixed["use_coords"] = False
        fixed["lam_temporal"] = 1e-3
    target = Target()
    if options.get("max_distortion") is not None:
        v = float(options["max_distortion"])
        if not v > 0:
            raise OptionError("max-distortion must be a positive percentage")
        target.max_distortion = v
    if options.get("max_error") is not None:
        target.max_error = parse_length(options["max_error"], motion.skeleton.unit_cm, "max-error")
        if not target.max_error > 0:
            raise OptionError("max-error must be positive")
    eff = options.get("effectors")
    names = [n.strip() for n in eff.split(",") if n.strip()] if isinstance(eff, str) else eff
    return fixed, target, names


def encode_with_options(motion: Motion, **options: Any) -> dict[str, bytes]:
    """Encode with fixed settings, or search them when a target is given."""
    fixed, target, names = parse_options(motion, options)
    from mocapz.codecs.pga.effectors import find_effectors

    effectors = list(find_effectors(motion.skeleton, names)) if names else None
    outl = options.get("outliers")
    p = prepare(motion, effectors, None if outl is None else list(outl))
    if effectors:
        fixed["effectors"] = [int(e) for e in effectors]
    dim = p.full_model.basis.shape[0] if p.full_model is not None else 1
    if "k" in fixed and fixed["k"] > dim:
        raise OptionError(f"geodesics must be between 1 and {dim} (the pose dimension), got {fixed['k']}")
    if not target.active:
        return encode_prepared(p, default_settings(p, fixed, options))
    return search(p, fixed, target)[0]


def default_settings(p: Prepared, fixed: dict[str, Any], options: dict[str, Any] | None = None) -> PGASettings:
    """Sensible settings without a target: k explaining 99.5 % of the variance (at most 20)."""
    s = PGASettings()
    if p.full_model is not None:
        frac = float((options or {}).get("variance", 0.995))
        s = s.replace(k=min(k_for_variance(p.full_model, frac), 20, p.full_model.basis.shape[1]))
    return s.replace(**fixed)


def evaluate_settings(p: Prepared, s: PGASettings, rows: np.ndarray | None = None
                      ) -> tuple[dict[str, bytes], int, float, float]:
    """Encode, decode with the real decoder, and measure: (sections, bytes, distortion_pct, max_err).

    With ``rows`` (indices of kept frames) only those frames are decoded and measured: an estimate used
    while searching; the final choice is always checked on every frame.
    """
    sections = encode_prepared(p, s)
    size = sum(len(v) + 2 for v in sections.values())
    sk = p.motion.skeleton
    s_dec = PGASettings.from_bytes(sections["params"])
    if rows is None:
        ch = decode_channels(sk, s_dec, sections, p.motion.n_frames)
        a = _reference(p, None)
    else:
        ch = decode_rows(sk, s_dec, sections, len(p.kept), rows)
        a = _reference(p, rows)
    b = forward_kinematics(sk, ch)[0]
    d = distortion_pct(a, b)
    e = float(np.linalg.norm(a - b, axis=-1).max()) if a.size else 0.0
    return sections, size, d, e


def _reference(p: Prepared, rows: np.ndarray | None) -> np.ndarray:
    """Original positions of all frames, or of the given kept frames (cached on the Prepared object)."""
    cache = p.ref_cache
    key = -1 if rows is None else int(rows.size)
    if key not in cache:
        ch = p.motion.channels if rows is None else p.motion.channels[p.kept[rows]]
        cache[key] = forward_kinematics(p.motion.skeleton, ch)[0]
    return cache[key]


def _moves(s: PGASettings, fixed: dict[str, Any], k_min: int) -> list[tuple[str, Callable[[], PGASettings]]]:
    moves: list[tuple[str, Callable[[], PGASettings]]] = []

    def add(name: str, **ch: Any) -> None:
        if not any(c in fixed for c in ch):
            moves.append((name, lambda ch=ch: s.replace(**ch)))

    if s.k > k_min:
        add("k-1", k=s.k - 1)
        if s.k - 3 >= k_min:
            add("k-3", k=s.k - 3)
        if s.k >= 24:
            add("k*0.75", k=int(s.k * 0.75))
    if s.use_coords and s.eff_mode == 0:
        add("eff_mode=1", eff_mode=1)
    if s.use_coords and s.eff_mode != 2:
        add("eff_mode=2", eff_mode=2)
    for lod in ("lod_root", "lod_effectors", "lod_coords"):
        if getattr(s, lod) < 6:
            add(f"{lod}+1", **{lod: getattr(s, lod) + 1})
    if s.basis_bits > 4:
        add("bits-1", basis_bits=s.basis_bits - 1)
    for step, top in (("pos_step", None), ("coord_step", 0.2), ("rot_step", 0.05), ("mean_step", 0.01)):
        v = getattr(s, step)
        for f in (4.0, 1.6):
            if top is None or v * f <= top:
                add(f"{step}*{f}", **{step: v * f})
    return moves


def _efficiency(saved: int, cur: tuple[float, float], new: tuple[float, float], target: Target) -> float:
    """Bytes saved per fraction of the remaining error budget a move uses. Moves using under a tenth of
    the budget rank by bytes saved alone, so cheap small steps do not crowd out big savings."""
    used = 0.0
    for limit, a, b in ((target.max_distortion, cur[0], new[0]), (target.max_error, cur[1], new[1])):
        if limit is not None:
            used = max(used, (b - a) / max(limit - a, 1e-12))
    return saved / max(used, 0.1)


def search(p: Prepared, fixed: dict[str, Any], target: Target) -> tuple[dict[str, bytes], PGASettings, list[str]]:
    """Greedy rate control; returns the sections, the chosen settings and a log of the steps taken."""
    if p.full_model is None:
        return encode_prepared(p, PGASettings().replace(**fixed)), PGASettings(), []
    dim = p.full_model.basis.shape[1]
    scale = float(np.ptp(p.eff_global.reshape(-1, 3), axis=0).max()) if p.eff_global.size else 1.0
    k_fine = min(dim, max(k_for_variance(p.full_model, 0.9995), 8))
    met = False
    for k in sorted({k_fine, min(dim, 2 * k_fine), dim}):
        start = PGASettings(k=k, lod_root=0, lod_effectors=0, lod_coords=0, pos_step=max(scale, 1e-6) * 2e-5,
                            coord_step=1e-3, rot_step=2e-4, basis_bits=12, mean_step=5e-5,
                            iterations=6).replace(**fixed)
        best_sections, best_size, d, e = evaluate_settings(p, start)
        if target.met(d, e):
            met = True
            break
    if not met:
        raise TargetError(
            f"cannot meet the target on this clip: the finest setting tried gives distortion {d:.4g} % "
            f"and max error {e:.4g} units"
        )
    best = start
    log = [f"start k={start.k} size={best_size} d={d:.4g} e={e:.4g}"]
    n = len(p.kept)
    stride = max(1, n // 300) | 1  # odd, so the subset samples every level of the lifting pyramid
    rows = np.arange(0, n, stride) if stride > 1 else None
    margin = 0.97 if rows is not None else 1.0  # estimates on a frame subset keep a little headroom
    tight = Target(None if target.max_distortion is None else target.max_distortion * margin,
                   None if target.max_error is None else target.max_error * margin)
    failed: set[str] = set()  # moves that broke the target are not tried again (errors grow monotonically)
    history = [best]
    cur = (d, e) if rows is None else evaluate_settings(p, best, rows)[2:]
    stale: dict[str, float] = {}  # lazy greedy: last known efficiency of every move (an estimate)
    while True:
        moves = {name: make for name, make in _moves(best, fixed, 1) if name not in failed}
        order = sorted(moves, key=lambda nm: (-stale.get(nm, np.inf), nm))
        accepted = None
        for i, name in enumerate(order):
            cand = moves[name]()
            sec, size, dd, ee = evaluate_settings(p, cand, rows)
            if not tight.met(dd, ee):
                failed.add(name)
                stale.pop(name, None)
                continue
            eff = _efficiency(best_size - size, cur, (dd, ee), tight) if size < best_size else -1.0
            stale[name] = eff
            rest = [stale.get(nm, np.inf) for nm in order[i + 1 :]]
            if eff > 0 and eff >= max(rest, default=-np.inf):
                accepted = (size, name, cand, sec, dd, ee)
                break
        if accepted is None:
            # stale estimates may have hidden a good move: take the best fresh one, if any
            fresh = [(v, nm) for nm, v in stale.items() if nm in moves and v > 0]
            if not fresh:
                break
            name = max(fresh)[1]
            cand = moves[name]()
            sec, size, dd, ee = evaluate_settings(p, cand, rows)
            if not (tight.met(dd, ee) and size < best_size):
                break
            accepted = (size, name, cand, sec, dd, ee)
        size, name, cand, sec, dd, ee = accepted
        best, best_size, best_sections = cand, size, sec
        cur = (dd, ee)
        history.append(best)
        log.append(f"{name}: size={size} d={dd:.4g} e={ee:.4g}" + (" (frame subset)" if rows is not None else ""))
    if rows is not None:
        # check on every frame; step back along the path taken until the target holds
        for cand in reversed(history):
            sec, size, dd, ee = evaluate_settings(p, cand)
            if target.met(dd, ee):
                best, best_sections = cand, sec
                log.append(f"checked on all frames: size={size} d={dd:.4g} e={ee:.4g}")
                break
            log.append(f"all frames: d={dd:.4g} e={ee:.4g} misses the target, stepping back")
    # decoding speed: fewer IK iterations when the target still holds (same size, faster decode)
    if "iterations" not in fixed:
        e_ref = evaluate_settings(p, best)[3]
        for it in (3, 1, 0):
            cand = best.replace(iterations=it)
            sec, size, dd, ee = evaluate_settings(p, cand)
            if not target.met(dd, ee) or ee > 1.1 * e_ref:  # faster, but not at the price of local failures
                break
            best, best_sections = cand, sec
            log.append(f"iterations={it}: d={dd:.4g} e={ee:.4g}")
    return best_sections, best, log
