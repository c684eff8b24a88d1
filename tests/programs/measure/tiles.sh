#!/usr/bin/env bash
# Detection and measurement tile by tile (--tile-side, issue 39) give the catalogue of the whole
# image: on a 2048² simulated field cut into 16 tiles of 512², the same objects (counts within
# 1%), at the same places (in image pixels and on the sky), with the same magnitudes for 99% of
# the objects no neighbour touches (|Δmag| < 1e-3): where blended neighbours meet, libsep's
# single-precision deblending may hand a pixel or two to the other member, since a tile's
# pixel coordinates round differently. Ids stay unique; objects cut by a tile are flagged. On the HDF with its
# weight map (each tile its own weight scale) the bright isolated galaxies agree too. Outputs
# made from the whole image (--stamps) are refused with tiles, in one line.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
models=$(cd ../../../share/data/models && pwd)
cd "$TMPDIR"
field=(--pixels 2048 --pixel-scale 0.03 --ra 150 --dec 2)
"$BIN/shapesim-sample" -q "$models/merged.json" "${field[@]}" --zero-point 25.94 --mag-limit 31 --density 3200 \
  --seed 2 -o objects.jsonl || fail "sample failed"
"$BIN/shapesim-render" -q objects.jsonl --psf-analytic gaussian:0.1 "${field[@]}" \
  --noise-rms 0.0003 -j 2 -o image.fits || fail "render failed"

"$BIN/shapesim-detect" image.fits --tile-side none -q >whole.jsonl || fail "detect --tile-side none failed"
"$BIN/shapesim-detect" image.fits --tile-side 512 >tiled.jsonl 2>err || fail "detect --tile-side 512: $(cat err)"
grep -q "the 2048×2048 image in 16 tiles of 512² pixels, each read with a margin of 256" err ||
  fail "no tile summary: $(cat err)"
grep -q "^shapesim-detect: tile 16 of 16 (x 1537–2048, y 1537–2048): " err || fail "no tile lines"
"$BIN/shapesim-measure" image.fits --tile-side none --mag-limit 28 -q >whole.morph.jsonl ||
  fail "measure --tile-side none failed"
"$BIN/shapesim-measure" image.fits --tile-side 512 --mag-limit 28 -j 2 -q >tiled.morph.jsonl ||
  fail "measure --tile-side 512 failed"
# Below 4096² pixels, auto is the whole image: the same bytes.
"$BIN/shapesim-detect" image.fits -q >auto.jsonl || fail "detect failed"
cmp -s auto.jsonl whole.jsonl || fail "--tile-side auto on 2048² is not the whole image"

