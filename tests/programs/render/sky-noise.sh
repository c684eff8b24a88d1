#!/usr/bin/env bash
# The real sky's noise, measured and drawn: shapesim-detect --noise-model writes the HDF sky's
# rms and 2-D autocorrelation; shapesim-render --noise-model draws it into a δ-function
# simulation of the HDF cut, its σ varying as the HDF's weight map says (--noise-weight);
# measured alike (its own detection, the HDF's weight map, objects of S/N ≥ 4 masked), the
# simulated sky has the real one's autocorrelation within 0.02 at every lag up to 3 pixels,
# its rms within 2% and a pixel histogram the KS test cannot tell apart (p > 0.05)
# (shapesim-measure --compare-sky). The drawn pixels follow the real sky's measured
# distribution (the noise record's marginal): an empty field's 1st, 5th, 95th and 99th
# percentiles within 1.5% of the real sky's, where Gaussian pixels of the same rms
# (--gaussian-noise) fall 3% short at the 99th; the map leaves ξ within 0.003 of the Gaussian
# field's and keeps the median. Tiles with the wide kernel equal the whole image, and so
# does the image drawn with narrower lanes (SHAPESIM_SIMD=avx2 where the CPU has AVX-512;
# SHAPESIM_SIMD=none: the scalar generator); bad
# noise models fail with one line.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-render
tools=$(cd ../tools && pwd)
weight=$HDF_DATA/hdfn_f814w_v2_weight.fits

cd "$TMPDIR"
"$BIN/shapesim-detect" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 --stamps stamps.fits \
  --noise-model hdf.noise.jsonl -q >sources.jsonl || fail "detect --noise-model failed"
"$BIN/shapesim-decompose" -q -j 2 <sources.jsonl >shapelets.jsonl || fail "decompose failed"
"$BIN/shapesim-decompose" -q --psf-image "$HDF_DATA/wfpc2_f814w_tinytim_psf.fits" --like "$HDF_IMAGE" \
  --psf-box 0.0996 0.05 >psf.jsonl || fail "decompose --psf-image failed"
"$BIN/shapesim-smooth" -q --delta --like "$HDF_IMAGE" <shapelets.jsonl >delta.json || fail "smooth failed"
"$BIN/shapesim-sample" delta.json --like "$HDF_IMAGE" --seed 7 -q >objects.jsonl || fail "sample failed"
common=(--psf psf.jsonl --galaxy-psf psf.jsonl --like "$HDF_IMAGE" --noise-model hdf.noise.jsonl
        --noise-weight "$weight" --gain 865200 --seed 7)
"$BIN/$prog" "${common[@]}" -q -o delta.fits <objects.jsonl || fail "render --noise-model failed"
"$BIN/shapesim-detect" delta.fits --weight "$weight" --noise-model delta.noise.jsonl -q >/dev/null ||
  fail "detect on the simulation failed"
"$BIN/shapesim-measure" --compare-sky hdf=hdf.noise.jsonl delta=delta.noise.jsonl >sky.md ||
  fail "measure --compare-sky failed"
# An empty field, with the measured marginal and with Gaussian pixels.
for mode in marginal gaussian; do
  extra=(); [ $mode = gaussian ] && extra=(--gaussian-noise)
  "$BIN/$prog" "${common[@]}" "${extra[@]}" -q -o empty_$mode.fits </dev/null ||
    fail "render of an empty field ($mode) failed"
  "$BIN/shapesim-detect" empty_$mode.fits --weight "$weight" --noise-model empty_$mode.noise.jsonl \
    -q >/dev/null || fail "detect on the empty field ($mode) failed"
done
"$BIN/shapesim-measure" --compare-sky hdf=hdf.noise.jsonl marginal=empty_marginal.noise.jsonl \
  gaussian=empty_gaussian.noise.jsonl >empty.md || fail "measure --compare-sky (empty) failed"
for t in "1 1 512 200" "1 201 512 512"; do
  "$BIN/$prog" "${common[@]}" -q --tile $t -o "tile_${t// /_}.fits" <objects.jsonl ||
    fail "--tile $t failed"
done

for simd in none avx2; do
  SHAPESIM_SIMD=$simd "$BIN/$prog" "${common[@]}" -q -o delta_$simd.fits <objects.jsonl ||
    fail "render with SHAPESIM_SIMD=$simd failed"
  cmp -s delta.fits delta_$simd.fits || fail "the noise with SHAPESIM_SIMD=$simd differs"
done

