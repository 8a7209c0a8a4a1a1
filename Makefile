# Every target creates .venv if it is missing and installs into it; the install is skipped while
# pyproject.toml is unchanged (the stamp file), so repeated runs start at once.
VENV   := .venv
PYTHON := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.installed-bench
OUT    ?= outputs
RUN    ?= $(OUT)/train/$(shell date +%Y-%m-%d/%H-%M-%S)
SOURCES := waterair hydra_plugins tests scripts train.py evaluate.py
# pytest-xdist workers, one torch thread each (docs/benchmarks.md, "Tests")
WORKERS ?= 2

.PHONY: install train evaluate test test-fast test-portable docs figures bench slurm-check cuda-check clean

install: $(STAMP)

# pip writes no bytecode (it would compile file after file on one core); compileall compiles every package as pip
# would have (files it cannot compile, a few packages' templates, are skipped as pip skips them), so that imports
# need not compile anything, also where PYTHONDONTWRITEBYTECODE is set. torch's and sympy's files, the most, are
# compiled on one core while pip installs the rest on the other (pip touches neither again); then the rest, on all.
$(STAMP): pyproject.toml
	test -x $(PYTHON) || python3 -m venv $(VENV)
	$(PYTHON) -m pip install --quiet --disable-pip-version-check --no-compile torch==2.13.0
	@site=$$($(PYTHON) -c 'import sysconfig; print(sysconfig.get_path("purelib"))'); \
	$(PYTHON) -m compileall -qq $$site/torch $$site/sympy > /dev/null 2>&1 & compiling=$$!; \
	echo "$(PYTHON) -m pip install --quiet --disable-pip-version-check --no-compile -e '.[dev,gym]'"; \
	$(PYTHON) -m pip install --quiet --disable-pip-version-check --no-compile -e '.[dev,gym]'; status=$$?; \
	wait $$compiling; test $$status -eq 0 && echo "$(PYTHON) -m compileall -qq -j 0 $$site" && \
	{ $(PYTHON) -m compileall -qq -j 0 $$site || true; }
	touch $(STAMP)

# Train into RUN, then evaluate that policy against its base, the classical controllers and the bound on what a first
# run needs (+study=first_run: S1 and S5's 10 % points) into RUN/evaluation; make evaluate ARGS=run=RUN: all of S1-S5.
train: $(STAMP)
	$(PYTHON) train.py hydra.run.dir=$(RUN) $(ARGS)
	$(PYTHON) evaluate.py run=$(RUN) hydra.run.dir=$(RUN)/evaluation +study=first_run

# Evaluate the shipped policies (or ARGS="run=outputs/train/DATE/TIME").
evaluate: $(STAMP)
	$(PYTHON) evaluate.py $(ARGS)

# Lint, format check, type check (physics and core), then every test on WORKERS workers, the 15 slowest
# listed so that growth shows; the last line says how long it all took. CI runs this. Workers take tests
# from each other's queues (worksteal): handed out in fixed shares, one worker was left with the slow tests
# while the other idled (docs/benchmarks.md, "Tests").
test: $(STAMP)
	@start=$$(date +%s); \
	$(VENV)/bin/ruff check $(SOURCES) && \
	$(VENV)/bin/ruff format --check $(SOURCES) && \
	$(VENV)/bin/mypy && \
	$(PYTHON) -m pytest -q -n $(WORKERS) --dist worksteal --durations=15; \
	status=$$?; elapsed=$$(( $$(date +%s) - start )); \
	echo "make test took $$((elapsed / 60)) min $$((elapsed % 60)) s (exit $$status)"; \
	exit $$status

# The quick tier while editing: lint, format check, type check and the tests not marked slow.
test-fast: $(STAMP)
	@start=$$(date +%s); \
	$(VENV)/bin/ruff check $(SOURCES) && \
	$(VENV)/bin/ruff format --check $(SOURCES) && \
	$(VENV)/bin/mypy && \
	$(PYTHON) -m pytest -q -n $(WORKERS) --dist worksteal -m "not slow"; \
	status=$$?; elapsed=$$(( $$(date +%s) - start )); \
	echo "make test-fast took $$((elapsed / 60)) min $$((elapsed % 60)) s (exit $$status)"; \
	exit $$status

# The tests marked capability (docs/benchmarks.md, "Tests") under each instruction set this CPU has, as torch and
# inductor pick them on an older machine (ATEN_CPU_CAPABILITY=default|avx2|avx512): what an AVX2 user's make test
# sees, seen on an AVX-512 machine. Not part of make test.
test-portable: $(STAMP)
	@top=$$($(PYTHON) -c 'import torch; print(torch.backends.cpu.get_cpu_capability().lower())'); \
	case $$top in avx512) caps="default avx2 avx512";; avx2) caps="default avx2";; *) caps="default";; esac; \
	status=0; for cap in $$caps; do echo "ATEN_CPU_CAPABILITY=$$cap"; \
	ATEN_CPU_CAPABILITY=$$cap $(PYTHON) -m pytest -q -n $(WORKERS) --dist worksteal -m capability || status=1; \
	done; exit $$status

figures: $(STAMP)
	$(PYTHON) -m waterair.evaluation.figures --out $(OUT)/figures

# What restates the env's defaults, generated from the dataclasses that hold them: conf/env/default.yaml, the seas'
# and channels' options, docs/reference/env.md (a test fails while any is stale).
docs: $(STAMP)
	$(PYTHON) -m waterair.cli.reference

# Stable-Baselines3, the training and quality suites' reference (the `bench` extra), once after each install.
$(BENCH_STAMP): $(STAMP)
	$(PYTHON) -m pip install --quiet --disable-pip-version-check --no-compile -e '.[bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	$(PYTHON) -m waterair.bench physics --compile --out $(OUT)/bench/physics.json
	$(PYTHON) -m waterair.bench env --compile --out $(OUT)/bench/env.json
	$(PYTHON) -m waterair.bench channel --compile --out $(OUT)/bench/channel.json
	$(PYTHON) -m waterair.bench training --out $(OUT)/bench/training.json
	$(PYTHON) -m waterair.bench evaluate --compile --out $(OUT)/bench/evaluate.json
	$(PYTHON) -m waterair.bench summary $(OUT)/bench

# As root on a Debian machine: install and start a private single-node Slurm with accounting, run sweeps
# through hydra/launcher=submitit_slurm and check them, then stop what it started (scripts/slurm_check.sh).
slurm-check: $(STAMP)
	scripts/slurm_check.sh

# On a machine with a CUDA GPU: CUDA against the CPU, compiled against eager, a short training, evaluate.py and
# the GPU's benchmarks (scripts/cuda_check.py; OUT/cuda_check/*.json, exit 1 if a part fails). CI has no GPU.
cuda-check: $(STAMP)
	$(PYTHON) scripts/cuda_check.py --out $(OUT)/cuda_check

clean:
	rm -rf $(VENV) *.egg-info .pytest_cache .ruff_cache
