"""Golden files: ``.mcz`` files made by earlier encoders decode for ever to the same values, and today's
encoders still write the same bytes (moves and refactors must not change a codec's output; a deliberate
format change bumps the codec version and adds new golden files beside the old ones)."""

from __future__ import annotations

import hashlib
import json

import pytest
from golden.make import CASES, HERE, encode, source, values_hash

import mocapz
from mocapz.codecs import codec_names

ENTRIES = json.loads((HERE / "golden.json").read_text())


def test_every_case_has_a_golden_file() -> None:
    assert [e["file"] for e in ENTRIES] == [f"{c[0]}.mcz" for c in CASES]
    assert {e["codec"] for e in ENTRIES} == set(codec_names())  # every registered codec is pinned


@pytest.mark.parametrize("entry", ENTRIES, ids=[e["file"] for e in ENTRIES])
def test_golden_decodes_to_the_same_values(entry: dict) -> None:
    data = (HERE / entry["file"]).read_bytes()
    assert hashlib.sha256(data).hexdigest() == entry["sha256"], "golden file changed on disk"
    assert values_hash(mocapz.decompress(data)) == entry["values_sha256"]


@pytest.mark.parametrize("entry", ENTRIES, ids=[e["file"] for e in ENTRIES])
def test_encoder_writes_the_golden_bytes(entry: dict) -> None:
    a, b = entry["frames"]
    data = encode(source(entry["source"], a, b), entry["codec"], entry["options"])
    assert hashlib.sha256(data).hexdigest() == entry["sha256"], f"{entry['file']}: the encoder's bytes moved"


OLDER = [(d, e) for d in ("format1", "format2", "format3", "format4", "format5", "format6",
                                  "format7")
         for e in json.loads((HERE / d / "golden.json").read_text())]


@pytest.mark.parametrize(("folder", "entry"), OLDER, ids=[f"{d}/{e['file']}" for d, e in OLDER])
def test_earlier_formats_still_decode(folder: str, entry: dict) -> None:
    """Files written before a format change decode to the same values: ``format1``, before the correction's
    shrink factor (``c.head`` format 1); ``format2``, before the entropy coder's quarter-octave scales coded as
    differences (coder 4: the lossy codecs' integer streams were coder 1 or 3); ``format3``, before the
    correction's streams of a clip under 1,024 frames could share their scales by joint or marker (coder 5) and
    its bases were searched from the cheapest (the files whose bytes that moved); ``format4``, before the
    correction's parts of such a clip could go into one range stream (``lifting.JOINT``, the files that moved);
    ``format5``, the streams before a continued block predicted its first details across its edge (``c.head``
    format 4, not 5); ``format6``, the files that moved when a file's default ``effort`` became fast (encoder
    only: a file of either effort decodes by the same decoder); ``format7``, the files that moved when the byte
    planes' zstd search became btopt (:data:`mocapz.format.planes.STRATEGY`; any zstd frame decodes alike)."""
    data = (HERE / folder / entry["file"]).read_bytes()
    assert hashlib.sha256(data).hexdigest() == entry["sha256"]
    assert values_hash(mocapz.decompress(data)) == entry["values_sha256"]
