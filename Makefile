# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
# ds3d developer entry points. Every target installs missing Debian packages first
# (scripts/install-deps.sh) and is idempotent.
#   make demo        Release build in build/ and run the demo on generated data
#   make test        build + ctest + pytest + out-of-tree consumer against an installed copy
#                    + offline pip install into a throw-away venv + examples + notebook + docs
#                    + 10 s of each fuzz target (test-fuzz; skipped without clang)
#   make docs        API reference (doxygen) -> build/docs/html; fails on any doxygen warning
#   make test-examples  cluster_bench/sweep.py --quick (the C++ examples run in ctest and
#                    test-consumer); make test-notebook: executes examples/notebooks headless
#   make test-asan   Debug + AddressSanitizer + UBSan build in build-asan/ and its ctest
#                    (per-test limit 3000 s: brute-force cross-checks are slow at -O0 + ASan)
#   make bench       every Google Benchmark binary -> bench/results/<name>.json + summary.md
#   make format / format-check / tidy
PYTHON      ?= /usr/bin/python3
BUILD_DIR   ?= build
ASAN_DIR    ?= build-asan
JOBS        ?= $(shell nproc)
GENERATOR   ?= Ninja
CMAKE_FLAGS ?=
ifeq ($(CI),true)
  CMAKE_FLAGS += -DDS3D_WERROR=ON
endif

.PHONY: all deps configure build demo test test-cpp test-python test-consumer test-pip test-asan bench \
        format format-check tidy clean docs test-examples test-notebook

all: build

deps:
	@scripts/install-deps.sh

$(BUILD_DIR)/CMakeCache.txt: | deps
	cmake -S . -B $(BUILD_DIR) -G $(GENERATOR) -DCMAKE_BUILD_TYPE=Release \
	  -DPython_EXECUTABLE=$(PYTHON) $(CMAKE_FLAGS)

configure: deps $(BUILD_DIR)/CMakeCache.txt

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

demo: build
	$(BUILD_DIR)/bin/ds3d-demo --out $(BUILD_DIR)/demo_out

test: build test-cpp test-python test-consumer test-pip test-examples test-notebook docs test-fuzz
	@echo "make test: all suites passed"

test-cpp: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS)

test-python: build
	PYTHONPATH=$(CURDIR)/$(BUILD_DIR)/python $(PYTHON) -m pytest -q python/tests

test-consumer: build
	scripts/test-consumer.sh $(BUILD_DIR)

# The pip build gets the same CMake flags as build/, so that ccache (when installed) reuses its
# objects instead of compiling the extension a second time.
test-pip: deps
	PYTHON=$(PYTHON) JOBS=$(JOBS) DS3D_CMAKE_ARGS="$(CMAKE_FLAGS)" scripts/test-pip-install.sh

test-examples: build
	PYTHONPATH=$(CURDIR)/$(BUILD_DIR)/python $(PYTHON) examples/cluster_bench/sweep.py --quick \
	  --out $(BUILD_DIR)/cluster_bench

test-notebook: build
	PYTHON=$(PYTHON) scripts/test-notebook.sh $(BUILD_DIR)

# API reference from include/ds3d/*.hpp (Doxyfile); any doxygen warning fails the target.
docs: deps
	@mkdir -p $(BUILD_DIR)/docs
	DS3D_DOCS_DIR=$(BUILD_DIR)/docs doxygen Doxyfile
	@if [ -s $(BUILD_DIR)/docs/warnings.log ]; then cat $(BUILD_DIR)/docs/warnings.log; \
	  echo "make docs: $$(wc -l < $(BUILD_DIR)/docs/warnings.log) doxygen warning(s)"; exit 1; fi
	@echo "make docs: $(BUILD_DIR)/docs/html/index.html (no warnings)"

test-asan: deps
	cmake -S . -B $(ASAN_DIR) -G $(GENERATOR) -DCMAKE_BUILD_TYPE=Debug -DDS3D_SANITIZE=ON \
	  -DDS3D_TEST_TIMEOUT=3000 \
	  -DDS3D_BUILD_PYTHON=OFF -DDS3D_BUILD_BENCH=OFF -DPython_EXECUTABLE=$(PYTHON) $(CMAKE_FLAGS)
	cmake --build $(ASAN_DIR) -j $(JOBS)
	cd $(ASAN_DIR) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS)

bench: build
	$(PYTHON) scripts/run_bench.py --build-dir $(BUILD_DIR) --out bench/results

