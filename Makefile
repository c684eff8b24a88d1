# shapesim — one non-recursive make (Miller, "Recursive Make Considered Harmful").
# Fragments (share/module.mk, <prog>/module.mk, tests/module.mk) append to the lists below
# and hold rules only for their own outputs.
#
#   make reproduce       install what is missing, build, and reproduce the paper on the shipped
#                        HDF data into out/reproduce/ (pipelines/reproduce.mk; OUT=, SEED=, AREA=)
#   make                 build the library and every program into bin/
#   make test            unit tests (GoogleTest) and program tests
#   make bench           Google Benchmark: run time and the error it buys
#   make stress          orders past 100, extreme beta, NaN-riddled and 8192² inputs
#   make fuzz            libFuzzer on the record readers and the FITS path (clang, build-fuzz/)
#   make corpus-matrix   every program on the bad-input corpus into tests/corpus/matrix.md
#   make colour          the multi-colour simulation of the shipped ten-band XDF cutout into
#                        out/colour/ (pipelines/colour.mk; OUT=, SEED=, AREA=, MAG_LIMIT=)
#   make lensing         a weak-lensing shear calibration end to end into out/lensing/
#                        (pipelines/lensing.mk; OUT=, SEED=, AREA=, NOISE=, SHEAR=, HALO=)
#   make cosmos CATALOGS="FILE..."  a morphology model trained on GalSim RealGalaxyCatalogs
#                        (the COSMOS training samples) into out/cosmos/ (pipelines/cosmos.mk)
#   make shapes          the survey's ellipticities against the real COSMOS/AEGIS stamps'
#                        into out/shapes/ (pipelines/shapes.sh)
#   make kids            the real KiDS r frame fitted, replayed and δ-simulated, measured
#                        alike, into out/kids/ (pipelines/kids.sh; BAND=, SEEDS=, JOBS=)
#   make slurm-test      a 4-tile survey through a one-node Slurm cluster = make -j (root; CI)
#   make install         programs, libshapesim.a, public headers, shapesim.pc and man pages
#                        into PREFIX (/usr/local); DESTDIR= stages them
#   make WERROR=1        warnings are errors (CI)
#   make test SAN=1      unit tests under AddressSanitizer + UBSan (objects in build-san/)
#   make V=1             echo commands

SHELL := bash
.SHELLFLAGS := -o pipefail -ec
.DELETE_ON_ERROR:
.SUFFIXES:
.DEFAULT_GOAL := all

PREFIX  ?= /usr/local
CXX     ?= g++
# Sanitizer builds at -Og with line tables only (-g1: stack traces keep file and line): half
# the compile time of -O1 -g (the sanitized build is CI's longest stage) and the same bits (no
# -ffast-math, no contraction).
OPT     ?= $(if $(SAN),-Og,-O2) -march=x86-64-v2
# -Wno-psabi: vector lanes are passed by value only inside always-inlined code and between
# functions of one target, so the warning that AVX code would pass them differently is moot
# (share/shapesim/lane_math.hpp).
WARN    := -Wall -Wextra -Wno-psabi $(if $(WERROR),-Werror)
comma := ,
SANFLAGS := $(if $(SAN),-fsanitize=address$(comma)undefined -fno-omit-frame-pointer \
            -fno-sanitize-recover=all)
BUILD   := build$(if $(SAN),-san)
BIN     := $(if $(SAN),$(BUILD)/bin,bin)
VERSION := $(shell git describe --always --dirty 2>/dev/null || echo unknown)

CPPFLAGS += -Ishare -I. -isystem /usr/include/eigen3
CXXFLAGS ?= $(OPT) $(if $(SAN),-g1,-g)
# No fused multiply-adds even where the target has them: the noise and every sum give the same
# bits on every machine and with every SIMD path (pixel_noise.hpp).
CXXFLAGS += -std=c++17 $(WARN) $(SANFLAGS) -pthread -ffp-contract=off
LDFLAGS  += $(SANFLAGS) -pthread
LDLIBS   := -lcfitsio -lsep -lwcs
# The programs' plumbing (app/: options, logging, exit codes) is the one user of Boost's
# compiled part; the library links without it.
APP_LDLIBS := -lboost_program_options

Q := $(if $(V),,@)

LIB      := $(BUILD)/libshapesim.a
LIB_OBJS  = $(LIB_SRCS:%.cpp=$(BUILD)/%.o)
APP_LIB  := $(BUILD)/libshapesim-app.a
APP_OBJS  = $(APP_SRCS:%.cpp=$(BUILD)/%.o)

