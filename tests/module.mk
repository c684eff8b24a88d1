# Tests: one GoogleTest binary from tests/unit/*_test.cpp; program tests are shell scripts
# under tests/programs/<prog>/*.sh run against $(BIN) (exit 77 = skipped).
UNIT_TESTS += $(sort $(wildcard tests/unit/*.cpp))
BENCH_SRCS += $(sort $(wildcard tests/bench/*_bench.cpp))
PROGRAM_TESTS := $(sort $(wildcard tests/programs/*/*.sh))

STRESS_TESTS := $(sort $(wildcard tests/stress/*.cpp))

UNIT_BIN  := $(BUILD)/tests/unit_tests
STRESS_BIN := $(BUILD)/tests/stress_tests

# Tests find their fixtures from the source tree, wherever the binary runs.
$(BUILD)/tests/%.o: CPPFLAGS += -DSHAPESIM_SOURCE_DIR='"$(CURDIR)"'
BENCH_BIN := $(BUILD)/tests/benchmarks

$(UNIT_BIN): $(UNIT_TESTS:%.cpp=$(BUILD)/%.o) $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ -lgtest -lgtest_main $(LDLIBS) -o $@.tmp && mv $@.tmp $@

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
$(BUILD)/examples/%: $(BUILD)/tests/examples/%.o $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ $(LDLIBS) -o $@.tmp && mv $@.tmp $@

.PHONY: examples
examples: $(EXAMPLES)

test: unit-test program-test

# GTEST_FILTER=... narrows the unit tests; SHAPESIM_DATA points tests at the shipped data.
# Under SAN=1, LeakSanitizer skips the leaks documented in tests/lsan.supp (third-party only).
unit-test: $(UNIT_BIN)
	LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp $(UNIT_BIN) --gtest_brief=1 \
	  $(if $(GTEST_FILTER),--gtest_filter=$(GTEST_FILTER))

program-test: all examples
	BIN=$(abspath $(BIN)) EXAMPLES=$(abspath $(BUILD)/examples) \
	  tests/run-program-tests.sh $(PROGRAM_TESTS)

bench: $(BENCH_BIN)
	$(BENCH_BIN) $(BENCH_ARGS)

# The bad- and odd-input corpus (issue 15). `make corpus` rewrites tests/corpus/cases/ with
# the generator (cfitsio only; the files are committed); `make corpus-matrix` reruns every
# program on every case and rewrites tests/corpus/matrix.md and the README's copy of its
# table; the program test tests/programs/corpus/matrix.sh checks both are current, and CI runs
# the matrix once more on the programs built with SAN=1.
CORPUS_GEN := $(BUILD)/tests/make-corpus
$(CORPUS_GEN): tests/corpus/make-corpus.cpp | deps
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
	tests/corpus/readme-table.sh tests/corpus/matrix.md README.md

# The matrix of the programs in $(BIN) (SAN=1: build-san/bin) equals the committed one.
corpus-check: all
	LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp:print_suppressions=0 ASAN_OPTIONS=detect_leaks=1 \
	  tests/corpus/matrix.sh $(BIN) >$(BUILD)/matrix.md
	diff -u tests/corpus/matrix.md $(BUILD)/matrix.md