format:
	scripts/format.sh fix

format-check: deps
	scripts/format.sh check

tidy: configure
	scripts/format.sh tidy $(BUILD_DIR)

clean:
	rm -rf $(BUILD_DIR) $(ASAN_DIR)

# Side-by-side single-thread timing against Open3D and PCL (installs libopen3d-dev, libpcl-dev).
# COMPARE_ARGS e.g. "--sizes 300000 --reps 5 --slow-reps 3".
COMPARE_DIR  ?= build-compare
COMPARE_ARGS ?=
.PHONY: bench-compare
bench-compare:
	DS3D_EXTRA_PACKAGES="libopen3d-dev libpcl-dev" scripts/install-deps.sh
	cmake -S bench/compare -B $(COMPARE_DIR) -G $(GENERATOR) -DCMAKE_BUILD_TYPE=Release
	cmake --build $(COMPARE_DIR) -j $(JOBS)
	OMP_NUM_THREADS=1 $(COMPARE_DIR)/bin/compare_open3d_pcl $(COMPARE_ARGS)

# ---- fuzzing: libFuzzer targets tests/fuzz/*_fuzz.cpp, built by tests/fuzz/CMakeLists.txt with
# clang + ASan/UBSan in build-fuzz/ (incremental), each run for FUZZ_SECONDS (default 60) from a
# seed corpus of tests/data. test-fuzz (part of `make test`): FUZZ_SECONDS=10, skipped without
# clang. A crash leaves its input in build-fuzz/crash-*: add it to the target's regression test.
FUZZ_DIR     ?= build-fuzz
FUZZ_SECONDS ?= 60
FUZZ_CXX     ?= clang++
FUZZ_RUN      = -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 -artifact_prefix=$(FUZZ_DIR)/
FUZZ_TARGETS  = tum_trajectory:8192:corpus_traj tum_list:4096:corpus_list camera:2048:corpus_camera \
                weights_io:65536:corpus_weights weights_stream:65536:corpus_weights_stream \
                hdbscan:6148:corpus_hdbscan ate_plot:8192:corpus_ate_plot
.PHONY: fuzz fuzz-build test-fuzz
fuzz-build: deps
	cmake -S tests/fuzz -B $(FUZZ_DIR) -G $(GENERATOR) -DCMAKE_CXX_COMPILER=$(FUZZ_CXX)
	cmake --build $(FUZZ_DIR) -j $(JOBS)
	@mkdir -p $(FUZZ_DIR)/corpus_traj $(FUZZ_DIR)/corpus_list $(FUZZ_DIR)/corpus_camera $(FUZZ_DIR)/corpus_weights
	@for d in tests/data/trajectory/*/; do head -c 4000 $$d/estimate.txt > $(FUZZ_DIR)/corpus_traj/$$(basename $$d); done
	@printf '# rgb\n1305031102.175304 rgb/1.png\n1305031102.211214,rgb/2.jpg\r\n' > $(FUZZ_DIR)/corpus_list/seed
	@cp tests/data/dataset/*.txt $(FUZZ_DIR)/corpus_camera/
	@cp tests/data/htx/*.safetensors $(FUZZ_DIR)/corpus_weights/
	$(PYTHON) scripts/fuzz-seeds.py $(FUZZ_DIR)

fuzz: fuzz-build
	@set -e; for t in $(FUZZ_TARGETS); do \
	  name=$${t%%:*}; rest=$${t#*:}; len=$${rest%%:*}; corpus=$${rest#*:}; \
	  echo "fuzz: $$name ($(FUZZ_SECONDS) s)"; \
	  $(FUZZ_DIR)/$${name}_fuzz $(FUZZ_RUN) -max_len=$$len $(FUZZ_DIR)/$$corpus 2>$(FUZZ_DIR)/$$name.log \
	    || { tail -40 $(FUZZ_DIR)/$$name.log; exit 1; }; \
	  grep -E "stat::number_of_executed_units" $(FUZZ_DIR)/$$name.log | sed "s/^/  /"; \
	done
	@echo "make fuzz: no crash in $(FUZZ_SECONDS) s per target"

test-fuzz:
	@if command -v $(FUZZ_CXX) >/dev/null 2>&1; then $(MAKE) --no-print-directory fuzz FUZZ_SECONDS=10; \
	else echo "make test-fuzz: $(FUZZ_CXX) not found, fuzzing skipped (scripts/deps/eval.txt installs clang)"; fi
