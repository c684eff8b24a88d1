#!/usr/bin/env bash
# shapesim-render on objects sampled from the HDF morphology: a FITS image of the --like
# geometry whose WCS is the HDF's, a truth line per drawn object; a 2×2 mosaic of --tile images
# equals the whole image pixel for pixel (noise included), and so do -j 1 and -j 2; a noise-
# free image holds the drawn flux; bad input fails with one line and no file.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-render
data=$(cd ../../../share/data/hdfn && pwd)
tools=$(cd ../tools && pwd)
hdf=$data/hdfn_f814w_v2.fits

cd "$TMPDIR"
hdf_models
"$BIN/shapesim-decompose" -q --psf-image "$data/wfpc2_f814w_tinytim_psf.fits" --like "$hdf" \
  --psf-box 0.0996 0.05 >psf.jsonl || fail "decompose --psf-image failed"
"$BIN/shapesim-smooth" -q <shapelets.jsonl >morph.json || fail "shapesim-smooth failed"
"$BIN/shapesim-sample" morph.json --like "$hdf" --seed 5 --star-count 3 -q >objects.jsonl ||
  fail "sample failed"

common=(--psf psf.jsonl --galaxy-psf psf.jsonl --like "$hdf" --noise-like sources.jsonl
        --gain 865200 --seed 5)
"$BIN/$prog" "${common[@]}" -o sim.fits --truth truth.jsonl <objects.jsonl 2>err ||
  fail "exit $?: $(cat err)"
"$BIN/$prog" "${common[@]}" -q -j 1 -o sim1.fits <objects.jsonl || fail "-j 1 failed"
for t in "1 1 256 256" "257 1 512 256" "1 257 256 512" "257 257 512 512"; do
  "$BIN/$prog" "${common[@]}" -q --tile $t -o "tile_${t// /_}.fits" <objects.jsonl ||
    fail "--tile $t failed"
done
"$BIN/$prog" --psf psf.jsonl --galaxy-psf psf.jsonl --like "$hdf" --noise-free -q -o clean.fits \
  --truth clean.jsonl \
  <objects.jsonl || fail "--noise-free failed"

python3 - "$tools" <<'PY' || fail "the images break the checks"
import json, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
cards, nx, ny, sim = read("sim.fits")
assert (nx, ny) == (512, 512), (nx, ny)
# --noise-like: the field's background rms (every record carries it), not a stamp's.
sources = [json.loads(l) for l in open("sources.jsonl")]
field_rms = sources[0]["background_rms"]
assert all(s["background_rms"] == field_rms for s in sources)
assert abs(float(cards["NOISERMS"]) - field_rms) < 1e-6 * field_rms, (cards["NOISERMS"], field_rms)
assert cards["CTYPE1"] == "RA---TAN" and abs(float(cards["CRVAL1"]) - 189.19) < 0.01, cards
truth = [json.loads(l) for l in open("truth.jsonl")]
objects = [json.loads(l) for l in open("objects.jsonl")]
assert int(cards["NOBJ"]) == len(truth) and len(truth) >= len(objects) - 5, (cards["NOBJ"], len(objects))
assert all(t["schema"] == "shapesim.truth/1" for t in truth)
# -j 1 equals -j 2; the 2x2 mosaic equals the whole image.
_, _, _, one = read("sim1.fits")
assert one == sim, "-j 1 and -j 2 differ"
for x0, y0 in ((1, 1), (257, 1), (1, 257), (257, 257)):
    name = f"tile_{x0}_{y0}_{x0 + 255}_{y0 + 255}.fits"
    c, tx, ty, tile = read(name)
    assert (tx, ty) == (256, 256), name
    assert abs(float(c["CRPIX1"]) - (float(cards["CRPIX1"]) - (x0 - 1))) < 1e-9, name
    for j in range(256):
        assert tile[j] == sim[y0 - 1 + j][x0 - 1:x0 + 255], f"{name}: row {j} differs"
# Noise-free: the image holds the drawn flux of objects well inside it (to float rounding).
_, _, _, clean = read("clean.fits")
truth = [json.loads(l) for l in open("clean.jsonl")]
inside = sum(t["flux"] for t in truth if 40 < t["x"] < 472 and 40 < t["y"] < 472)
total = sum(sum(r) for r in clean)
edge = sum(t["flux"] for t in truth) - inside
assert inside * 0.999 - 1e-6 <= total <= inside + edge + 1e-6, (total, inside, edge)
PY

# Bad input.
rc=0; "$BIN/$prog" --like "$hdf" <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'give the output image'
rc=0; "$BIN/$prog" --like "$hdf" -o bad.fits <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'schema: expected "shapesim.object/1"'
[ ! -e bad.fits ] || fail "an image was left after a wrong schema"
rc=0; "$BIN/$prog" --like "$hdf" -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'point source: give --psf'
rc=0; "$BIN/$prog" --like "$hdf" --psf psf.jsonl --tile 1 1 600 10 -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'tile'
rc=0; "$BIN/$prog" --like "$hdf" --psf psf.jsonl --shear 0.9 0.9 -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'shear'
# No silent wrong image: observed-frame models through a PSF without the PSF they hold would be
# convolved twice; a field other than sample's would leave objects out.
rc=0; "$BIN/$prog" --like "$hdf" --psf psf.jsonl -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'frame: object g0 is an observed-frame model: it already holds its field.s PSF; give --galaxy-psf'
[ ! -e bad.fits ] || fail "an image was left after a refused frame"
rc=0; "$BIN/$prog" --psf psf.jsonl --galaxy-psf psf.jsonl --area 0.1156 --pixel-scale 0.03985 \
  --ra 189.2 --dec 62.2 -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 ':1: x: object g0 was drawn for another field'
[ ! -e bad.fits ] || fail "an image was left for another field"
"$BIN/$prog" --psf psf.jsonl --galaxy-psf psf.jsonl --area 0.1156 --pixel-scale 0.03985 \
  --ra 189.2 --dec 62.2 --place-by-sky -q -o sky.fits <objects.jsonl ||
  fail "--place-by-sky failed"
# A star with a magnitude but a denormal flux is refused where it is read, naming its line,
# before anything is painted (issue 39): it used to fail after painting, on the truth's NaN.
printf '{"schema":"shapesim.object/1","id":"s1","kind":"star","ra":189.2,"dec":62.2,"mag":21,"flux":5e-324}\n' >tiny.jsonl
rc=0
"$BIN/$prog" --psf psf.jsonl --area 0.01 --pixel-scale 0.03985 --ra 189.2 --dec 62.2 -q \
  -o tiny.fits --truth tiny.truth.jsonl tiny.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 "^$prog: tiny.jsonl:1: flux: must be a positive normal number"
[ ! -e tiny.fits ] && [ ! -e tiny.truth.jsonl ] || fail "an output was left for a refused record"
exit 0
