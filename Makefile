# mocapz: `make demo` runs a real compress/decompress/evaluate round trip; `make test` runs the tests.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
DATA ?= ../shared/data
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast lint bench clean kernels

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

# the compiled kernels ahead of time (mocapz.aot; about 30 s), rebuilt where the kernels' source changed
kernels: $(STAMP)
	MOCAPZ_NO_AOT=0 $(BIN)/python -m mocapz.aot_build --if-stale

demo: kernels
	@mkdir -p out
	$(BIN)/mocapz compress $(DATA)/cmu/bvh/09_06.bvh -o out/09_06.lossless.mcz --codec lossless -f
	$(BIN)/mocapz decompress out/09_06.lossless.mcz -o out/09_06.lossless.bvh -f
	$(BIN)/mocapz eval $(DATA)/cmu/bvh/09_06.bvh out/09_06.lossless.mcz
	$(BIN)/mocapz compress $(DATA)/cmu/bvh/09_06.bvh -o out/09_06.pga.mcz --codec pga --max-distortion 0.36 -f
	$(BIN)/mocapz decompress out/09_06.pga.mcz -o out/09_06.pga.bvh -f
	$(BIN)/mocapz eval $(DATA)/cmu/bvh/09_06.bvh out/09_06.pga.mcz

test: kernels
	$(BIN)/ruff check src tests scripts
	$(BIN)/python -m pytest -n 2

# everything but the tests marked slow (rate-control searches, browser, Dask, CLI conventions): under a minute
test-fast: kernels
	$(BIN)/ruff check src tests scripts
	$(BIN)/python -m pytest -n 2 -m "not slow"

bench: kernels
	$(BIN)/python scripts/lossless.py
	$(BIN)/python scripts/pga.py --out docs/benchmarks/pga.md
	$(BIN)/python scripts/patterns.py
	$(BIN)/python scripts/run_all.py
	$(BIN)/python scripts/quality.py --jobs 2
	$(BIN)/python scripts/speed.py
	$(BIN)/python scripts/memory.py

clean:
	rm -rf $(VENV) out .pytest_cache
