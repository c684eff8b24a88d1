# A morphology model trained on GalSim RealGalaxyCatalogs: the COSMOS I < 23.5 and I < 25.2
# training samples a lensing user already holds, or any catalogue in that layout, in one
# command. Every galaxy is fitted through its own PSF image (shapesim-decompose
# --real-galaxy-catalog; where a catalogue's PSF file is absent, through PSF, flagged
# psf_substituted), and the fits are smoothed into one model, each galaxy a parent weighted by
# the catalogue's WEIGHT (the sample's selection weights).
#
#   make -f pipelines/cosmos.mk CATALOGS="/data/COSMOS_25.2_training_sample/real_galaxy_catalog_25.2.fits"
#        [OUT=out/cosmos] [PSF='IMAGE[HDU]'] [THREADS=2] [GAIN=0]
#
# Outputs in $(OUT): fits/N.jsonl (catalogue N's models), model.json (the morphology model).
# Draw from it with the I-band count law (shapesim-sample's default):
#   bin/shapesim-sample $(OUT)/model.json --area 6 --pixel-scale 0.03 --zero-point 25.94
# or name it in a survey file (model = $(OUT)/model.json).
SELF := $(lastword $(MAKEFILE_LIST))
OUT      ?= out/cosmos
include $(dir $(SELF))common.mk

CATALOGS ?= $(R)share/data/cosmos_catalog/extension_26/real_galaxy_catalog_26_extension_example.fits
PSF      ?= $(R)share/data/cosmos_catalog/real_galaxy_PSF_images.fits[0]
THREADS  ?= 2
GAIN     ?= 0
INPUTS   := $(CATALOGS)

# Catalogue k of CATALOGS (1-based) is $(OUT)/fits/k.jsonl.
COUNT := $(words $(CATALOGS))
FITS  := $(foreach k,$(shell seq 1 $(COUNT)),$(OUT)/fits/$(k).jsonl)
value_decompose = $(PSF) $(GAIN)

.PHONY: all outputs
all:
	$(call logged_outputs,CATALOGS="$(CATALOGS)" PSF='$(PSF)' GAIN=$(GAIN))
outputs: $(OUT)/model.json

.SECONDARY: $(OUT)/params/decompose
$(OUT)/fits/%.jsonl: $(OUT)/params/decompose $(call prog,decompose)
	@mkdir -p $(@D)
	$(call prog,decompose) -j $(THREADS) --gain $(GAIN) \
	  --real-galaxy-catalog '$(word $*,$(CATALOGS))' --real-galaxy-psf '$(PSF)' > $@.tmp
	mv $@.tmp $@

$(OUT)/model.json: $(FITS) $(call prog,smooth)
	cat $(FITS) | $(call prog,smooth) -v --weight-field weight > $@.tmp
	mv $@.tmp $@