# A program's objects: every source of its folder (<prog>/main.cpp, its options, its modes).
program_objs = $(patsubst %.cpp,$(BUILD)/%.o,$(sort $(wildcard $(1)/*.cpp)))
PROGRAM_OBJS = $(foreach p,$(PROGRAMS:shapesim-%=%),$(call program_objs,$(p)))
.SECONDEXPANSION:

# Lists the fragments append to.
LIB_SRCS   :=
APP_SRCS   :=
PROGRAMS   :=
UNIT_TESTS :=
BENCH_SRCS :=

include share/module.mk app/module.mk
include detect/module.mk decompose/module.mk smooth/module.mk sample/module.mk
include render/module.mk measure/module.mk survey/module.mk table/module.mk lens/module.mk calibrate/module.mk
include tests/module.mk

.PHONY: all deps test unit-test program-test bench stress install clean reproduce colour lensing cosmos shapes kids slurm-test
all: $(PROGRAMS:%=$(BIN)/%)

# Every first target installs what is missing (as root) or prints the apt line.
deps:
	$(Q)share/scripts/install-deps.sh

$(BUILD)/%.o: %.cpp | deps
	@mkdir -p $(@D)
	$(if $(Q),@echo "  CXX  $<")
	$(Q)$(CXX) $(CPPFLAGS) -MMD -MP -MT $@ -MF $(@:.o=.d) $(CXXFLAGS) -c $< -o $@.tmp.o
	$(Q)mv $@.tmp.o $@

$(LIB): $(LIB_OBJS)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  AR   $@")
	$(Q)rm -f $@.tmp && ar rcs $@.tmp $^ && mv $@.tmp $@

$(APP_LIB): $(APP_OBJS)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  AR   $@")
	$(Q)rm -f $@.tmp && ar rcs $@.tmp $^ && mv $@.tmp $@

# Each program links the sources of its own folder (main.cpp and its options, its modes)
# against the programs' plumbing and the library. Naming the objects as targets keeps make from
# treating them as intermediate files (deleting them, or missing their rebuild).
$(PROGRAM_OBJS):
$(BIN)/shapesim-%: $$(call program_objs,$$*) $(APP_LIB) $(LIB)
	@mkdir -p $(@D)
	$(if $(Q),@echo "  LD   $@")
	$(Q)$(CXX) $(LDFLAGS) $^ $(LDLIBS) $(APP_LDLIBS) -o $@.tmp && mv $@.tmp $@

# The version string lives in version.o alone; its stamp changes only when `git describe` does.
$(BUILD)/version.stamp: FORCE
	@mkdir -p $(@D)
	@if [ "$$(cat $@ 2>/dev/null)" != "$(VERSION)" ]; then echo "$(VERSION)" > $@; fi
$(BUILD)/share/shapesim/version.o: $(BUILD)/version.stamp
$(BUILD)/share/shapesim/version.o: CPPFLAGS += -DSHAPESIM_VERSION='"$(VERSION)"'
.PHONY: FORCE
FORCE:

# The paper end to end (pipelines/reproduce.mk); make variables (OUT, SEED, AREA, THREADS) pass on.
reproduce: deps all examples
	$(MAKE) --no-print-directory -f pipelines/reproduce.mk BIN=$(BIN) EXAMPLES=$(BUILD)/examples

# The XDF's nine bands end to end (pipelines/colour.mk); OUT, SEED, AREA, MAG_LIMIT pass on.
colour: deps all examples
	$(MAKE) --no-print-directory -f pipelines/colour.mk BIN=$(BIN) EXAMPLES=$(BUILD)/examples

# Ellipticities of the survey's galaxies against the real COSMOS/AEGIS stamps', measured alike
# (pipelines/shapes.sh, docs/sample.md#ellipticities); SEEDS, MAG_CUT pass on.
shapes: deps all
	pipelines/shapes.sh $(BIN) out/shapes

# A real ground-based frame through the whole chain (pipelines/kids.sh): the KiDS r frame's fits
# replayed and δ-simulated, measured alike; BAND, SEEDS, JOBS pass on.
kids: deps all
	pipelines/kids.sh $(BIN) out/kids

# A weak-lensing shear calibration end to end (pipelines/lensing.mk); OUT, SEED, AREA, NOISE,
# SHEAR, HALO pass on.
lensing: deps all
	$(MAKE) --no-print-directory -f pipelines/lensing.mk BIN=$(BIN)

# A morphology model trained on RealGalaxyCatalogs (pipelines/cosmos.mk): CATALOGS, OUT, PSF,
# THREADS, GAIN pass on.
cosmos: deps all
	$(MAKE) --no-print-directory -f pipelines/cosmos.mk BIN=$(BIN)

# A 4-tile survey on a throw-away one-node Slurm cluster equals make -j (CI; root; installs Slurm).
slurm-test: all
	tests/slurm/survey.sh

# Man pages from each program's --help and --version; the NAME line is SUMMARY.<prog> in its
# module.mk, the date the last commit's (SOURCE_DATE_EPOCH), so a rebuild gives the same page.
MANPAGES := $(PROGRAMS:%=$(BUILD)/man/%.1)
$(BUILD)/man/%.1: $(BIN)/% | deps
	@mkdir -p $(@D)
	$(if $(Q),@echo "  MAN  $@")
	$(Q)SOURCE_DATE_EPOCH=$$(git log -1 --format=%ct 2>/dev/null || date +%s) \
	  help2man --no-info --name='$(SUMMARY.$*)' --output=$@.tmp $< && mv $@.tmp $@
.PHONY: man
man: $(MANPAGES)

# The programs, the library, its public headers (not app/: program plumbing that pulls in
# Boost), shapesim.pc (share/shapesim.pc.in with this PREFIX), the man pages and the data.
install: all man
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig \
	  $(DESTDIR)$(PREFIX)/include/shapesim $(DESTDIR)$(PREFIX)/share/shapesim \
	  $(DESTDIR)$(PREFIX)/share/man/man1
	install -m 755 $(PROGRAMS:%=$(BIN)/%) $(DESTDIR)$(PREFIX)/bin/
	install -m 644 $(LIB) $(DESTDIR)$(PREFIX)/lib/
	install -m 644 share/shapesim/*.hpp $(DESTDIR)$(PREFIX)/include/shapesim/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(VERSION)|' share/shapesim.pc.in \
	  >$(DESTDIR)$(PREFIX)/lib/pkgconfig/shapesim.pc
	install -m 644 $(MANPAGES) $(DESTDIR)$(PREFIX)/share/man/man1/
	if [ -d share/data ]; then cp -R share/data/. $(DESTDIR)$(PREFIX)/share/shapesim/; fi

clean:
	rm -rf build build-san build-fuzz bin

-include $(shell find $(BUILD) -name '*.d' 2>/dev/null)
