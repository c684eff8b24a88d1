#!/usr/bin/env bash
# Saturation: a ground-based frame (tests/examples/ground: the XDF cutout through 0.8″ seeing
# in 0.24″ pixels) whose CCD saturates at a full well that flattens the cutout's star (without
# a level, it reads as a stellarity-0.23 galaxy). shapesim-detect reads the level from the header's SATURATE (or --saturation), flags
# every object with a pixel at it "saturated" and sets it aside with the stars, and says how
# many; decompose --stars then flags the galaxies in their wings, and smooth keeps no saturated
# object. Without a level (--saturation 0) nothing is flagged.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
xdf=$(cd ../../../share/data/xdf && pwd)
cd "$TMPDIR"
"$EXAMPLES/ground" "$xdf/f814w_sci.fits" unsaturated.fits 0.06 25.959 0.8 4 15.3 7200 2 ||
  fail "ground: the frame could not be made"
"$BIN/shapesim-detect" -q unsaturated.fits --stars stars0.jsonl >all.jsonl || fail "detect failed"
# The full well: 5% of the brightest object's (the star's) peak above the sky, ADU.
level=$(python3 -c 'import json
rows = [json.loads(l) for l in open("all.jsonl")] + [json.loads(l) for l in open("stars0.jsonl")]
peaks = sorted((r["peak"] for r in rows), reverse=True)
sky = 15.3 * 7200 / 2  # SKY × EXPOSURE / GAIN, ADU
print(sky + 0.05 * peaks[0])')
"$EXAMPLES/ground" "$xdf/f814w_sci.fits" ground.fits 0.06 25.959 0.8 4 15.3 7200 2 1 "$level" ||
  fail "ground: the saturated frame could not be made"
"$BIN/shapesim-detect" ground.fits --stars stars.jsonl --stamps stamps.fits >sources.jsonl 2>err ||
  fail "detect failed: $(cat err)"
grep -q 'saturated objects (a pixel at or above' err || fail "no count of the saturated objects: $(cat err)"
python3 - <<'PY' || fail "saturated objects are not set aside"
import json
sources = [json.loads(l) for l in open("sources.jsonl")]
stars = [json.loads(l) for l in open("stars.jsonl")]
saturated = [s for s in stars if "saturated" in s["flags"]]
assert saturated, "nothing flagged saturated"
assert not any("saturated" in s["flags"] for s in sources), "a saturated object among the galaxies"
print(f"{len(saturated)} saturated, {len(sources)} galaxies, {len(stars)} stars")
PY
# Without a level the flattened star is a "galaxy" of low stellarity: the failure this prevents.
"$BIN/shapesim-detect" -q ground.fits --saturation 0 --stars none.jsonl >plain.jsonl || fail "--saturation 0 failed"
! grep -q '"saturated"' plain.jsonl none.jsonl || fail "--saturation 0 still flags"
[ "$(wc -l <plain.jsonl)" -gt "$(wc -l <sources.jsonl)" ] ||
  fail "the saturated star is not a galaxy without a level: the test tests nothing"
"$BIN/shapesim-decompose" -q -j 2 --stars stars.jsonl <sources.jsonl >shapelets.jsonl || fail "decompose failed"
"$BIN/shapesim-smooth" -q --like ground.fits <shapelets.jsonl >morph.json || fail "smooth failed"
python3 - <<'PY' || fail "a saturated object reaches the model"
import json
saturated = {s["id"] for s in map(json.loads, open("stars.jsonl")) if "saturated" in s["flags"]}
points = {p["id"] for p in json.load(open("morph.json"))["points"]}
assert not saturated & points, saturated & points
PY
rc=0; "$BIN/shapesim-detect" ground.fits --saturation -1 >out 2>err || rc=$?
expect_error "$rc" 2 'saturation'
exit 0
