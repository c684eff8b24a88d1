# What every pipeline makefile shares: strict bash recipes, where the repository and the
# programs are, and parameter files. Include it first, after setting SELF:
#   SELF := $(lastword $(MAKEFILE_LIST))
#   include $(dir $(SELF))common.mk

SHELL := bash
.SHELLFLAGS := -o pipefail -ec
.DELETE_ON_ERROR:
.SUFFIXES:
.DEFAULT_GOAL := all

# The repository, as a prefix: empty when make runs from it, its absolute path otherwise.
ROOT := $(abspath $(dir $(SELF))/..)
R    := $(if $(filter $(CURDIR),$(ROOT)),,$(ROOT)/)
BIN  ?= $(R)bin
prog = $(BIN)/shapesim-$(1)

# $(OUT)/params/NAME holds $(value_NAME) and is rewritten only when that value changes, so the
# targets that name it rerun exactly then.
$(OUT)/params/%: FORCE
	@mkdir -p $(@D)
	@if [ "$$(cat $@ 2>/dev/null)" != '$(value_$*)' ]; then echo '$(value_$*)' > $@; fi
.PHONY: FORCE
FORCE:

# The whole job, logged: a pipeline's `all` runs its `outputs` target in a sub-make and appends
# the transcript to $(OUT)/pipeline.log: the date, the parameters $(1), the programs' version,
# the inputs' SHA-256 ($(INPUTS)), each command with the programs' own timing lines, and the
# total wall time.
define logged_outputs
@mkdir -p $(OUT)
@start=$$(date +%s.%N); { \
  echo "==== $$(date -u '+%Y-%m-%d %H:%M:%S UTC') make -f $(SELF) OUT=$(OUT) $(1)"; \
  echo "programs: $$($(call prog,detect) --version)"; \
  echo "inputs (SHA-256):"; sha256sum $(INPUTS) | sed 's/^/  /'; \
  $(MAKE) --no-print-directory -f $(SELF) outputs; \
  echo "==== done in $$(awk -v a=$$start -v b=$$(date +%s.%N) 'BEGIN { printf "%.1f", b - a }') s"; \
} 2>&1 | tee -a $(OUT)/pipeline.log
endef
