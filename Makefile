# mtanno — two commands: `make demo` runs the pipeline on default data, `make test` runs the tests.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
SHARED ?= ../shared/data
OUT    ?= out

.PHONY: install test demo bench lint clean experiment-hdm05 experiment-mocap6 experiment-bandai experiment-openworld experiment-review

$(BIN)/mtanno: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	@touch $@

install: $(BIN)/mtanno  ## create .venv and install mtanno with its test extras

test: $(BIN)/mtanno  ## run the whole test suite (real-data tests skip when ../shared is absent)
	$(BIN)/python -m pytest -q

demo: $(BIN)/mtanno  ## features → learn-mt → tune → compose → annotate → evaluate → report (HDM05, or synthetic data)
	scripts/demo.sh $(BIN)/mtanno $(BIN)/python $(SHARED) $(OUT)

experiment-hdm05: $(BIN)/mtanno  ## the HDM05 annotation experiment (scripts/experiment_hdm05.sh)
	scripts/experiment_hdm05.sh $(OUT)/hdm05

experiment-mocap6: $(BIN)/mtanno  ## the CMU mocap6 annotation experiment
	scripts/experiment_mocap6.sh $(OUT)/mocap6

experiment-openworld: $(BIN)/mtanno  ## the open-world protocol: foreign archives, background, confidence (issue 26)
	scripts/experiment_openworld.sh $(OUT)/openworld

experiment-bandai: $(BIN)/mtanno  ## the Bandai set-2 leave-one-style-out annotation experiment
	scripts/experiment_bandai.sh $(OUT)/bandai

experiment-review: $(BIN)/mtanno  ## the Bandai set-2 review loop: K = 0, 1, 2 reviewed clips per content (issue 24)
	scripts/experiment_review.sh $(OUT)/review

bench: $(BIN)/mtanno  ## speed figures (see docs/benchmarks.md); installs the peers first
	$(BIN)/pip install --quiet -e '.[test,bench]'
	$(BIN)/python scripts/bench_features.py
	$(BIN)/python scripts/bench_c3d_readers.py
	$(BIN)/python scripts/bench_learn.py
	$(BIN)/python scripts/bench_match.py
	$(BIN)/python scripts/bench_annotate.py
	$(BIN)/python scripts/bench_index.py
	$(BIN)/python scripts/bench_keyframes.py
	$(BIN)/python scripts/bench_align.py
	$(BIN)/python scripts/bench_tune.py

lint: $(BIN)/mtanno
	$(BIN)/ruff check mtanno tests scripts

clean:
	rm -rf $(OUT) .cache .pytest_cache