python3 - "$tools" <<'PY' || fail "the sky checks fail: $(cat sky.md)"
import json, sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
real = json.loads(open("hdf.noise.jsonl").readline())
assert real["schema"] == "shapesim.noise/1", real["schema"]
r = real["correlation_radius"]
xi = lambda d, dx, dy: d["correlation"][(dy + r) * (2 * r + 1) + dx + r]
assert 1.5e-5 < real["rms"] < 2.5e-5 and 0.4 < xi(real, 1, 0) < 0.6, real["rms"]
row = [c.strip() for c in open("sky.md").read().splitlines()[3].split("|")[1:-1]]
assert row[0] == "delta", row
max_dxi, ratio, offset, ks_p = float(row[11]), float(row[12]), float(row[17]), float(row[19])
assert max_dxi <= 0.02, f"autocorrelation differs by {max_dxi}"
assert abs(ratio - 1) <= 0.02, f"rms ratio {ratio}"
assert ks_p > 0.05, f"KS p {ks_p}"
assert abs(offset) < 0.1, f"sky levels differ by {offset} rms"
# The marginal: percentiles 1, 5, 95, 99 of an empty field against the real sky's.
m = real["marginal"]
assert m["z0"] < -3.5 and abs(m["dz"] - 0.05) < 1e-12 and len(m["values"]) == 2 * round(-m["z0"] / m["dz"]) + 1, m["z0"]
lines = open("empty.md").read().splitlines()
rows = {c[0]: c for c in ([x.strip() for x in l.split("|")[1:-1]] for l in lines[2:])}
marg, gauss = rows["marginal"], rows["gaussian"]
for k, name in zip(range(13, 17), ("P1", "P5", "P95", "P99")):
    assert abs(float(marg[k]) - 1) <= 0.015, f"{name} of the empty field: {marg[k]} of the real sky's"
assert float(gauss[16]) < 0.975 and float(marg[16]) - float(gauss[16]) > 0.02, \
    f"P99: marginal {marg[16]}, Gaussian {gauss[16]}: the marginal changed nothing"
em = json.loads(open("empty_marginal.noise.jsonl").readline())
eg = json.loads(open("empty_gaussian.noise.jsonl").readline())
for dx, dy in ((1, 0), (0, 1), (1, 1), (2, 0), (3, 3)):
    assert abs(xi(em, dx, dy) - xi(eg, dx, dy)) <= 0.003, f"the marginal moved xi({dx},{dy})"
assert abs(float(marg[17])) < 0.03, f"median offset {marg[17]}"
cards, nx, ny, whole = read("delta.fits")
assert cards["NOISEMOD"] == "hdf.noise.jsonl, scaled by the weight map", cards["NOISEMOD"]
for y0, y1 in ((1, 200), (201, 512)):
    _, _, _, tile = read(f"tile_1_{y0}_512_{y1}.fits")
    assert tile == whole[y0 - 1:y1], f"tile rows {y0}-{y1} differ"
PY

# Bad input: one line, the right exit code, no image.
rc=0; "$BIN/$prog" "${common[@]}" --noise-rms 1 -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'noise-model sets the noise'
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --psf psf.jsonl --noise-model sources.jsonl -o bad.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'schema'
sed 's/"correlation_radius":[0-9]*/"correlation_radius":3/' hdf.noise.jsonl >short.jsonl
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --psf psf.jsonl --noise-model short.jsonl -o bad.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'short.jsonl:1: correlation: must hold'
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --psf psf.jsonl --gaussian-noise -o bad.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'gaussian-noise needs --noise-model'
sed 's/"dz":[0-9.e-]*/"dz":-1/' hdf.noise.jsonl >bad_marginal.jsonl
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --psf psf.jsonl --noise-model bad_marginal.jsonl -o bad.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'bad_marginal.jsonl:1: marginal: dz must be within'
[ ! -e bad.fits ] || fail "an image was left after a bad noise model"
# A weight map of another size than the field, or with no positive weight.
rc=0; "$BIN/$prog" --size 0.2 --pixel-scale 0.04 --noise-model hdf.noise.jsonl --noise-weight "$weight" \
  -o bad.fits <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'the weight map is 512 x 512 pixels, the field 300 x 300'
: | "$BIN/$prog" --like "$HDF_IMAGE" --noise-free -q -o zero.fits || fail "could not draw an empty image"
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --noise-model hdf.noise.jsonl --noise-weight zero.fits -o bad.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'no pixel with a positive weight'
[ ! -e bad.fits ] || fail "an image was left after a bad weight map"
# A correlated-noise factor beyond the 3×3 kernel's reach: one limit, one line, no image.
rc=0; "$BIN/$prog" --like "$HDF_IMAGE" --noise-rms 1 --noise-correlation 2.4 -o bad.fits </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 'above 2.33969.* needs a wider kernel than 3×3: give the measured noise model'
[ ! -e bad.fits ] || fail "an image was left after an unreachable correlation"
# A field with no sky left (every pixel within 100 px of an object): detect fails before any
# output, leaving no noise model, no stamps and an empty catalogue.
rc=0; "$BIN/shapesim-detect" "$HDF_IMAGE" -q --zero-point 22.08 --noise-grow 100 --noise-model nosky.jsonl \
  --stamps nosky.fits >out 2>err || rc=$?
expect_error "$rc" 1 'sky noise: only'
[ ! -e nosky.jsonl ] && [ ! -e nosky.fits ] && [ ! -s out ] || fail "detect left output without a sky"
exit 0
