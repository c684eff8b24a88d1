#!/usr/bin/env bash
# Catalogue mode: GalSim's RealGalaxyCatalog. The shipped AEGIS table (five galaxies, their
# stamps and PSF images) fitted through each galaxy's own PSF: intrinsic models, the
# catalogue's magnitudes, the same bytes on one thread or two and in batches of two; the
# COSMOS example table, whose stamps are not shipped, refused at its first row with nothing
# written; a catalogue without its PSF file refused, or fitted through a stated one
# (--real-galaxy-psf); catalogue mode with --psf refused.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
data=$(cd ../../../share/data && pwd)
cd "$TMPDIR"
aegis=$data/cosmos_aegis/AEGIS_F814w_catalog.fits
"$BIN/shapesim-decompose" --real-galaxy-catalog "$aegis" --gain 2100 -j 2 -q >a.jsonl ||
  fail "catalogue mode failed"
[ "$(wc -l <a.jsonl)" -eq 5 ] || fail "expected 5 models, got $(wc -l <a.jsonl)"
[ "$(grep -c '"frame":"intrinsic"' a.jsonl)" -eq 5 ] || fail "not every model is intrinsic"
for want in '"id":"23409"' '"id":"24216"' '"mag":22.0027' '"mag":24.7407' "\"image\":\"$aegis\""; do
  grep -q "$want" a.jsonl || fail "no $want in the models"
done
# The PSF models reach the 1% residual target; every galaxy converges.
[ "$(grep -c '"converged"' a.jsonl)" -eq 5 ] || fail "not every fit converged: $(grep -o '"flags":[^]]*]' a.jsonl)"
grep -q psf_residual_above_target a.jsonl && fail "a PSF model missed its residual target"
"$BIN/shapesim-decompose" --real-galaxy-catalog "$aegis" --gain 2100 -j 1 --batch 2 -q >b.jsonl ||
  fail "catalogue mode, one thread, batches of two, failed"
cmp -s a.jsonl b.jsonl || fail "the models depend on the threads or the batch"
# Models smooth takes as they are (with a field: --field CATALOGUE=shapes, shape-only).
"$BIN/shapesim-smooth" <a.jsonl >m.json 2>smooth.err ||
  fail "smooth refused the catalogue's models: $(cat smooth.err)"

# The COSMOS example: its stamps are not shipped. One line naming the row and the file,
# exit 1, no output file.
rc=0
"$BIN/shapesim-decompose" --real-galaxy-catalog "$data/cosmos_catalog/real_galaxy_catalog_23.5_example.fits" \
  -q -o cosmos.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 "real_galaxy_catalog_23.5_example.fits:1: GAL_FILENAME: .*real_galaxy_images.fits\[0\]: cannot open"
[ ! -e cosmos.jsonl ] || fail "a refused catalogue left cosmos.jsonl behind"
# A catalogue whose PSF file is not shipped (the bright pair of the COSMOS I < 23.5 sample):
# refused naming the row and file; with --real-galaxy-psf, fitted through that stated PSF, every
# record flagged psf_substituted and naming it, and a warning that says how many.
pair=$data/cosmos_catalog/bright_pair/real_galaxy_catalog_23.5.fits
psf="$data/cosmos_catalog/real_galaxy_PSF_images.fits[0]"
rc=0
"$BIN/shapesim-decompose" --real-galaxy-catalog "$pair" -q -o pair.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 "real_galaxy_catalog_23.5.fits:1: PSF_FILENAME: .*real_galaxy_PSF_images_23.5_n4.fits\[532\]: no such file .*give one with --real-galaxy-psf"
[ ! -e pair.jsonl ] || fail "a refused catalogue left pair.jsonl behind"
"$BIN/shapesim-decompose" --real-galaxy-catalog "$pair" --real-galaxy-psf "$psf" -j 2 >pair.jsonl 2>err ||
  fail "--real-galaxy-psf failed: $(cat err)"
grep -q "warning: 2 of 2 galaxies' PSF files are absent (first: 97475): fitted through --real-galaxy-psf .*real_galaxy_PSF_images.fits\[0\]" err ||
  fail "no warning of the substituted PSF: $(cat err)"
[ "$(grep -c '"psf_substituted"' pair.jsonl)" -eq 2 ] && [ "$(grep -c '"psf_image":"[^"]*real_galaxy_PSF_images.fits\[0\]"' pair.jsonl)" -eq 2 ] ||
  fail "the substituted PSF is not on the records: $(head -c 400 pair.jsonl)"
# A catalogue with its PSFs keeps them: nothing substituted.
"$BIN/shapesim-decompose" --real-galaxy-catalog "$aegis" --gain 2100 --real-galaxy-psf "$psf" -j 2 -q >c.jsonl ||
  fail "--real-galaxy-psf with every PSF present failed"
cmp -s a.jsonl c.jsonl || fail "--real-galaxy-psf changed a catalogue whose PSFs are all there"
rc=0
"$BIN/shapesim-decompose" --real-galaxy-psf "$psf" <a.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "need --real-galaxy-catalog"
rc=0
"$BIN/shapesim-decompose" --real-galaxy-catalog "$aegis" --psf a.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "no --psf or --stamps with it"
rc=0
"$BIN/shapesim-decompose" --real-galaxy-catalog "$data/hdfn/hdfn_f814w_v2.fits" -q >out 2>err || rc=$?
expect_error "$rc" 1 "no table in the file"
exit 0
