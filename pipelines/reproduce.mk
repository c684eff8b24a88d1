# The paper end to end on the shipped HDF-N cut (Massey et al. 2004; DESIGN §1): detect →
# decompose (galaxies and the PSF) → smooth → sample → render → measure → compare, into one
# folder with a report. `make reproduce` runs it after building the programs; by hand:
#
#   make -f pipelines/reproduce.mk [OUT=out/reproduce] [SEED=7] [AREA=6] [THREADS=2]
#
# Make reruns only what changed: a new SEED re-samples, re-renders and re-measures the
# simulations, and leaves detection, the fits and the morphology model alone. Parameters are
# prerequisites through small files in $(OUT)/params/ that change only when their value does.
# Every run appends to $(OUT)/pipeline.log: the date, the programs' version, the inputs'
# SHA-256, each command with the programs' own timing lines, and the total wall time.

SELF := $(lastword $(MAKEFILE_LIST))
OUT      ?= out/reproduce
include $(dir $(SELF))common.mk

EXAMPLES ?= $(R)build/examples
DATA     ?= $(R)share/data/hdfn
PAPER    ?= $(R)share/data/paper/massey2004_table.jsonl
SEED     ?= 7
# The larger simulation, arcmin² (the paper's 6).
AREA     ?= 6
THREADS  ?= 2
ZERO_POINT ?= 22.08
# Photon noise: electrons per DN/s, WFPC2's 7 e⁻/DN times the HDF's 123 600 s.
GAIN     ?= 865200
# Nothing fainter is measured: the paper compares galaxies brighter than I = 29.
MAG_LIMIT ?= 29

IMAGE     := $(DATA)/hdfn_f814w_v2.fits
WEIGHT    := $(DATA)/hdfn_f814w_v2_weight.fits
PSF_IMAGE := $(DATA)/wfpc2_f814w_tinytim_psf.fits
INPUTS    := $(IMAGE) $(WEIGHT) $(PSF_IMAGE) $(PAPER)

# The whole job, logged: this make runs the targets below in a sub-make and keeps the transcript.
.PHONY: all outputs
all:
	$(call logged_outputs,SEED=$(SEED) AREA=$(AREA))

# Parameters (common.mk).
value_seed := $(SEED)
value_area := $(AREA)

# Write a target through a temporary name, so a failed or killed step leaves nothing behind.
tmp = $@.tmp

# --- the real image ---------------------------------------------------------------------
$(OUT)/sources.jsonl $(OUT)/stamps.fits $(OUT)/stars.jsonl $(OUT)/hdf.noise.jsonl &: $(IMAGE) $(WEIGHT) $(call prog,detect)
	@mkdir -p $(OUT)
	$(call prog,detect) $(IMAGE) --weight $(WEIGHT) --zero-point $(ZERO_POINT) --gain $(GAIN) \
	  --stamps $(OUT)/stamps.fits --stars $(OUT)/stars.jsonl --noise-model $(OUT)/hdf.noise.jsonl \
	  > $(OUT)/sources.jsonl.tmp
	mv $(OUT)/sources.jsonl.tmp $(OUT)/sources.jsonl

$(OUT)/shapelets.jsonl $(OUT)/models.fits &: $(OUT)/sources.jsonl $(OUT)/stars.jsonl $(call prog,decompose)
	$(call prog,decompose) -j $(THREADS) --stars $(OUT)/stars.jsonl --models $(OUT)/models.fits \
	  < $(OUT)/sources.jsonl > $(OUT)/shapelets.jsonl.tmp
	mv $(OUT)/shapelets.jsonl.tmp $(OUT)/shapelets.jsonl

# TinyTim at 0.01″, boxed by the WFPC2 pixel and the drizzle drop, modelled at the HDF's scale.
$(OUT)/psf.jsonl: $(PSF_IMAGE) $(IMAGE) $(call prog,decompose)
	$(call prog,decompose) --psf-image $(PSF_IMAGE) --like $(IMAGE) --psf-box 0.0996 0.05 > $(tmp)
	mv $(tmp) $@

$(OUT)/morphology.json: $(OUT)/shapelets.jsonl $(IMAGE) $(call prog,smooth)
	$(call prog,smooth) --weight-left-out --like $(IMAGE) < $< > $(tmp)
	mv $(tmp) $@
$(OUT)/delta.json: $(OUT)/shapelets.jsonl $(IMAGE) $(call prog,smooth)
	$(call prog,smooth) --weight-left-out --delta --like $(IMAGE) < $< > $(tmp)
	mv $(tmp) $@

# --- the simulations: like the HDF cut (δ-function and full PDF), and AREA arcmin² ---------
$(OUT)/sim.objects.jsonl: $(OUT)/morphology.json $(IMAGE) $(OUT)/params/seed $(call prog,sample)
	$(call prog,sample) $< --like $(IMAGE) --seed $(SEED) > $(tmp)
	mv $(tmp) $@
