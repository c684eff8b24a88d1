#!/usr/bin/env bash
# Every rendered FITS says how it was made (issue 15): the image HDU is EXTNAME SCI, with the
# BUNIT of its --like image and its WCS's RADESYS; the primary HDU holds the run's options as
# HIERARCH OPTION cards; -j and the output's own path are not among them, so a run on two
# threads into another folder writes the same bytes. A short option name never lands on a
# FITS keyword (--bitpix on BITPIX).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_morphology
"$BIN/shapesim-sample" -q morph.json --like "$HDF_IMAGE" --seed 3 >objects.jsonl || fail "sample failed"
mkdir a b
"$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-rms 2e-5 --seed 3 -j 1 --bitpix -32 \
  -o a/sim.fits --truth a/truth.jsonl <objects.jsonl || fail "render -j 1 failed"
"$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-rms 2e-5 --seed 3 -j 2 --bitpix -32 \
  -o b/sim.fits --truth b/truth.jsonl <objects.jsonl || fail "render -j 2 failed"
cmp a/sim.fits b/sim.fits || fail "-j 2 into another folder changed the bytes"
header=$(python3 "$tools/fitsdata.py" a/sim.fits header)
grep -qx 'EXTNAME=SCI' <<<"$header" || fail "no EXTNAME SCI"
grep -qx 'RADESYS=ICRS' <<<"$header" || fail "no RADESYS"
primary=$(head -c 8640 a/sim.fits | fold -w 80)
grep -q "^BITPIX  =                    8" <<<"$primary" || fail "the primary BITPIX was overwritten"
grep -q "^HIERARCH OPTION SEED = '3 *'" <<<"$primary" || fail "no OPTION SEED card"
grep -q "^HIERARCH OPTION LIKE = '/" <<<"$primary" || fail "no OPTION LIKE card"
grep -q "HIERARCH OPTION \(OUTPUT\|THREADS\|TRUTH\)" <<<"$primary" && fail "outputs or -j among the options"
# A field made --like an image keeps its BUNIT (the COSMOS stamp's ELECTRONS); the HDF has none.
grep -q '^BUNIT=' <<<"$header" && fail "BUNIT invented for a --like image without one"
cosmos=$HDF_DATA/../cosmos_aegis/100610.img.fits
"$BIN/shapesim-render" -q --like "$cosmos" --noise-rms 1 --seed 3 -o cosmos.fits </dev/null ||
  fail "render --like the COSMOS stamp failed"
python3 "$tools/fitsdata.py" cosmos.fits header | grep -x 'BUNIT=ELECTRONS' >/dev/null || fail "BUNIT not kept"
exit 0
