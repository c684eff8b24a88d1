# Multi-colour simulation of the XDF cutout (issue 17): detect on the detection image, measure
# and cut every band in its apertures, fit all nine bands jointly, smooth the joint morphology,
# draw δ-function and full simulations in every band, then measure real and simulated fields
# the same way (SExtractor's dual-image mode on F814W) and compare their colours.
#
#   make colour            (after building; = make -f pipelines/colour.mk)
#   make -f pipelines/colour.mk [OUT=out/colour] [SEED=7] [AREA=1.5] [MAG_LIMIT=28] [THREADS=2]
#
# Outputs in $(OUT): sources.jsonl and stamps.fits (every band's stamps), joint.jsonl (the
# nine-band models), delta.json and morphology.json, {delta,sim}/<band>.fits and their truth,
# {real,delta,sim}.sources.jsonl (dual-image photometry), colours.md (the report) and
# figures/rgb.png (F814W/F606W/F435W as red/green/blue: real | δ | full simulation).
SELF := $(lastword $(MAKEFILE_LIST))
OUT      ?= out/colour
include $(dir $(SELF))common.mk

EXAMPLES  ?= $(R)build/examples
XDF       ?= $(R)share/data/xdf
SEED      ?= 7
# The simulated area, arcmin² (the cutout's 0.25 six times over: more galaxies to compare).
AREA      ?= 1.5
THREADS   ?= 2
MAG_LIMIT ?= 28
# Extra shapesim-smooth options for both models (e.g. --keep-colour-noise to compare).
SMOOTH_OPTIONS ?=
SCALE     := 0.06
REFERENCE := f814w
BANDS     := f435w f606w f775w f814w f850lp f105w f125w f140w f160w
# AB zero points of the bands, e⁻/s (share/data/xdf/README.md).
ZP_f435w := 25.684
ZP_f606w := 26.505
ZP_f775w := 25.678
ZP_f814w := 25.959
ZP_f850lp := 24.867
ZP_f105w := 26.269
ZP_f125w := 26.230
ZP_f140w := 26.452
ZP_f160w := 25.946
# Photon noise only where the gain is known: F814W's exposure (the HDF/XDF README).
GAIN_f814w := 50800
# F814W ships uncompressed for make reproduce; the other bands gzipped (cfitsio reads both).
sci = $(XDF)/$(1)_sci.fits$(if $(filter f814w,$(1)),,.gz)
wht = $(XDF)/$(1)_wht.fits$(if $(filter f814w,$(1)),,.gz)
STAR := [87:145,352:410]
INPUTS := $(foreach b,$(BANDS) detection,$(call sci,$(b)) $(call wht,$(b)))
KINDS := delta sim

.PHONY: all outputs
all:
	$(call logged_outputs,SEED=$(SEED) AREA=$(AREA) MAG_LIMIT=$(MAG_LIMIT))

outputs: $(OUT)/colours.md $(OUT)/figures/rgb.png

value_seed := $(SEED)
value_area := $(AREA)
tmp = $@.tmp

$(OUT)/real.bands.jsonl: $(INPUTS)
	@mkdir -p $(@D)
	{ $(foreach b,$(BANDS),printf '{"schema":"shapesim.band/1","band":"%s","image":"%s","weight":"%s","zero_point":%s%s}\n' \
	    $(b) $(abspath $(call sci,$(b))) $(abspath $(call wht,$(b))) $(ZP_$(b)) '$(if $(GAIN_$(b)),$(comma)"gain":$(GAIN_$(b)))';) } > $(tmp)
	mv $(tmp) $@
comma := ,

# The PSF, from the cut's bright star in F814W (the bands are matched to one PSF).
$(OUT)/psf.jsonl: $(call sci,f814w) $(call prog,decompose)
	@mkdir -p $(@D)
	$(call prog,decompose) --psf-image '$(call sci,f814w)$(STAR)' --psf-pixel-scale $(SCALE) \
	  --pixel-scale $(SCALE) > $(tmp)
	mv $(tmp) $@

# Detection on the detection image; every band measured in its apertures and cut in its boxes.
$(OUT)/sources.jsonl $(OUT)/stamps.fits $(OUT)/stars.jsonl &: $(OUT)/real.bands.jsonl $(OUT)/psf.jsonl $(call prog,detect)
	$(call prog,detect) $(call sci,detection) --weight $(call wht,detection) --pixel-scale $(SCALE) \
	  --psf $(OUT)/psf.jsonl --bands $(OUT)/real.bands.jsonl --stamps $(OUT)/stamps.fits \
	  --stars $(OUT)/stars.jsonl > $(OUT)/sources.jsonl.tmp
	mv $(OUT)/sources.jsonl.tmp $(OUT)/sources.jsonl

# Nine bands at once: one centre, β and n_max; F814W the reference (the records' own model).
$(OUT)/joint.jsonl: $(OUT)/sources.jsonl $(OUT)/stars.jsonl $(call prog,decompose)
	$(call prog,decompose) -j $(THREADS) --stars $(OUT)/stars.jsonl --reference-band $(REFERENCE) \
	  < $< > $(tmp)
	mv $(tmp) $@