$(OUT)/delta.objects.jsonl: $(OUT)/delta.json $(IMAGE) $(OUT)/params/seed $(call prog,sample)
	$(call prog,sample) $< --like $(IMAGE) --seed $(SEED) > $(tmp)
	mv $(tmp) $@
LARGE_FIELD = --area $(AREA) --pixel-scale 0.03985 --ra 189.2 --dec 62.21
$(OUT)/sim6.objects.jsonl: $(OUT)/morphology.json $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	$(call prog,sample) $< $(LARGE_FIELD) --seed $(SEED) > $(tmp)
	mv $(tmp) $@

# Galaxy models already hold the HDF's PSF (--galaxy-psf = --psf: no further convolution);
# the noise is the HDF sky's, measured by detect (rms and 2-D autocorrelation), plus photon
# noise; images the HDF's size vary its σ as the HDF's weight map does.
HDF_RENDER = $(call prog,render) --psf $(OUT)/psf.jsonl --galaxy-psf $(OUT)/psf.jsonl \
  --noise-model $(OUT)/hdf.noise.jsonl --gain $(GAIN) -j $(THREADS)
RENDER = $(HDF_RENDER) --seed $(SEED)
$(OUT)/sim.fits $(OUT)/sim.truth.jsonl &: $(OUT)/sim.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(RENDER) --like $(IMAGE) --noise-weight $(WEIGHT) -o $(OUT)/sim.fits --truth $(OUT)/sim.truth.jsonl < $<
$(OUT)/delta.fits $(OUT)/delta.truth.jsonl &: $(OUT)/delta.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(RENDER) --like $(IMAGE) --noise-weight $(WEIGHT) -o $(OUT)/delta.fits --truth $(OUT)/delta.truth.jsonl < $<
$(OUT)/sim6.fits $(OUT)/sim6.truth.jsonl &: $(OUT)/sim6.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(RENDER) $(LARGE_FIELD) -o $(OUT)/sim6.fits --truth $(OUT)/sim6.truth.jsonl < $<

# --- the merged run: every shipped F814W-like field, intrinsic models (issue 14 §2–4) -------
# Each field's galaxies are fitted through its own PSF (forward modelling): the HDF's TinyTim
# model, and for the XDF cutout (no PSF shipped, probably matched to F160W) a model of its
# bright star. One morphology model holds both, their counts combined where each is complete
# and each galaxy weighted by the area counted at its magnitude; shapes are drawn conditional
# on magnitude, and the 6 arcmin² field is rendered through the HDF's PSF and noise.
XDF_DATA   ?= $(R)share/data/xdf
XDF_IMAGE  := $(XDF_DATA)/f814w_sci.fits
XDF_WEIGHT := $(XDF_DATA)/f814w_wht.fits
XDF_ZERO_POINT ?= 25.959
# e⁻ per (e⁻/s): the F814W stack's exposure (share/data/xdf/README.md).
XDF_GAIN   ?= 50800
XDF_SCALE  := 0.06
XDF_STAR   := [87:145,352:410]
# arcmin²: (512 × 0.03985″)² and (500 × 0.06″)².
HDF_AREA   := 0.115643
XDF_AREA   := 0.25
# Shapes from the 32 parents nearest each drawn magnitude, moved by at most 3 mag (β as L^0.3):
# with magnitudes from the fitted counts, the few bright parents must reach the I < 24 draws.
# Each galaxy a mixture of MIX of them (shapesim-sample's default draw).
NEIGHBOURS ?= 32
MAX_MAG_SHIFT ?= 3
MIX ?= 3
INPUTS     += $(XDF_IMAGE) $(XDF_WEIGHT)

$(OUT)/xdf/psf.jsonl: $(XDF_IMAGE) $(call prog,decompose)
	@mkdir -p $(@D)
	$(call prog,decompose) --psf-image '$(XDF_IMAGE)$(XDF_STAR)' --psf-pixel-scale $(XDF_SCALE) \
	  --pixel-scale $(XDF_SCALE) > $(tmp)
	mv $(tmp) $@
$(OUT)/xdf/sources.jsonl $(OUT)/xdf/stamps.fits $(OUT)/xdf/stars.jsonl $(OUT)/xdf/real.noise.jsonl &: $(XDF_IMAGE) $(XDF_WEIGHT) $(OUT)/xdf/psf.jsonl $(call prog,detect)
	$(call prog,detect) $(XDF_IMAGE) --weight $(XDF_WEIGHT) --pixel-scale $(XDF_SCALE) \
	  --zero-point $(XDF_ZERO_POINT) --gain $(XDF_GAIN) --psf $(OUT)/xdf/psf.jsonl \
	  --stamps $(OUT)/xdf/stamps.fits --stars $(OUT)/xdf/stars.jsonl \
	  --noise-model $(OUT)/xdf/real.noise.jsonl > $(OUT)/xdf/sources.jsonl.tmp
	mv $(OUT)/xdf/sources.jsonl.tmp $(OUT)/xdf/sources.jsonl
