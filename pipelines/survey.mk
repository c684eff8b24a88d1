# A survey of any size as a grid of tiles (DESIGN §6). Each tile is one make target: sample the
# objects whose stamps reach the tile, render the tile (and, with MEASURE=1, measure it). Tiles
# are independent, so `make -j N` runs N at once, and pipelines/slurm-survey.sh runs the same
# targets as a Slurm array job. A tile's bytes depend only on the field, the seed and its window:
# a rerun, a killed-and-rerun tile or a tile run on another machine is bit-identical, and the
# tiles' mosaic equals the whole field rendered at once.
#
#   make -f pipelines/survey.mk -j 2 FIELD='--area 1' TILE=1024 SEED=1 OUT=out/survey
#
# Outputs in $(OUT): tiles/tile-IX-IY.fits (+ .truth.jsonl, .log; .morph.jsonl with MEASURE=1),
# truth.jsonl (every object once, by the tile holding its centre, tiles in index order),
# index.jsonl (one shapesim.tile/1 line per tile: window, files, object count, SHA-256) and,
# with MEASURE=1, measured.jsonl. The defaults draw from what `make reproduce` made.

SELF := $(lastword $(MAKEFILE_LIST))
.SECONDEXPANSION:

OUT      ?= out/survey
include $(dir $(SELF))common.mk

MODEL    ?= out/reproduce/morphology.json
PSF      ?= out/reproduce/psf.jsonl
# The PSF the galaxy models already hold (the real image's): none more is applied when equal.
GALAXY_PSF ?= $(PSF)
# The field, as shapesim-sample and shapesim-render take it (--like IMAGE, --area, --size ...).
FIELD    ?= --area 1 --pixel-scale 0.03985
# Tile side, pixels ("W H" for rectangles).
TILE     ?= 1024
SEED     ?= 1
NOISE    ?= --noise-model out/reproduce/hdf.noise.jsonl --gain 865200
SAMPLE_OPTIONS ?=
RENDER_OPTIONS ?=
# Threads per tile job (tiles themselves run in parallel under make -j or Slurm).
THREADS  ?= 1
MEASURE  ?=
ZERO_POINT ?= 22.08
MAG_LIMIT  ?= 29

SAMPLE = $(call prog,sample) $(MODEL) $(FIELD) --seed $(SEED) $(SAMPLE_OPTIONS)
RENDER = $(call prog,render) --psf $(PSF) --galaxy-psf $(GALAXY_PSF) $(FIELD) $(NOISE) \
  --seed $(SEED) -j $(THREADS) $(RENDER_OPTIONS)

# Parameters (common.mk): a new seed redraws every tile, a new field re-plans the grid.
value_grid := $(FIELD) | $(TILE)
value_draw := $(SEED) | $(SAMPLE_OPTIONS) | $(NOISE) | $(RENDER_OPTIONS)

# The plan: one 'IX IY X0 Y0 X1 Y1' line per tile, and the make variables made from it.
$(OUT)/tiles.txt: $(OUT)/params/grid $(call prog,sample)
	$(call prog,sample) $(FIELD) --tile-grid $(TILE) > $@.tmp
	mv $@.tmp $@
$(OUT)/tiles.mk: $(OUT)/tiles.txt
	awk '{ name = sprintf("tile-%03d-%03d", $$1, $$2); \
	       print "TILES += " name; print "TASK_" NR - 1 " := " name; \
	       print "WINDOW_" name " := " $$3 " " $$4 " " $$5 " " $$6 }' $< > $@.tmp
	mv $@.tmp $@
ifeq ($(filter clean print-%,$(MAKECMDGOALS)),)
include $(OUT)/tiles.mk
endif

