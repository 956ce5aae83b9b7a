"""Baseline codecs, real codecs in the ``.mcz`` container so that ``mocapz bench`` measures them exactly
like the others. Each module exports a :class:`~mocapz.codecs.CodecInfo` named ``INFO``; all four take
skeletal data (channel values, Euler angles unwrapped in time, decoded back into the skeleton's own
channels) and marker data (coordinates; gaps filled for the model, kept as NaN on output).

============  ==========================================================  ===============================
codec         method                                                      what is stored
============  ==========================================================  ===============================
subsample     every N-th frame, cubic spline in between (pattern paper)   key frames as float32
pca           one PCA for the clip, K components (pattern paper)          mean, basis, coefficients float32
segpca        PCA per segment, spline-interpolated key-frame              per segment: mean, basis, key
              coefficients (Liu & McMillan 2006; PGA paper Table 3)       coefficients float32
quant         per-track range reduction and uniform quantisation at a     integers, time differences range
              step chosen from an error threshold, every frame kept       coded (mocapz.format.entropy)
              (how ACL / game-engine codecs work)
============  ==========================================================  ===============================

Headers (counts, lengths, step codes) are varints. The general-purpose compressors (gzip, bzip2, xz,
zstd) are not codecs: the benchmark measures them on the source file (:mod:`mocapz.bench.measure`).
"""
