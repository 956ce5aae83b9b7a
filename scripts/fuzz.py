"""A longer seeded run of the hostile-file fuzzer of ``tests/test_hostile.py`` (which CI runs with one seed):
every codec's sections, and the C3D extras' (exact, rounded to a precision, in blocks), damaged in every way of
``_damage`` with seeds 1..N (the seed-independent varint cases once), each decode under the test's limits
(address space, a 5 s alarm).

    .venv/bin/python scripts/fuzz.py 4      # seeds 1..4; prints the count and the outcomes
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import numpy as np  # noqa: E402
import test_hostile as hostile  # noqa: E402

from mocapz.format.container import Container  # noqa: E402


def main(seeds: int) -> int:
    t0 = time.perf_counter()
    outcomes: collections.Counter[str] = collections.Counter()
    bad: dict[str, str] = {}
    files = [(f"{codec}/{kind}", hostile._file(codec, kind)) for codec, kind in hostile.PAIRS]
    files += [(f"c3d extras {options or 'exact'}", hostile.c3d_file(options)) for options in hostile.EXTRAS_CASES]
    for name, data_in in files:
        box = Container.from_bytes(data_in)
        payloads = list(box.sections.values())
        for seed in range(1, seeds + 1):
            for k, (key, payload) in enumerate(box.sections.items()):
                rng = np.random.default_rng([seed, k])
                with hostile._limits():
                    for how, damaged in hostile._damage(payload, rng, payloads):
                        if how.startswith("varint") and seed > 1:
                            continue  # the same for every seed
                        data = Container(box.codec, box.codec_version, box.layout,
                                         dict(box.sections, **{key: damaged})).to_bytes()
                        verdict = hostile._verdict(data)
                        if verdict is None:
                            outcomes["FormatError or a consistent decode"] += 1
                        else:
                            outcomes["misbehaved"] += 1
                            bad[f"{name}/{key}/seed {seed}: {how}"] = verdict
    total = sum(outcomes.values())
    print(f"{total} damaged files over {len(hostile.PAIRS)} codec/data pairs and {len(hostile.EXTRAS_CASES)} C3D "
          f"extras files (exact, rounded, in blocks), seeds 1..{seeds}, "
          f"{time.perf_counter() - t0:.0f} s: {dict(outcomes)}")
    for name, verdict in list(bad.items())[:20]:
        print(f"  {name}: {verdict}")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 4))
