"""The PGA codec's container entry point (:func:`encode`) and its rate control.

With a target (``max_distortion`` in percent, ``max_error`` as a length) the encoder searches the
settings for the smallest file whose *decoded* result meets the target on this clip: it starts from a
fine setting, checks it meets the target, then greedily takes the coarsening step (fewer geodesics, more
levels of detail dropped, coarser quantisation) that saves the most bytes while still meeting the target,
until no step does. Every candidate is checked by decoding it: with the decoder, or on a short clip with the
compiled IK (:func:`screens`: the decoder's values to rounding), the choice then checked with the decoder.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import nullcontext
from typing import Any

import numpy as np

from mocapz import aot
from mocapz.codecs.pga import ikjit
from mocapz.codecs.pga.decode import decode_channels, decode_rows, with_turns
from mocapz.codecs.pga.effectors import find_effectors
from mocapz.codecs.pga.encode import Prepared, encode_prepared, prepare
from mocapz.codecs.pga.model import k_for_variance
from mocapz.codecs.pga.options import DEFAULT_VARIANCE, fixed_settings
from mocapz.codecs.pga.params import PGASettings
from mocapz.codecs.target import ErrorMetric, Errors, Target
from mocapz.errors import OptionError, TargetError
from mocapz.model.kinematics import forward_positions
from mocapz.model.motion import Motion


def encode(motion: Motion, **options: Any) -> dict[str, bytes]:
    """Container entry point: encode with fixed settings, or search them when a target is given.

    ``options`` are checked (:data:`mocapz.codecs.pga.options.OPTIONS`); lengths are resolved here against
    the clip's unit.
    """
    fixed = fixed_settings(options)
    target = Target.from_options(options, motion.skeleton.unit_cm)
    names = options.get("effectors")
    effectors = list(find_effectors(motion.skeleton, names)) if names else None
    outl = options.get("outliers")
    p = prepare(motion, effectors, None if outl is None else list(outl))
    if effectors:
        fixed["effectors"] = [int(e) for e in effectors]
    dim = p.full_model.basis.shape[0] if p.full_model is not None else 1
    if "k" in fixed and fixed["k"] > dim:
        raise OptionError(f"geodesics must be between 1 and {dim} (the pose dimension), got {fixed['k']}")
    if not target.active:
        return with_turns(motion.skeleton, encode_prepared(p, default_settings(p, fixed, options)), motion.n_frames)
    return with_turns(motion.skeleton, search(p, fixed, target)[0], motion.n_frames)


def default_settings(p: Prepared, fixed: dict[str, Any], options: dict[str, Any] | None = None) -> PGASettings:
    """Sensible settings without a target: k explaining 99.5 % of the variance (at most 20)."""
    s = PGASettings()
    if p.full_model is not None:
        frac = float((options or {}).get("variance") or DEFAULT_VARIANCE)
        s = s.replace(k=min(k_for_variance(p.full_model, frac), 20, p.full_model.basis.shape[1]))
    return s.replace(**fixed)


def evaluate_settings(p: Prepared, s: PGASettings, rows: np.ndarray | None = None, screen: bool = False
                      ) -> tuple[dict[str, bytes], int, Errors]:
    """Encode, decode with the real decoder, and measure: (sections, bytes, errors).

    With ``rows`` (indices of kept frames) only those frames are decoded and measured: an estimate used
    while searching; the final choice is always checked on every frame. Each stream is coded and decoded once
    per clip and the settings it depends on (``p.memo``: the candidates of a search differ in a setting or two;
    the IK is solved for every candidate). ``screen``: decoded with the compiled IK whatever the clip's length
    (:func:`screens`): an estimate, the values of the real decoder to rounding, which the search's last check
    confirms with the real decoder.
    """
    memo = p.memo
    sections = encode_prepared(p, s, memo)
    size = sum(len(v) + 2 for v in sections.values())
    sk = p.motion.skeleton
    s_dec = PGASettings.from_bytes(sections["params"])
    with ikjit.any_length() if screen else nullcontext():
        if rows is None:
            ch = decode_channels(sk, s_dec, sections, p.motion.n_frames, memo=memo)
            a = _reference(p, None)
        else:
            ch = decode_rows(sk, s_dec, sections, len(p.kept), rows, memo)
            a = _reference(p, rows)
    return sections, size, ErrorMetric.between(a, forward_positions(sk, ch))


def screens(p: Prepared) -> bool:
    """Whether the search screens a clip's candidates with the compiled IK: a clip under
    :data:`.ikjit.LAZY_FRAMES` kept frames (its file's values are the NumPy IK's, which the compiled one gives to
    rounding, about 6 times faster there), where the kernels are compiled ahead of time (nothing to load; with
    numba alone, loading it would cost more than a short clip's search)."""
    return len(p.kept) < ikjit.LAZY_FRAMES and ikjit.enabled() and aot.kernels("ik") is not None


def _reference(p: Prepared, rows: np.ndarray | None) -> np.ndarray:
    """Original positions of all frames, or of the given kept frames (cached on the Prepared object)."""
    cache = p.ref_cache
    key = -1 if rows is None else int(rows.size)
    if key not in cache:
        ch = p.motion.channels if rows is None else p.motion.channels[p.kept[rows]]
        cache[key] = forward_positions(p.motion.skeleton, ch)
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


def _efficiency(saved: int, cur: Errors, new: Errors, target: Target) -> float:
    """Bytes saved per fraction of the remaining error budget a move uses. Moves using under a tenth of
    the budget rank by bytes saved alone, so cheap small steps do not crowd out big savings."""
    used = 0.0
    for (limit, a), (_, b) in zip(target.limits(cur), target.limits(new), strict=True):
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
    screen = screens(p)  # the candidates' errors estimated (the compiled IK); the choice checked by the decoder
    for k in sorted({k_fine, min(dim, 2 * k_fine), dim}):
        start = PGASettings(k=k, lod_root=0, lod_effectors=0, lod_coords=0, pos_step=max(scale, 1e-6) * 2e-5,
                            coord_step=1e-3, rot_step=2e-4, basis_bits=12, mean_step=5e-5,
                            iterations=PGASettings().iterations).replace(**fixed)
        best_sections, best_size, err = evaluate_settings(p, start, screen=screen)
        if target.met(err):
            met = True
            break
    if not met:
        raise TargetError(
            f"cannot meet the target on this clip: the finest setting tried gives distortion "
            f"{err.distortion_pct:.4g} %, max error {err.max_error:.4g} and ARMS {err.arms:.4g} file units"
        )
    best = start
    log = [f"start k={start.k} size={best_size} {_show(err)}"]
    n = len(p.kept)
    stride = max(1, n // 300) | 1  # odd, so the subset samples every level of the lifting pyramid
    rows = np.arange(0, n, stride) if stride > 1 else None
    margin = 0.97 if rows is not None else 1.0  # estimates on a frame subset keep a little headroom
    tight = target.scaled(margin)
    failed: set[str] = set()  # moves that broke the target are not tried again (errors grow monotonically)
    history = [best]
    cur = err if rows is None else evaluate_settings(p, best, rows)[2]
    stale: dict[str, float] = {}  # lazy greedy: last known efficiency of every move (an estimate)
    while True:
        moves = {name: make for name, make in _moves(best, fixed, 1) if name not in failed}
        order = sorted(moves, key=lambda nm: (-stale.get(nm, np.inf), nm))
        accepted = None
        for i, name in enumerate(order):
            cand = moves[name]()
            sec, size, got = evaluate_settings(p, cand, rows, screen)
            if not tight.met(got):
                failed.add(name)
                stale.pop(name, None)
                continue
            eff = _efficiency(best_size - size, cur, got, tight) if size < best_size else -1.0
            stale[name] = eff
            rest = [stale.get(nm, np.inf) for nm in order[i + 1 :]]
            if eff > 0 and eff >= max(rest, default=-np.inf):
                accepted = (size, name, cand, sec, got)
                break
        if accepted is None:
            # stale estimates may have hidden a good move: take the best fresh one, if any
            fresh = [(v, nm) for nm, v in stale.items() if nm in moves and v > 0]
            if not fresh:
                break
            name = max(fresh)[1]
            cand = moves[name]()
            sec, size, got = evaluate_settings(p, cand, rows, screen)
            if not (tight.met(got) and size < best_size):
                break
            accepted = (size, name, cand, sec, got)
        size, name, cand, sec, got = accepted
        best, best_size, best_sections = cand, size, sec
        cur = got
        history.append(best)
        log.append(f"{name}: size={size} {_show(got)}" + (" (frame subset)" if rows is not None else ""))
    if rows is not None or screen:
        # check on every frame with the decoder; step back along the path taken until the target holds
        for cand in reversed(history):
            sec, size, got = evaluate_settings(p, cand)
            if target.met(got):
                best, best_sections = cand, sec
                log.append(f"checked on all frames: size={size} {_show(got)}")
                break
            log.append(f"all frames: {_show(got)} misses the target, stepping back")
    # decoding speed: fewer IK iterations when the target still holds (same size, faster decode)
    if "iterations" not in fixed:
        e_ref = evaluate_settings(p, best)[2].max_error
        for it in range(best.iterations - 1, -1, -1):
            cand = best.replace(iterations=it)
            sec, size, got = evaluate_settings(p, cand)
            if not target.met(got) or got.max_error > 1.1 * e_ref:  # faster, but not at the price of local failures
                break
            best, best_sections = cand, sec
            log.append(f"iterations={it}: {_show(got)}")
    p.memo.clear()  # the streams kept for the candidates
    return best_sections, best, log


def _show(e: Errors) -> str:
    return f"d={e.distortion_pct:.4g} e={e.max_error:.4g} arms={e.arms:.4g}"