python3 - <<'PY' || fail "the tiled catalogues differ from the whole image's"
import json, math
def load(f): return [json.loads(l) for l in open(f)]
def compare(name, whole, tiled, sky):
    ids = [r["id"] for r in tiled]
    assert len(set(ids)) == len(ids), f"{name}: ids repeat"
    grid = {}
    for r in tiled: grid.setdefault((int(r["x"]) // 4, int(r["y"]) // 4), []).append(r)
    def nearest(r):
        cands = [t for i in (-1, 0, 1) for j in (-1, 0, 1)
                 for t in grid.get((int(r["x"]) // 4 + i, int(r["y"]) // 4 + j), [])]
        return min(cands, key=lambda t: math.hypot(t["x"] - r["x"], t["y"] - r["y"]), default=None)
    matched = alone = worst_alone = 0
    worst_sky = 0.0
    for r in whole:
        t = nearest(r)
        if t is None or math.hypot(t["x"] - r["x"], t["y"] - r["y"]) > 0.01: continue
        matched += 1
        # The same place in pixels is the same place on the sky: the window's WCS is the image's.
        if sky and math.hypot(t["x"] - r["x"], t["y"] - r["y"]) < 1e-6:
            worst_sky = max(worst_sky, abs(t["ra"] - r["ra"]), abs(t["dec"] - r["dec"]))
        if not {"blended", "aperture_masked", "tile_truncated"} & set(r["flags"]):
            alone += 1
            if abs(t["mag"] - r["mag"]) >= 1e-3: worst_alone += 1
    print(f"{name}: whole {len(whole)}, tiled {len(tiled)}, matched within 0.01 px {matched}; "
          f"alone {alone}, |dmag| >= 1e-3: {worst_alone}; sky positions within {worst_sky:.1e} deg")
    assert abs(len(tiled) - len(whole)) <= 0.01 * len(whole), (len(tiled), len(whole))
    assert matched >= 0.98 * len(whole), matched
    assert alone >= 0.5 * matched and worst_alone <= 0.01 * alone, (alone, worst_alone)
    assert worst_sky < 1e-10, worst_sky
    return len(whole)
n = compare("detect", load("whole.jsonl"), load("tiled.jsonl"), True)
assert n > 1000, n
compare("measure", load("whole.morph.jsonl"), load("tiled.morph.jsonl"), False)
PY

# The HDF with its weight map, in four tiles: each tile its own weight scale.
weight=$HDF_DATA/hdfn_f814w_v2_weight.fits
"$BIN/shapesim-measure" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 -q >hdf.whole.jsonl ||
  fail "measure of the HDF failed"
"$BIN/shapesim-measure" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 --tile-side 256 \
  --tile-margin 128 -q >hdf.tiled.jsonl || fail "measure of the HDF in tiles failed"
python3 - <<'PY' || fail "the HDF's tiles differ from the whole"
import json, math
whole = [json.loads(l) for l in open("hdf.whole.jsonl")]
tiled = [json.loads(l) for l in open("hdf.tiled.jsonl")]
bright = [r for r in whole if r["mag"] < 28.5 and not {"blended", "aperture_masked"} & set(r["flags"])]
off = 0
for r in bright:
    t = min(tiled, key=lambda t: math.hypot(t["x"] - r["x"], t["y"] - r["y"]))
    if math.hypot(t["x"] - r["x"], t["y"] - r["y"]) > 0.05 or abs(t["mag"] - r["mag"]) > 0.01: off += 1
print(f"HDF: whole {len(whole)}, tiled {len(tiled)}; isolated I < 28.5: {len(bright)}, off by > 0.01 mag: {off}")
assert abs(len(tiled) - len(whole)) <= 0.05 * len(whole)
assert len(bright) >= 15 and off <= 0.1 * len(bright), off
PY

# Without a margin, objects across a tile's edge are cut by it: flagged and counted in one
# warning; with the default margin none is.
"$BIN/shapesim-detect" image.fits --tile-side 512 --tile-margin 0 >cut.jsonl 2>err ||
  fail "detect --tile-margin 0 failed"
cut=$(grep -c '"tile_truncated"' cut.jsonl) || fail "no object flagged tile_truncated"
grep -q "warning: [0-9]* objects reach the edge of their tile's window and are cut by it (flag tile_truncated): give a larger --tile-margin than 0" err ||
  fail "no warning for the cut objects: $(cat err)"
! grep -q tile_truncated tiled.jsonl || fail "objects cut with the default margin"
echo "margin 0: $cut objects flagged tile_truncated; default margin: none"

# A weight map of the wrong type is named once for all the tiles, as for the whole image.
"$BIN/shapesim-measure" "$HDF_IMAGE" --weight "$weight" --weight-type rms --zero-point 22.08 \
  --tile-side 256 >/dev/null 2>err || fail "measure with --weight-type rms failed"
[ "$(grep -c "differs from the measured rms" err)" -eq 1 ] &&
  grep -q "warning: in 4 of 4 tiles the weight map's noise differs" err ||
  fail "no single warning for the wrong weight type: $(grep warning err)"

# Whole-image outputs are refused with tiles; nothing is written.
rc=0
"$BIN/shapesim-detect" image.fits --tile-side 512 --stamps stamps.fits >out.jsonl 2>err || rc=$?
expect_error "$rc" 2 "^shapesim-detect: --tile-side: --stamps, --segmentation, --noise-model and --bands"
[ ! -e stamps.fits ] || fail "stamps written"
rc=0
"$BIN/shapesim-measure" image.fits --tile-side 8x8 >out.jsonl 2>err || rc=$?
expect_error "$rc" 2 "^shapesim-measure: --tile-side: must be auto, none or a side of at least 16 pixels, got '8x8'"
exit 0