$(OUT)/xdf/intrinsic.jsonl: $(OUT)/xdf/sources.jsonl $(OUT)/xdf/stars.jsonl $(OUT)/xdf/psf.jsonl $(call prog,decompose)
	$(call prog,decompose) -j $(THREADS) --psf $(OUT)/xdf/psf.jsonl --stars $(OUT)/xdf/stars.jsonl \
	  < $< > $(tmp)
	mv $(tmp) $@
$(OUT)/intrinsic.jsonl: $(OUT)/sources.jsonl $(OUT)/stars.jsonl $(OUT)/psf.jsonl $(call prog,decompose)
	$(call prog,decompose) -j $(THREADS) --psf $(OUT)/psf.jsonl --stars $(OUT)/stars.jsonl \
	  < $< > $(tmp)
	mv $(tmp) $@
# The COSMOS/AEGIS stamps (share/data/cosmos_aegis/README.md): isolated galaxies, each fitted
# through its own PSF; shape-only parents (a cutout has no area to count).
STAMP_DATA ?= $(R)share/data/cosmos_aegis
STAMP_ZERO_POINT ?= 25.94
# Stamp name → image[HDU], PSF image[HDU], gain (the exposure).
STAMPS := aegis1 aegis2 aegis3 aegis4 aegis5 cosmos
aegis_images = $(STAMP_DATA)/AEGIS_F814w_images_0$(1).fits
aegis_psfs   = $(STAMP_DATA)/AEGIS_F814w_PSF_images_0$(1).fits
stamp_file_aegis1 := $(call aegis_images,1)
stamp_hdu_aegis1 := [0]
stamp_file_aegis2 := $(call aegis_images,1)
stamp_hdu_aegis2 := [1]
stamp_file_aegis3 := $(call aegis_images,1)
stamp_hdu_aegis3 := [2]
stamp_file_aegis4 := $(call aegis_images,2)
stamp_hdu_aegis4 := [0]
stamp_file_aegis5 := $(call aegis_images,2)
stamp_hdu_aegis5 := [1]
stamp_file_cosmos := $(STAMP_DATA)/100610.img.fits
stamp_hdu_cosmos :=
$(foreach s,aegis1 aegis2 aegis3,$(eval stamp_psf_$(s) := $(call aegis_psfs,1)))
$(foreach s,aegis4 aegis5,$(eval stamp_psf_$(s) := $(call aegis_psfs,2)))
stamp_psf_cosmos := $(call aegis_psfs,1)
$(foreach s,aegis1 aegis2 aegis3 aegis4 aegis5,$(eval stamp_psf_hdu_$(s) := $(stamp_hdu_$(s))))
stamp_psf_hdu_cosmos := [0]
$(foreach s,aegis1 aegis2 aegis3 aegis4 aegis5,$(eval stamp_gain_$(s) := 2100))
stamp_gain_cosmos := 4056
stamp_image = $(stamp_file_$(1))$(stamp_hdu_$(1))
INPUTS += $(STAMP_DATA)/AEGIS_F814w_images_01.fits $(STAMP_DATA)/AEGIS_F814w_images_02.fits \
          $(STAMP_DATA)/AEGIS_F814w_PSF_images_01.fits $(STAMP_DATA)/AEGIS_F814w_PSF_images_02.fits \
          $(STAMP_DATA)/100610.img.fits

.SECONDEXPANSION:
.SECONDARY: $(STAMPS:%=$(OUT)/stamps/%.psf.jsonl)
$(OUT)/stamps/%.psf.jsonl: $$(stamp_psf_$$*) $(call prog,decompose)
	@mkdir -p $(@D)
	$(call prog,decompose) --psf-image '$(stamp_psf_$*)$(stamp_psf_hdu_$*)' --psf-pixel-scale 0.03 \
	  --pixel-scale 0.03 > $(tmp)
	mv $(tmp) $@
$(OUT)/stamps/%.jsonl: $(OUT)/stamps/%.psf.jsonl $$(stamp_file_$$*) $(call prog,detect) $(call prog,decompose)
	$(call prog,detect) '$(call stamp_image,$*)' --pixel-scale 0.03 --zero-point $(STAMP_ZERO_POINT) \
	  --gain $(stamp_gain_$*) --stamps $(OUT)/stamps/$*.fits > $(OUT)/stamps/$*.sources.jsonl
	$(call prog,decompose) --psf $< < $(OUT)/stamps/$*.sources.jsonl > $(tmp)
	mv $(tmp) $@

