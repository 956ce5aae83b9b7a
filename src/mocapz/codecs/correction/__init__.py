"""The correction layer: a residual on top of any lossy model so that every target holds on every file.

:mod:`.lifting` codes a residual within a tolerance per sample (closed-loop interpolating lifting, smooth
in time, mostly zeros); :mod:`.bounds` turns position bounds into value tolerances (the skeleton's chain
of rotation errors times lever arms); :mod:`.fit` codes one model's residual and verifies it by forward
kinematics; :mod:`.wrap` wraps a codec's encoder and decoder (:func:`~.wrap.corrected`).
"""
