"""What the lossless codec's residual decoding kernel (:func:`._kernels.decode_residual_rows`) returns: a module
of its own, which the kernels (compiled in) and :mod:`.coding` (which reads them, numba or not) both import."""

OK, BAD_ESCAPES, BAD_LOW_BITS, BAD_DATA = 0, 1, 2, 3