# The COSMOS catalogues (share/data/cosmos_catalog/README.md): 113 real ACS galaxies in
# GalSim's RealGalaxyCatalog layout, each fitted through its own PSF image; where a catalogue's
# PSF file is not shipped, through a stated real COSMOS PSF (COSMOS_PSF; flagged
# psf_substituted). Shape-only parents: most of the bright end's shapes.
COSMOS_DATA ?= $(R)share/data/cosmos_catalog
COSMOS_PSF  ?= $(COSMOS_DATA)/real_galaxy_PSF_images.fits[0]
COSMOS_SAMPLES := extension_26 sample_23.5_n1 bright_pair galsim_test_100533
cosmos_catalogue_extension_26 := $(COSMOS_DATA)/extension_26/real_galaxy_catalog_26_extension_example.fits
cosmos_catalogue_sample_23.5_n1 := $(COSMOS_DATA)/sample_23.5_n1/real_galaxy_catalog_23.5.fits
cosmos_catalogue_bright_pair := $(COSMOS_DATA)/bright_pair/real_galaxy_catalog_23.5.fits
cosmos_catalogue_galsim_test_100533 := $(COSMOS_DATA)/galsim_test_100533/real_galaxy_catalog_100533.fits
INPUTS += $(foreach c,$(COSMOS_SAMPLES),$(cosmos_catalogue_$(c)))
$(OUT)/cosmos/%.jsonl: $$(cosmos_catalogue_$$*) $(call prog,decompose)
	@mkdir -p $(@D)
	$(call prog,decompose) -j $(THREADS) --real-galaxy-catalog $< --real-galaxy-psf '$(COSMOS_PSF)' \
	  > $(tmp)
	mv $(tmp) $@

MERGED_INPUTS := $(OUT)/intrinsic.jsonl $(OUT)/xdf/intrinsic.jsonl $(STAMPS:%=$(OUT)/stamps/%.jsonl) \
  $(COSMOS_SAMPLES:%=$(OUT)/cosmos/%.jsonl)
$(OUT)/merged.json: $(MERGED_INPUTS) $(call prog,smooth)
	cat $(MERGED_INPUTS) | \
	  $(call prog,smooth) -v --weight-left-out --field $(IMAGE)=$(HDF_AREA) --field $(XDF_IMAGE)=$(XDF_AREA) \
	  $(foreach s,$(STAMPS),--field '$(call stamp_image,$(s))=shapes') \
	  $(foreach c,$(COSMOS_SAMPLES),--field '$(cosmos_catalogue_$(c))=shapes') > $(tmp)
	mv $(tmp) $@
MERGED_SAMPLE = $(call prog,sample) $(OUT)/merged.json $(LARGE_FIELD) --zero-point $(ZERO_POINT) \
  --neighbours $(NEIGHBOURS) --max-mag-shift $(MAX_MAG_SHIFT) --mix $(MIX)
$(OUT)/merged6.objects.jsonl: $(OUT)/merged.json $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	$(MERGED_SAMPLE) --seed $(SEED) > $(tmp)
	mv $(tmp) $@
# One seed's largest share is one Poisson draw: the merged model's shares over ten seeds from
# SEED on ("SEED I < 22: n/N from P; I < 24: …", sample's summary line), objects discarded.
$(OUT)/merged.shares.txt: $(OUT)/merged.json $(OUT)/params/seed $(OUT)/params/area $(call prog,sample)
	for s in $$(seq $(SEED) $$(($(SEED) + 9))); do \
	  $(MERGED_SAMPLE) --seed $$s 2>&1 >/dev/null | sed -n "s/.*among the galaxies written: /$$s /p"; \
	done > $(tmp)
	mv $(tmp) $@
$(OUT)/merged6.fits $(OUT)/merged6.truth.jsonl &: $(OUT)/merged6.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(call prog,render) --psf $(OUT)/psf.jsonl --noise-model $(OUT)/hdf.noise.jsonl --gain $(GAIN) \
	  --seed $(SEED) -j $(THREADS) $(LARGE_FIELD) -o $(OUT)/merged6.fits \
	  --truth $(OUT)/merged6.truth.jsonl < $<

# --- a field we did not tune on: the XDF cutout's δ-function simulation -------------------
# Its intrinsic models re-placed at its density, drawn through its star's PSF with its own
# sky (measured noise, weight map) and photon noise; measured and compared with the real
# cutout as the HDF is.
XDF_FIELD := --size 0.5 --pixel-scale $(XDF_SCALE)
$(OUT)/xdf/delta.json: $(OUT)/xdf/intrinsic.jsonl $(call prog,smooth)
	$(call prog,smooth) --weight-left-out --delta --area $(XDF_AREA) < $< > $(tmp)
	mv $(tmp) $@
$(OUT)/xdf/delta.objects.jsonl: $(OUT)/xdf/delta.json $(OUT)/params/seed $(call prog,sample)
	$(call prog,sample) $< $(XDF_FIELD) --seed $(SEED) > $(tmp)
	mv $(tmp) $@
XDF_RENDER = $(call prog,render) --psf $(OUT)/xdf/psf.jsonl --noise-model $(OUT)/xdf/real.noise.jsonl \
  --noise-weight $(XDF_WEIGHT) --gain $(XDF_GAIN) -j $(THREADS) $(XDF_FIELD)
$(OUT)/xdf/delta.fits $(OUT)/xdf/delta.truth.jsonl &: $(OUT)/xdf/delta.objects.jsonl $(OUT)/xdf/psf.jsonl $(OUT)/xdf/real.noise.jsonl $(XDF_WEIGHT) $(call prog,render)
	$(XDF_RENDER) --seed $(SEED) -o $(OUT)/xdf/delta.fits --truth $(OUT)/xdf/delta.truth.jsonl < $<
