"""Every readable C3D file of ../shared/data through the lossless codec: .mcz size against the source and
against ``xz -9e`` of the source, how many bytes hold the rest of the C3D (the ``c3d.*`` sections), whether
the written file is the source byte for byte (SHA-256), and the time of compress / decompress (API calls,
file reading and writing excluded).

Usage: python scripts/c3d_lossless.py [DATA_DIR] > docs/benchmarks/c3d.md
"""

from __future__ import annotations

import hashlib
import lzma
import sys
import tempfile
import time
from pathlib import Path

import mocapz
from mocapz.format.container import Container

FILES = [f"other/markers/btkdata/c3d_samples/{n}" for n in (
    "Eb015pi.c3d", "Eb015pr.c3d", "Eb015si.c3d", "Eb015sr.c3d", "Eb015vi.c3d", "Eb015vr.c3d", "Dance.c3d",
    "FP1.C3D", "PiG_Motion-FlatFoot-Full.c3d")] + ["other/markers/pyomeca/markers_analogs.c3d", "cmu/c3d/01_01.c3d"]


def main() -> None:
    data = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared" / "data"
    print("# C3D files through the lossless codec\n")
    print("`python scripts/c3d_lossless.py`: `.mcz` against the source and against `xz -9e` of the source "
          "(`lzma` preset 9e, the same as `xz -9e -k`); `rest` = bytes of the `c3d.*` sections (header, "
          "parameters, residuals, analogs, model outputs); identical = SHA-256 of the written file equals the "
          "source's; times are the API calls.\n")
    print("| file | storage | source | xz -9e | .mcz | of which rest | source / .mcz | .mcz / xz | identical "
          "| compress s | decompress s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rel in FILES:
            path = data / rel
            src = path.read_bytes()
            xz = len(lzma.compress(src, preset=9 | lzma.PRESET_EXTREME))
            m = mocapz.load(path)
            t0 = time.perf_counter()
            mcz = mocapz.compress(m, codec="lossless")
            t1 = time.perf_counter()
            back = mocapz.decompress(mcz)
            t2 = time.perf_counter()
            out = Path(tmp) / path.name
            mocapz.save(back, out)
            same = hashlib.sha256(out.read_bytes()).digest() == hashlib.sha256(src).digest()
            rest = sum(len(v) for k, v in Container.from_bytes(mcz).sections.items() if k.startswith("c3d."))
            extras = m.metadata["c3d"]
            cpu = {84: "Intel", 85: "DEC", 86: "SGI"}[extras.processor]
            storage = f"{cpu} {'float' if extras.is_float else 'int'}"
            print(f"| {path.name} | {storage} | {len(src)} | {xz} | {len(mcz)} | {rest} | {len(src) / len(mcz):.2f} "
                  f"| {len(mcz) / xz:.3f} | {'yes' if same else 'NO'} | {t1 - t0:.2f} | {t2 - t1:.2f} |")


if __name__ == "__main__":
    main()