.PHONY: all plan tiles clean
plan: $(OUT)/tiles.mk $(OUT)/params/draw
tiles: $(TILES:%=$(OUT)/tiles/%.fits) $(if $(MEASURE),$(TILES:%=$(OUT)/tiles/%.morph.jsonl))
# task-K: the K-th tile (from 0), for array jobs.
task-%: $(OUT)/tiles/$$(TASK_$$*).fits $(if $(MEASURE),$(OUT)/tiles/$$(TASK_$$*).morph.jsonl) ;

# One tile. The objects go through a file, not a pipe: a sample killed mid-stream must not
# leave render a short list that looks whole. render writes both outputs atomically.
$(OUT)/tiles/%.fits $(OUT)/tiles/%.truth.jsonl: $(MODEL) $(PSF) $(GALAXY_PSF) $(OUT)/tiles.txt \
    $(OUT)/params/draw $(call prog,sample) $(call prog,render)
	@mkdir -p $(@D)
	$(SAMPLE) -q --tile $(WINDOW_$*) > $(OUT)/tiles/$*.objects.tmp
	$(RENDER) --tile $(WINDOW_$*) -o $(OUT)/tiles/$*.fits --truth $(OUT)/tiles/$*.truth.jsonl \
	  < $(OUT)/tiles/$*.objects.tmp 2>&1 | tee $(OUT)/tiles/$*.log
	rm $(OUT)/tiles/$*.objects.tmp

$(OUT)/tiles/%.morph.jsonl: $(OUT)/tiles/%.fits $(call prog,measure)
	$(call prog,measure) $< --zero-point $(ZERO_POINT) --mag-limit $(MAG_LIMIT) -j $(THREADS) > $@.tmp
	mv $@.tmp $@

# The merge: the tiles' truths in index order, the index with every tile's SHA-256.
$(OUT)/truth.jsonl $(OUT)/index.jsonl &: $(TILES:%=$(OUT)/tiles/%.fits) $(OUT)/tiles.txt
	cat $(TILES:%=$(OUT)/tiles/%.truth.jsonl) > $(OUT)/truth.jsonl.tmp
	while read -r ix iy x0 y0 x1 y1; do \
	  name=$$(printf 'tile-%03d-%03d' "$$ix" "$$iy"); \
	  printf '{"schema":"shapesim.tile/1","tile":"%s","ix":%d,"iy":%d,"x0":%d,"y0":%d,"x1":%d,"y1":%d,"image":"tiles/%s.fits","truth":"tiles/%s.truth.jsonl","objects":%d,"sha256":"%s"}\n' \
	    "$$name" "$$ix" "$$iy" "$$x0" "$$y0" "$$x1" "$$y1" "$$name" "$$name" \
	    "$$(wc -l < $(OUT)/tiles/$$name.truth.jsonl)" "$$(sha256sum < $(OUT)/tiles/$$name.fits | cut -d' ' -f1)"; \
	done < $(OUT)/tiles.txt > $(OUT)/index.jsonl.tmp
	mv $(OUT)/truth.jsonl.tmp $(OUT)/truth.jsonl
	mv $(OUT)/index.jsonl.tmp $(OUT)/index.jsonl
	@echo "survey: $(words $(TILES)) tiles, $$(wc -l < $(OUT)/truth.jsonl) objects in $(OUT)/truth.jsonl"

# Measured catalogues: ids prefixed by the tile (each tile numbers its own detections); x, y
# are the tile's pixels, ra, dec the sky's. Objects cut by a tile edge carry the flag "edge".
$(OUT)/measured.jsonl: $(TILES:%=$(OUT)/tiles/%.morph.jsonl)
	for name in $(TILES); do sed "s/\"id\":\"/\"id\":\"$$name:/" $(OUT)/tiles/$$name.morph.jsonl; done > $@.tmp
	mv $@.tmp $@

all: $(OUT)/truth.jsonl $(OUT)/index.jsonl $(if $(MEASURE),$(OUT)/measured.jsonl)

print-%:
	@echo '$($*)'
clean:
	rm -rf $(OUT)