$(OUT)/xdf/delta.noise.jsonl: $(OUT)/xdf/delta.fits $(XDF_WEIGHT) $(call prog,detect)
	$(call prog,detect) $< --weight $(XDF_WEIGHT) --pixel-scale $(XDF_SCALE) --noise-model $(tmp) > /dev/null
	mv $(tmp) $@
$(OUT)/xdf/sky.md: $(OUT)/xdf/real.noise.jsonl $(OUT)/xdf/delta.noise.jsonl $(call prog,measure)
	$(call prog,measure) --compare-sky $(foreach c,real delta,$c=$(OUT)/xdf/$c.noise.jsonl) > $(tmp)
	mv $(tmp) $@
# The stellarity through the star's PSF model: the default 0.15″ Gaussian is too narrow at
# 0.06″ pixels and called the cutout's star a galaxy (stellarity 0), one more in the real row.
XDF_MEASURE = $(call prog,measure) --zero-point $(XDF_ZERO_POINT) --mag-limit $(MAG_LIMIT) -j $(THREADS) \
  --psf $(OUT)/xdf/psf.jsonl
$(OUT)/xdf/real.morph.jsonl: $(XDF_IMAGE) $(XDF_WEIGHT) $(OUT)/xdf/psf.jsonl $(call prog,measure)
	$(XDF_MEASURE) $(XDF_IMAGE) --weight $(XDF_WEIGHT) --pixel-scale $(XDF_SCALE) > $(tmp)
	mv $(tmp) $@
$(OUT)/xdf/delta.morph.jsonl: $(OUT)/xdf/delta.fits $(OUT)/xdf/psf.jsonl $(XDF_WEIGHT) $(call prog,measure)
	$(XDF_MEASURE) $< --weight $(XDF_WEIGHT) > $(tmp)
	mv $(tmp) $@
$(OUT)/xdf/table.md: $(OUT)/xdf/real.morph.jsonl $(OUT)/xdf/delta.morph.jsonl $(call prog,measure)
	$(call prog,measure) --compare $(foreach c,real delta,xdf_$c=$(OUT)/xdf/$c.morph.jsonl) \
	  -o $(OUT)/xdf/compare
	cp $(OUT)/xdf/compare/table.md $@

# --- the δ-function simulations at five seeds ---------------------------------------------
# One seed's KS p is one draw (of the bootstrap and the noise): the HDF's and the XDF's δ
# simulations at SEED … SEED + 4, drawn, rendered and measured as above, each compared with its
# real image in one --compare (seeds/hdf/distances.md, seeds/xdf/distances.md) and summed up
# in seeds.md by pipelines/seeds.sh.
SEEDS := $(shell seq $(SEED) $$(($(SEED) + 4)))
$(OUT)/seeds/hdf_%.objects.jsonl: $(OUT)/delta.json $(IMAGE) $(call prog,sample)
	@mkdir -p $(@D)
	$(call prog,sample) -q $< --like $(IMAGE) --seed $* > $(tmp)
	mv $(tmp) $@
$(OUT)/seeds/hdf_%.fits: $(OUT)/seeds/hdf_%.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(HDF_RENDER) -q --seed $* --like $(IMAGE) --noise-weight $(WEIGHT) -o $@ < $<
$(OUT)/seeds/hdf_%.morph.jsonl: $(OUT)/seeds/hdf_%.fits $(WEIGHT) $(call prog,measure)
	$(MEASURE) -q $< --weight $(WEIGHT) > $(tmp)
	mv $(tmp) $@
$(OUT)/seeds/xdf_%.objects.jsonl: $(OUT)/xdf/delta.json $(call prog,sample)
	@mkdir -p $(@D)
	$(call prog,sample) -q $< $(XDF_FIELD) --seed $* > $(tmp)
	mv $(tmp) $@
$(OUT)/seeds/xdf_%.fits: $(OUT)/seeds/xdf_%.objects.jsonl $(OUT)/xdf/psf.jsonl $(OUT)/xdf/real.noise.jsonl $(XDF_WEIGHT) $(call prog,render)
	$(XDF_RENDER) -q --seed $* -o $@ < $<
$(OUT)/seeds/xdf_%.morph.jsonl: $(OUT)/seeds/xdf_%.fits $(OUT)/xdf/psf.jsonl $(XDF_WEIGHT) $(call prog,measure)
	$(XDF_MEASURE) -q $< --weight $(XDF_WEIGHT) > $(tmp)
	mv $(tmp) $@
