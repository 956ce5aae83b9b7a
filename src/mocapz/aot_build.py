"""Build :mod:`mocapz.aot`'s extension: every kernel of :data:`mocapz.aot.SIGNATURES` compiled ahead of time by
numba's ``numba.pycc`` (the kernels' own source, numba's compiler, for this machine's processor), with the
:func:`mocapz.aot.stamp` of the source and processor it was built from and for.

    python -m mocapz.aot_build            # writes src/mocapz/_kernels_aot.*.so beside the package (make does)
    python -m mocapz.aot_build --out DIR  # elsewhere (a directory on the import path as ``mocapz``'s)
    python -m mocapz.aot_build --if-stale # only where the extension mocapz would import is missing or stale

Without numba, or with a numba that no longer has ``numba.pycc``, it says so and exits 0: mocapz then uses the
just-in-time kernels or the NumPy paths.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
import warnings
from pathlib import Path

from mocapz import aot


def build(out: Path) -> Path | None:
    """Compile the extension into ``out``; its path, or None when numba's ahead-of-time compiler is missing."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numba.pycc's pending-deprecation notice
            from numba.pycc import CC
    except ImportError as exc:
        print(f"mocapz.aot_build: no ahead-of-time compiler ({exc}); the just-in-time kernels will be used",
              file=sys.stderr)
        return None
    name = aot.EXTENSION.rsplit(".", 1)[1]
    cc = CC(name)
    with tempfile.TemporaryDirectory() as tmp:
        cc.output_dir = tmp
        cc.verbose = False
        cc.target_cpu = "host"
        seen: dict[tuple[str, str], int] = {}
        for alias, kernel, sig in aot.SIGNATURES:
            i = seen[(alias, kernel)] = seen.get((alias, kernel), -1) + 1
            fn = getattr(importlib.import_module(aot.MODULES[alias]), kernel)
            cc.export(f"{alias}__{kernel}__{i}", sig)(fn.py_func)
        value = aot.stamp()

        def stamp() -> int:
            return value

        cc.export("stamp", "i8()")(stamp)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cc.compile()
        built = next(Path(tmp).glob(f"{name}*"))
        out.mkdir(parents=True, exist_ok=True)
        target = out / built.name
        part = target.with_name(target.name + ".part")
        part.write_bytes(built.read_bytes())
        part.chmod(0o755)
        part.replace(target)  # whole or not at all
    return target


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path(aot.__file__).resolve().parent,
                    help="directory of the extension (default: the mocapz package's)")
    ap.add_argument("--if-stale", action="store_true",
                    help="do nothing when the extension mocapz imports is current (its stamp is the source's)")
    args = ap.parse_args(argv)
    if args.if_stale and aot.extension() is not None:
        return 0
    path = build(args.out)
    if path is not None:
        print(f"mocapz.aot_build: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
