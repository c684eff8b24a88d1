# Tests: one GoogleTest binary from tests/unit/*_test.cpp; program tests are shell scripts
# under tests/programs/<prog>/*.sh run against $(BIN) (exit 77 = skipped).
UNIT_TESTS += $(sort $(wildcard tests/unit/*.cpp))
BENCH_SRCS += $(sort $(wildcard tests/bench/*_bench.cpp))
PROGRAM_TESTS := $(sort $(wildcard tests/programs/*/*.sh))

STRESS_TESTS := $(sort $(wildcard tests/stress/*.cpp))

UNIT_BIN  := $(BUILD)/tests/unit_tests
STRESS_BIN := $(BUILD)/tests/stress_tests

# Tests find their fixtures in the source tree above their binary (test_support.hpp
# source_dir): no absolute path is compiled in, so a compiler cache serves any clone.
BENCH_BIN := $(BUILD)/tests/benchmarks

# The unit tests also hold the programs' own option code (every program source but main.cpp).
UNIT_PROGRAM_OBJS = $(filter-out %/main.o,$(PROGRAM_OBJS))
$(UNIT_BIN): $(UNIT_TESTS:%.cpp=$(BUILD)/%.o) $(UNIT_PROGRAM_OBJS) $(APP_LIB) $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -lgtest -lgtest_main $(LDLIBS) $(APP_LDLIBS) -o $@.tmp && mv $@.tmp $@

$(STRESS_BIN): $(STRESS_TESTS:%.cpp=$(BUILD)/%.o) $(BUILD)/tests/unit/test_support.o $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -lgtest -lgtest_main $(LDLIBS) -o $@.tmp && mv $@.tmp $@

stress: $(STRESS_BIN)
	$(STRESS_BIN) --gtest_brief=1

$(BENCH_BIN): $(BENCH_SRCS:%.cpp=$(BUILD)/%.o) $(BUILD)/tests/unit/test_support.o $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -lbenchmark -lbenchmark_main $(LDLIBS) -o $@.tmp && mv $@.tmp $@

# Examples: small programs on the library that the README shows (and program tests run).
EXAMPLE_SRCS := $(sort $(wildcard tests/examples/*.cpp))
EXAMPLES     := $(EXAMPLE_SRCS:tests/examples/%.cpp=$(BUILD)/examples/%)

$(EXAMPLE_SRCS:%.cpp=$(BUILD)/%.o):
$(BUILD)/examples/%: $(BUILD)/tests/examples/%.o $(APP_LIB) $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ $(LDLIBS) $(APP_LDLIBS) -o $@.tmp && mv $@.tmp $@

.PHONY: examples
examples: $(EXAMPLES)

test: unit-test program-test

# GTEST_FILTER=... narrows the unit tests; SHAPESIM_DATA points tests at the shipped data.
# Under SAN=1, LeakSanitizer skips the leaks documented in tests/lsan.supp (third-party only).
# The tests are split into UNIT_SHARDS GoogleTest shards (every test in exactly one; test k in
# shard k mod UNIT_SHARDS, so the long decomposition tests, which sit together, spread out)
# run UNIT_JOBS at a time (default: one per core; four shards per core balance the load),
# each shard's output printed whole once all have ended.
UNIT_JOBS   ?= $(shell nproc 2>/dev/null || echo 1)
UNIT_SHARDS ?= $(shell echo $$((4 * $(UNIT_JOBS))))
unit-test: $(UNIT_BIN)
	@rm -f $(BUILD)/unit-shard-*.log $(BUILD)/unit-shards.failed; \
	seq 0 $$(($(UNIT_SHARDS) - 1)) | xargs -P $(UNIT_JOBS) -I{} sh -c \
	  'GTEST_TOTAL_SHARDS=$(UNIT_SHARDS) GTEST_SHARD_INDEX={} \
	   LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp $(UNIT_BIN) --gtest_brief=1 \
	     $(if $(GTEST_FILTER),--gtest_filter=$(GTEST_FILTER)) >$(BUILD)/unit-shard-{}.log 2>&1 || \
	   echo {} >>$(BUILD)/unit-shards.failed'; \
	for i in $$(seq 0 $$(($(UNIT_SHARDS) - 1))); do cat $(BUILD)/unit-shard-$$i.log; done; \
	if [ -s $(BUILD)/unit-shards.failed ]; then \
	  echo "unit tests FAILED in shard(s) $$(sort -n $(BUILD)/unit-shards.failed | tr '\n' ' ')of $(UNIT_SHARDS)"; \
	  exit 1; \
	fi

program-test: all examples
	BIN=$(abspath $(BIN)) EXAMPLES=$(abspath $(BUILD)/examples) \
	  tests/run-program-tests.sh $(PROGRAM_TESTS)

# Google Benchmark (every stage: run time and the error it buys), then the HDF scene end to end
# through shapesim-render at 1 and 2 threads (tests/bench/hdf_scene.sh; make reproduce's
# morphology, PSF and sky).
bench: $(BENCH_BIN) all
	$(BENCH_BIN) $(BENCH_ARGS)
	@[ -f out/reproduce/morphology.json ] || $(MAKE) reproduce
	tests/bench/hdf_scene.sh $(BIN) out/reproduce

# The bad- and odd-input corpus (issue 15). `make corpus` rewrites tests/corpus/cases/ with
# the generator (cfitsio only; the files are committed); `make corpus-matrix` reruns every
# program on every case and rewrites tests/corpus/matrix.md and docs/corpus.md's copy of its
# table; the program test tests/programs/corpus/matrix.sh checks both are current, and CI runs
# the matrix once more on the programs built with SAN=1.
CORPUS_GEN := $(BUILD)/tests/make-corpus
$(CORPUS_GEN): tests/corpus/make-corpus.cpp tests/corpus/tool_support.hpp | deps
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) -std=c++17 $(OPT) $(WARN) $< -lcfitsio -o $@.tmp && mv $@.tmp $@

.PHONY: corpus corpus-matrix corpus-check
corpus: $(CORPUS_GEN)
	rm -rf tests/corpus/cases.tmp && mkdir tests/corpus/cases.tmp
	$(CORPUS_GEN) tests/corpus/cases.tmp
	rm -rf tests/corpus/cases && mv tests/corpus/cases.tmp tests/corpus/cases

corpus-matrix: all
	tests/corpus/matrix.sh $(BIN) >tests/corpus/matrix.md.tmp
	mv tests/corpus/matrix.md.tmp tests/corpus/matrix.md
	tests/corpus/readme-table.sh tests/corpus/matrix.md docs/corpus.md

# The matrix of the programs in $(BIN) (SAN=1: build-san/bin) equals the committed one.
corpus-check: all
	LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp:print_suppressions=0 ASAN_OPTIONS=detect_leaks=1 \
	  tests/corpus/matrix.sh $(BIN) >$(BUILD)/matrix.md
	diff -u tests/corpus/matrix.md $(BUILD)/matrix.md

# Fuzzing (issue 15): libFuzzer harnesses for the record readers and the FITS path, built with
# clang, AddressSanitizer and UBSan into build-fuzz/ (the whole library instrumented), each run
# for FUZZ_RUNS executions (at most FUZZ_TIME seconds) from the committed seed corpus
# tests/fuzz/corpus/<target>/; what the run discovers stays in build-fuzz/corpus-<target>/, a
# crash in build-fuzz/crash-*. The FITS target checks leaks once at exit, not after every input:
# cfitsio leaks 32 bytes on some failed opens (tests/lsan.supp), and a leak scan per input
# would take 80% of the run. Its resident memory climbs to ~1.9 GB over 10⁶ runs (ASan's
# caches), hence a 4 GB RSS limit; one allocation over 2 GB is still a failure.
FUZZ_BUILD := build-fuzz
FUZZ_CXX   ?= clang++
FUZZ_FLAGS := -std=c++17 -O1 -gline-tables-only -fno-omit-frame-pointer -fno-sanitize-recover=all \
              -fsanitize=address,undefined -Wno-psabi
FUZZ_RUNS  ?= 1000000
FUZZ_TIME  ?= 900
# FUZZ_SEED=N makes a run repeatable (CI: the same commit fuzzes the same inputs every time).
FUZZ_SEED  ?=
FUZZ_TARGETS := records fits
FUZZ_LIB   := $(FUZZ_BUILD)/libshapesim.a

$(FUZZ_BUILD)/%.o: %.cpp | deps
	@mkdir -p $(@D)
	$(if $(Q),@echo "  FUZZ $<")
	$(Q)$(FUZZ_CXX) $(CPPFLAGS) -MMD -MP -MT $@ -MF $(@:.o=.d) $(FUZZ_FLAGS) -fsanitize=fuzzer-no-link -c $< -o $@.tmp.o
	$(Q)mv $@.tmp.o $@

$(FUZZ_LIB): $(LIB_SRCS:%.cpp=$(FUZZ_BUILD)/%.o)
	$(Q)rm -f $@.tmp && ar rcs $@.tmp $^ && mv $@.tmp $@

$(FUZZ_TARGETS:%=$(FUZZ_BUILD)/tests/fuzz/fuzz_%.o):
$(FUZZ_BUILD)/fuzz_%: $(FUZZ_BUILD)/tests/fuzz/fuzz_%.o $(FUZZ_LIB)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(FUZZ_CXX) $(FUZZ_FLAGS) -fsanitize=fuzzer -pthread $^ $(LDLIBS) -o $@.tmp && mv $@.tmp $@

.PHONY: fuzz
fuzz: $(FUZZ_TARGETS:%=$(FUZZ_BUILD)/fuzz_%)
	@for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_BUILD)/corpus-$$t; \
	  echo "== fuzz $$t: $(FUZZ_RUNS) runs (at most $(FUZZ_TIME) s)"; \
	  LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp:print_suppressions=0 \
	  $(FUZZ_BUILD)/fuzz_$$t $(FUZZ_BUILD)/corpus-$$t tests/fuzz/corpus/$$t \
	    -runs=$(FUZZ_RUNS) -max_total_time=$(FUZZ_TIME) -max_len=32768 -rss_limit_mb=4096 -malloc_limit_mb=2048 \
	    -timeout=20 -print_final_stats=1 -artifact_prefix=$(FUZZ_BUILD)/ $(if $(FUZZ_SEED),-seed=$(FUZZ_SEED)) \
	    $$( [ $$t = fits ] && echo -detect_leaks=0 ) \
	    2>$(FUZZ_BUILD)/$$t.log || \
	    { tail -n 40 $(FUZZ_BUILD)/$$t.log; exit 1; }; \
	  grep -E '^stat::number_of_executed_units|^Done' $(FUZZ_BUILD)/$$t.log; \
	done
-include $(shell find $(FUZZ_BUILD) -name '*.d' 2>/dev/null)