SEED_FILES := $(foreach f,hdf xdf,$(foreach s,$(SEEDS),$(foreach e,objects.jsonl fits morph.jsonl,$(OUT)/seeds/$(f)_$(s).$(e))))
# The five seeds pooled ("pooled": one catalogue of them all) are compared too.
$(OUT)/seeds.md: $(R)pipelines/seeds.sh $(SEED_FILES) $(OUT)/hdf.morph.jsonl $(OUT)/xdf/real.morph.jsonl $(call prog,measure)
	cat $(foreach s,$(SEEDS),$(OUT)/seeds/hdf_$(s).morph.jsonl) > $(OUT)/seeds/hdf_pooled.morph.jsonl
	cat $(foreach s,$(SEEDS),$(OUT)/seeds/xdf_$(s).morph.jsonl) > $(OUT)/seeds/xdf_pooled.morph.jsonl
	$(call prog,measure) -q --compare hdf=$(OUT)/hdf.morph.jsonl \
	  $(foreach s,$(SEEDS) pooled,delta$(s)=$(OUT)/seeds/hdf_$(s).morph.jsonl) -o $(OUT)/seeds/hdf
	$(call prog,measure) -q --compare xdf=$(OUT)/xdf/real.morph.jsonl \
	  $(foreach s,$(SEEDS) pooled,delta$(s)=$(OUT)/seeds/xdf_$(s).morph.jsonl) -o $(OUT)/seeds/xdf
	$(R)pipelines/seeds.sh $(OUT)/seeds/hdf $(OUT)/seeds/xdf > $(tmp)
	mv $(tmp) $@

# The five seeds' skies, each measured as its real field's is (its own detection, the field's
# weight map), against the real sky (shapesim-measure --compare-sky), and the seeds' mean of
# each ratio (seeds/sky.md).
$(OUT)/seeds/hdf_%.noise.jsonl: $(OUT)/seeds/hdf_%.fits $(WEIGHT) $(call prog,detect)
	$(call prog,detect) -q $< --weight $(WEIGHT) --noise-model $(tmp) > /dev/null
	mv $(tmp) $@
$(OUT)/seeds/xdf_%.noise.jsonl: $(OUT)/seeds/xdf_%.fits $(XDF_WEIGHT) $(call prog,detect)
	$(call prog,detect) -q $< --weight $(XDF_WEIGHT) --pixel-scale $(XDF_SCALE) --noise-model $(tmp) > /dev/null
	mv $(tmp) $@
SKY_MEAN = awk -F'|' '{ print } NR > 3 && NF > 20 { n++; for (c = 13; c <= 18; c++) sum[c] += $$c } \
  END { printf "| mean of the seeds | – | – | – | – | – | – | – | – | – | – |"; \
        for (c = 13; c <= 18; c++) printf " %.4f |", sum[c] / n; print " – | – | – |" }'
$(OUT)/seeds/sky.md: $(foreach f,hdf xdf,$(SEEDS:%=$(OUT)/seeds/$(f)_%.noise.jsonl)) $(OUT)/hdf.noise.jsonl $(OUT)/xdf/real.noise.jsonl $(call prog,measure)
	$(call prog,measure) -q --compare-sky hdf=$(OUT)/hdf.noise.jsonl \
	  $(foreach s,$(SEEDS),seed$(s)=$(OUT)/seeds/hdf_$(s).noise.jsonl) | $(SKY_MEAN) > $(tmp)
	echo >> $(tmp)
	$(call prog,measure) -q --compare-sky xdf=$(OUT)/xdf/real.noise.jsonl \
	  $(foreach s,$(SEEDS),seed$(s)=$(OUT)/seeds/xdf_$(s).noise.jsonl) | $(SKY_MEAN) >> $(tmp)
	mv $(tmp) $@

# --- the models where they were: every real galaxy paired with its own fit ---------------
# Each field's fits replayed where they were fitted (shapesim-sample --replay: no draw), at the
# five seeds rendered and measured as its δ simulations are, then paired galaxy by galaxy with
# the real catalogue (shapesim-measure --compare-paired): the models' fidelity, before any draw.
$(OUT)/replays/hdf.objects.jsonl: $(OUT)/shapelets.jsonl $(IMAGE) $(call prog,sample)
	@mkdir -p $(@D)
	$(call prog,sample) -q --replay $< --like $(IMAGE) > $(tmp)
	mv $(tmp) $@
$(OUT)/replays/hdf_%.fits: $(OUT)/replays/hdf.objects.jsonl $(OUT)/psf.jsonl $(OUT)/hdf.noise.jsonl $(call prog,render)
	$(HDF_RENDER) -q --seed $* --like $(IMAGE) --noise-weight $(WEIGHT) -o $@ < $<
$(OUT)/replays/hdf_%.morph.jsonl: $(OUT)/replays/hdf_%.fits $(WEIGHT) $(call prog,measure)
	$(MEASURE) -q $< --weight $(WEIGHT) > $(tmp)
	mv $(tmp) $@
$(OUT)/replays/xdf.objects.jsonl: $(OUT)/xdf/intrinsic.jsonl $(call prog,sample)
	@mkdir -p $(@D)
	$(call prog,sample) -q --replay $< $(XDF_FIELD) > $(tmp)
	mv $(tmp) $@
$(OUT)/replays/xdf_%.fits: $(OUT)/replays/xdf.objects.jsonl $(OUT)/xdf/psf.jsonl $(OUT)/xdf/real.noise.jsonl $(XDF_WEIGHT) $(call prog,render)
	$(XDF_RENDER) -q --seed $* -o $@ < $<
