"""Build :mod:`mocapz.aot`'s extension: every kernel of :data:`mocapz.aot.SIGNATURES` compiled ahead of time by
numba's ``numba.pycc`` (the kernels' own source, numba's compiler, for this machine's processor), with the
:func:`mocapz.aot.stamp` of the source and processor it was built from and for.

    python -m mocapz.aot_build            # writes src/mocapz/_kernels_aot.*.so beside the package (make does)
    python -m mocapz.aot_build --out DIR  # elsewhere (a directory on the import path as ``mocapz``'s)
    python -m mocapz.aot_build --if-stale # only where the extension mocapz would import is missing or stale

Without numba, with a numba that no longer has ``numba.pycc`` or without a C compiler, it says so on stderr and
exits 0: mocapz then uses the just-in-time kernels or the NumPy paths (tests/test_aot.py fails where numba has
``numba.pycc`` and the extension is missing).
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
    """Compile the extension into ``out``; its path, or None (said on stderr) when it cannot be compiled."""
    name = aot.EXTENSION.rsplit(".", 1)[1]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # numba.pycc's pending-deprecation notice
                _compile(name, Path(tmp))
        except Exception as exc:  # no numba.pycc, no C compiler or linker: the just-in-time kernels then
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            print(f"mocapz.aot_build: the kernels could not be compiled ahead of time ({type(exc).__name__}: "
                  f"{first}); mocapz will use numba's just-in-time kernels", file=sys.stderr)
            return None
        built = next(Path(tmp).glob(f"{name}*"))
        out.mkdir(parents=True, exist_ok=True)
        target = out / built.name
        part = target.with_name(target.name + ".part")
        part.write_bytes(built.read_bytes())
        part.chmod(0o755)
        part.replace(target)  # whole or not at all
    return target


def _compile(name: str, tmp: Path) -> None:
    from numba.pycc import CC

    cc = CC(name)
    cc.output_dir = str(tmp)
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
    cc.compile()


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