$(OUT)/delta.json: $(OUT)/joint.jsonl $(call prog,smooth)
	$(call prog,smooth) --delta --area 0.25 $(SMOOTH_OPTIONS) < $< > $(tmp)
	mv $(tmp) $@
$(OUT)/morphology.json: $(OUT)/joint.jsonl $(call prog,smooth)
	$(call prog,smooth) --area 0.25 $(SMOOTH_OPTIONS) < $< > $(tmp)
	mv $(tmp) $@

FIELD := --area $(AREA) --pixel-scale $(SCALE)
$(OUT)/delta.objects.jsonl: $(OUT)/delta.json $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	$(call prog,sample) $< $(FIELD) --zero-point $(ZP_$(REFERENCE)) --seed $(SEED) > $(tmp)
	mv $(tmp) $@
$(OUT)/sim.objects.jsonl: $(OUT)/morphology.json $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	$(call prog,sample) $< $(FIELD) --zero-point $(ZP_$(REFERENCE)) --seed $(SEED) > $(tmp)
	mv $(tmp) $@

# Each band's sky, measured on its own image (rms and 2-D autocorrelation).
$(OUT)/noise/%.jsonl: $(INPUTS) $(call prog,detect)
	@mkdir -p $(@D)
	$(call prog,detect) -q $(call sci,$*) --weight $(call wht,$*) --pixel-scale $(SCALE) \
	  --noise-model $(tmp) > /dev/null
	mv $(tmp) $@

# Every band of every simulation: its own noise realisation of SEED, photon noise where known.
define render_band
$(OUT)/$(1)/$(2).fits $(OUT)/$(1)/$(2).truth.jsonl &: $(OUT)/$(1).objects.jsonl $(OUT)/noise/$(2).jsonl $(call prog,render)
	@mkdir -p $(OUT)/$(1)
	$(call prog,render) -q -j $(THREADS) --band $(2) --noise-model $(OUT)/noise/$(2).jsonl \
	  $(if $(GAIN_$(2)),--gain $(GAIN_$(2))) $(FIELD) --seed $(SEED) -o $(OUT)/$(1)/$(2).fits \
	  --truth $(OUT)/$(1)/$(2).truth.jsonl < $(OUT)/$(1).objects.jsonl
endef
$(foreach k,$(KINDS),$(foreach b,$(BANDS),$(eval $(call render_band,$(k),$(b)))))

$(OUT)/%.sim-bands.jsonl: $(foreach b,$(BANDS),$(OUT)/%/$(b).fits)
	{ $(foreach b,$(BANDS),printf '{"schema":"shapesim.band/1","band":"%s","image":"%s","zero_point":%s}\n' \
	    $(b) $(abspath $(OUT)/$*/$(b).fits) $(ZP_$(b));) } > $(tmp)
	mv $(tmp) $@

# Real and simulated fields measured alike: detection on F814W, every band in its apertures.
$(OUT)/real.sources.jsonl: $(OUT)/real.bands.jsonl $(OUT)/psf.jsonl $(call prog,detect)
	$(call prog,detect) -q $(call sci,f814w) --weight $(call wht,f814w) --pixel-scale $(SCALE) \
	  --zero-point $(ZP_f814w) --psf $(OUT)/psf.jsonl --bands $< > $(tmp)
	mv $(tmp) $@
$(OUT)/delta.sources.jsonl $(OUT)/sim.sources.jsonl: $(OUT)/%.sources.jsonl: $(OUT)/%.sim-bands.jsonl $(OUT)/psf.jsonl $(call prog,detect)
	$(call prog,detect) -q $(OUT)/$*/f814w.fits --pixel-scale $(SCALE) --zero-point $(ZP_f814w) \
	  --psf $(OUT)/psf.jsonl --bands $< > $(tmp)
	mv $(tmp) $@

$(OUT)/colours.md: $(OUT)/real.sources.jsonl $(OUT)/delta.sources.jsonl $(OUT)/sim.sources.jsonl $(call prog,measure)
	$(call prog,measure) --compare-colours $(foreach k,real delta sim,$(k)=$(OUT)/$(k).sources.jsonl) \
	  --mag-limit $(MAG_LIMIT) > $(tmp)
	mv $(tmp) $@
	cat $@

# Real | δ | full: the simulations' first 500 × 500 pixels, as large as the cutout.
CUT := [1:500,1:500]
RGB_BANDS := f814w f606w f435w
$(OUT)/figures/rgb.png: $(foreach k,$(KINDS),$(foreach b,$(RGB_BANDS),$(OUT)/$(k)/$(b).fits)) $(EXAMPLES)/rgb
	@mkdir -p $(@D)
	$(EXAMPLES)/rgb $(@:.png=.ppm) $(foreach b,$(RGB_BANDS),$(call sci,$(b))) \
	  $(foreach k,$(KINDS),$(foreach b,$(RGB_BANDS),'$(OUT)/$(k)/$(b).fits$(CUT)'))
	pnmtopng $(@:.png=.ppm) > $(tmp) && rm $(@:.png=.ppm) && mv $(tmp) $@
