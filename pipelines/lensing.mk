# A weak-lensing shear calibration end to end (issue 38): galaxies of the shipped intrinsic
# model drawn in rotated pairs over an ACS-like field, lensed by a Gaussian random shear field
# (an illustrative power spectrum) plus a constant shear and, optionally, an NFW halo,
# rendered through the ACS F814W PSF with noise, measured by the reference shear estimator
# (shapesim-measure --shear-estimate) and calibrated (shapesim-calibrate): m and c overall and
# against S/N, resolution and magnitude.
#
#   make lensing           (after building; = make -f pipelines/lensing.mk)
#   make -f pipelines/lensing.mk [OUT=out/lensing] [SEED=1] [AREA=4] [NOISE=0.0005]
#                          [SHEAR="0.02 -0.01"] [HALO="X Y M200 C Z"] [SOURCE_Z=1]
#                          [LIKE=image.fits PSF_FIELD=image.psf [ZERO_POINT=…]]
#
# LIKE and PSF_FIELD: your own image's field and the PSF varying across it (psfex's model of
# it): rendered through, and each galaxy's shape corrected by, the PSF at its place; the
# report adds m and c in bins of the PSF's ellipticity there (the truth's psf_e1, psf_e2).
#
# Outputs in $(OUT): objects.jsonl, lensed.jsonl, image.fits, truth.jsonl, shapes.jsonl,
# calibration.md (the report), calibration.json (its numbers) and figures/calibration.png
# (<e − g> against g, and m against S/N).
SELF := $(lastword $(MAKEFILE_LIST))
OUT      ?= out/lensing
include $(dir $(SELF))common.mk

SEED      ?= 1
AREA      ?= 4
NOISE     ?= 0.0005
SHEAR     ?= 0.02 -0.01
HALO      ?=
SOURCE_Z  ?= 1
THREADS   ?= 2
SCALE     := 0.03
ZERO_POINT ?= 25.94
MODEL     := $(R)share/data/models/merged.json
SPECTRUM  := $(R)share/data/lensing/illustrative-cosmic-shear.txt
LIKE      ?=
PSF_FIELD ?=
ifeq ($(PSF_FIELD),)
PSF       := $(R)share/data/psfs/acs-f814w.jsonl
PSF_OPT   := --psf $(PSF)
FIELD     := --area $(AREA) --pixel-scale $(SCALE)
PSF_BINS  :=
else
ifeq ($(LIKE),)
$(error PSF_FIELD needs LIKE: the image psfex modelled, whose field is drawn)
endif
PSF       := $(PSF_FIELD)
PSF_OPT   := --psf-field $(PSF_FIELD)
FIELD     := --like $(LIKE)
PSF_BINS  := --bin psf_e1:4 --bin psf_e2:4
endif
INPUTS    := $(MODEL) $(PSF) $(SPECTRUM)

.PHONY: all outputs
all:
	$(call logged_outputs,SEED=$(SEED) AREA=$(AREA) NOISE=$(NOISE) SHEAR="$(SHEAR)" HALO="$(HALO)")

outputs: $(OUT)/calibration.md

value_seed := $(SEED)
value_area := $(AREA) $(LIKE) $(PSF_FIELD)
value_noise := $(NOISE)
value_lens := $(SHEAR) $(HALO) $(SOURCE_Z)
tmp = $@.tmp

$(OUT)/objects.jsonl: $(MODEL) $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	@mkdir -p $(@D)
	$(call prog,sample) $(MODEL) $(FIELD) --zero-point $(ZERO_POINT) --ring 2 --seed $(SEED) > $(tmp)
	mv $(tmp) $@
$(OUT)/lensed.jsonl: $(OUT)/objects.jsonl $(SPECTRUM) $(OUT)/params/lens $(call prog,lens)
	$(call prog,lens) $(FIELD) --power-spectrum $(SPECTRUM) --shear $(SHEAR) --seed $$(($(SEED) + 1)) \
	  $(if $(HALO),--halo $(HALO) --source-z $(SOURCE_Z) --drop-strong) < $< > $(tmp)
	mv $(tmp) $@
$(OUT)/image.fits $(OUT)/truth.jsonl &: $(OUT)/lensed.jsonl $(PSF) $(OUT)/params/noise $(call prog,render)
	$(call prog,render) $(FIELD) $(PSF_OPT) --noise-rms $(NOISE) --seed $$(($(SEED) + 2)) -j $(THREADS) \
	  --truth $(OUT)/truth.jsonl -o $(OUT)/image.fits < $<
$(OUT)/shapes.jsonl: $(OUT)/image.fits $(PSF) $(call prog,measure)
	$(call prog,measure) $< --zero-point $(ZERO_POINT) $(PSF_OPT) --shear-estimate -j $(THREADS) > $(tmp)
	mv $(tmp) $@
$(OUT)/calibration.md: $(OUT)/truth.jsonl $(OUT)/shapes.jsonl $(call prog,calibrate)
	$(call prog,calibrate) $(OUT)/truth.jsonl $(OUT)/shapes.jsonl --e1 shear_e1 --e2 shear_e2 \
	  --bin snr:4 --bin shear_resolution:4 --bin mag:4 $(PSF_BINS) --json $(OUT)/calibration.json \
	  --figures $(OUT)/figures > $(tmp)
	mv $(tmp) $@