$(OUT)/replays/xdf_%.morph.jsonl: $(OUT)/replays/xdf_%.fits $(OUT)/xdf/psf.jsonl $(XDF_WEIGHT) $(call prog,measure)
	$(XDF_MEASURE) -q $< --weight $(XDF_WEIGHT) > $(tmp)
	mv $(tmp) $@
$(OUT)/replays/hdf.md: $(foreach s,$(SEEDS),$(OUT)/replays/hdf_$(s).morph.jsonl) $(OUT)/hdf.morph.jsonl $(call prog,measure)
	$(call prog,measure) --compare-paired hdf=$(OUT)/hdf.morph.jsonl \
	  $(foreach s,$(SEEDS),replay$(s)=$(OUT)/replays/hdf_$(s).morph.jsonl) > $(tmp)
	mv $(tmp) $@
$(OUT)/replays/xdf.md: $(foreach s,$(SEEDS),$(OUT)/replays/xdf_$(s).morph.jsonl) $(OUT)/xdf/real.morph.jsonl $(call prog,measure)
	$(call prog,measure) --compare-paired xdf=$(OUT)/xdf/real.morph.jsonl \
	  $(foreach s,$(SEEDS),replay$(s)=$(OUT)/replays/xdf_$(s).morph.jsonl) > $(tmp)
	mv $(tmp) $@

# --- measure all four images alike, and compare -----------------------------------------
MEASURE = $(call prog,measure) --zero-point $(ZERO_POINT) --mag-limit $(MAG_LIMIT) -j $(THREADS)
$(OUT)/hdf.morph.jsonl: $(IMAGE) $(WEIGHT) $(call prog,measure)
	$(MEASURE) $(IMAGE) --weight $(WEIGHT) > $(tmp)
	mv $(tmp) $@
# The simulations of the HDF's own field carry its weight map's noise: measured with it, as the
# HDF is (issue 36 §2: without it the δ image's FWHM median read 0.456″ against 0.424″ with it).
$(OUT)/delta.morph.jsonl $(OUT)/sim.morph.jsonl: $(OUT)/%.morph.jsonl: $(OUT)/%.fits $(WEIGHT) $(call prog,measure)
	$(MEASURE) $< --weight $(WEIGHT) > $(tmp)
	mv $(tmp) $@
$(OUT)/%.morph.jsonl: $(OUT)/%.fits $(call prog,measure)
	$(MEASURE) $< > $(tmp)
	mv $(tmp) $@

# The skies, objects masked alike: each image's own detection (the HDF's weight map for the
# simulations of its field), its sky noise measured as detect measures the real one.
$(OUT)/delta.noise.jsonl $(OUT)/sim.noise.jsonl: $(OUT)/%.noise.jsonl: $(OUT)/%.fits $(WEIGHT) $(call prog,detect)
	$(call prog,detect) $< --weight $(WEIGHT) --noise-model $(tmp) > /dev/null
	mv $(tmp) $@
$(OUT)/sky.md: $(OUT)/hdf.noise.jsonl $(OUT)/delta.noise.jsonl $(OUT)/sim.noise.jsonl $(call prog,measure)
	$(call prog,measure) --compare-sky $(foreach c,hdf delta sim,$c=$(OUT)/$c.noise.jsonl) > $(tmp)
	mv $(tmp) $@

CATALOGUES := hdf delta sim sim6 merged6
$(OUT)/table.md: $(CATALOGUES:%=$(OUT)/%.morph.jsonl) $(PAPER) $(call prog,measure)
	$(call prog,measure) --compare $(foreach c,$(CATALOGUES),$c=$(OUT)/$c.morph.jsonl) \
	  --paper $(PAPER) -o $(OUT)/compare
	cp $(OUT)/compare/table.md $@

# --- figures and the report -------------------------------------------------------------
# HDF | δ | full simulation at one scale and stretch; the large simulation scaled to 1200 px.
$(OUT)/figures/hdf_delta_sim.png: $(IMAGE) $(OUT)/delta.fits $(OUT)/sim.fits $(EXAMPLES)/panels
	@mkdir -p $(@D)
	$(EXAMPLES)/panels $(@:.png=.pgm) $(IMAGE) $(OUT)/delta.fits $(OUT)/sim.fits
	pnmtopng $(@:.png=.pgm) > $(tmp) && rm $(@:.png=.pgm) && mv $(tmp) $@
$(OUT)/figures/sim6.png: $(OUT)/sim6.fits $(EXAMPLES)/panels
	@mkdir -p $(@D)
	$(EXAMPLES)/panels $(@:.png=.pgm) $<
	pnmscale -xsize 1200 $(@:.png=.pgm) | pnmtopng > $(tmp) && rm $(@:.png=.pgm) && mv $(tmp) $@
