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
