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