# The real HDF cut | the full simulation (merged6, the product: every galaxy new): the field's
# first 512² (any AREA holds it), at the HDF's scale and stretch (README's figure).
$(OUT)/figures/hdf_merged.png: $(IMAGE) $(OUT)/merged6.fits $(EXAMPLES)/panels
	@mkdir -p $(@D)
	$(EXAMPLES)/panels $(@:.png=.pgm) $(IMAGE) '$(OUT)/merged6.fits[1:512,1:512]'
	pnmtopng $(@:.png=.pgm) > $(tmp) && rm $(@:.png=.pgm) && mv $(tmp) $@
# The paper's Fig. 3 and its negative-flux diagnostic (a fixed seed of its own).
$(OUT)/figures/perturbations.png $(OUT)/perturbations.md &: $(OUT)/morphology.json $(EXAMPLES)/perturbations
	@mkdir -p $(OUT)/figures
	$(EXAMPLES)/perturbations $< $(OUT)/figures/perturbations.pgm 2000 > $(OUT)/perturbations.md.tmp
	pnmtopng $(OUT)/figures/perturbations.pgm > $(OUT)/figures/perturbations.png.tmp
	rm $(OUT)/figures/perturbations.pgm
	mv $(OUT)/figures/perturbations.png.tmp $(OUT)/figures/perturbations.png
	mv $(OUT)/perturbations.md.tmp $(OUT)/perturbations.md

# The brightest galaxy of each shipped field (HDF, XDF, the AEGIS cutouts, COSMOS) fitted
# intrinsically, as in the merged run: data | model (through its PSF) | residual, one row each.
BRIGHTEST_ROWS := hdf xdf aegis cosmos
BRIGHTEST := $(R)pipelines/brightest.py
$(OUT)/figures/brightest.png: $(OUT)/sources.jsonl $(OUT)/xdf/sources.jsonl $(STAMPS:%=$(OUT)/stamps/%.jsonl) \
    $(STAMPS:%=$(OUT)/stamps/%.psf.jsonl) $(OUT)/psf.jsonl $(OUT)/xdf/psf.jsonl $(BRIGHTEST) \
    $(call prog,decompose) $(EXAMPLES)/montage
	@mkdir -p $(OUT)/figures/brightest
	for row in $(BRIGHTEST_ROWS); do \
	  case $$row in \
	    hdf) set -- $$($(BRIGHTEST) $(OUT)/sources.jsonl); psf=$(OUT)/psf.jsonl; stars="--stars $(OUT)/stars.jsonl";; \
	    xdf) set -- $$($(BRIGHTEST) $(OUT)/xdf/sources.jsonl); psf=$(OUT)/xdf/psf.jsonl; stars="--stars $(OUT)/xdf/stars.jsonl";; \
	    aegis) set -- $$($(BRIGHTEST) $(filter-out %cosmos.sources.jsonl,$(STAMPS:%=$(OUT)/stamps/%.sources.jsonl))); \
	       psf=$${1%.sources.jsonl}.psf.jsonl; stars=;; \
	    cosmos) set -- $$($(BRIGHTEST) $(OUT)/stamps/cosmos.sources.jsonl); psf=$(OUT)/stamps/cosmos.psf.jsonl; stars=;; \
	  esac; \
	  grep "\"id\":\"$$2\"" $$1 | $(call prog,decompose) -q --psf $$psf $$stars \
	    --models $(OUT)/figures/brightest/$$row.fits > $(OUT)/figures/brightest/$$row.jsonl; \
	  $(EXAMPLES)/montage $(OUT)/figures/brightest/$$row.fits $$2 $(OUT)/figures/brightest/$$row.pgm \
	    $$( [ $$row = xdf ] && echo 1 || echo 2); \
	done
	pnmcat -tb -jleft -black $(BRIGHTEST_ROWS:%=$(OUT)/figures/brightest/%.pgm) | pnmtopng > $(tmp)
	rm $(BRIGHTEST_ROWS:%=$(OUT)/figures/brightest/%.pgm)
	mv $(tmp) $@

FIGURES := $(OUT)/figures/hdf_delta_sim.png $(OUT)/figures/hdf_merged.png $(OUT)/figures/sim6.png \
           $(OUT)/figures/perturbations.png \
           $(OUT)/figures/brightest.png
$(OUT)/report.md: $(R)pipelines/report.sh $(OUT)/table.md $(OUT)/sky.md $(OUT)/morphology.json $(OUT)/perturbations.md \
    $(OUT)/xdf/table.md $(OUT)/xdf/sky.md \
    $(FIGURES) $(INPUTS) $(OUT)/sim.truth.jsonl $(OUT)/delta.truth.jsonl $(OUT)/sim6.truth.jsonl \
    $(OUT)/merged.json $(OUT)/merged6.objects.jsonl $(OUT)/sim6.objects.jsonl $(OUT)/merged.shares.txt \
    $(OUT)/seeds.md $(OUT)/seeds/sky.md $(OUT)/replays/hdf.md $(OUT)/replays/xdf.md
	$(R)pipelines/report.sh $(OUT) $(INPUTS) > $(tmp)
	mv $(tmp) $@

outputs: $(OUT)/report.md
