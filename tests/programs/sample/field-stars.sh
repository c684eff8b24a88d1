#!/usr/bin/env bash
# Stars from the real field: smooth --stars records the field's star magnitudes in the model,
# and sample draws that field's star counts by default (Poisson about density × area, each
# magnitude in a 0.5-mag bin of a real star, none fainter than --mag-limit); --star-density 0
# or --star-count override it; a model without star counts draws none; --stars without a
# field, or naming an unknown one, is one line on stderr.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cd "$TMPDIR"
hdf_models
# Thirteen stars over the 4 arcmin² given: twelve at 19.1–24.9, one at 29.0 (fainter than the
# draws' limit of 28.5), and one without a magnitude (not counted).
: >stars.jsonl
for m in 19.1 20.3 20.4 21.7 22.0 22.2 23.1 23.4 23.6 24.2 24.8 24.9 29.0; do
  printf '{"schema":"shapesim.source/1","id":"s%s","x":10,"y":10,"flux":1,"mag":%s,"kind":"star"}\n' "$m" "$m" >>stars.jsonl
done
printf '{"schema":"shapesim.source/1","id":"nomag","x":10,"y":10,"flux":0,"kind":"star"}\n' >>stars.jsonl
"$BIN/shapesim-smooth" --area 4.0 --stars stars.jsonl <shapelets.jsonl >morph.json 2>smooth.err ||
  fail "smooth --stars failed: $(cat smooth.err)"
grep -q "13 stars in the field (4 arcmin^2)" smooth.err || fail "smooth did not say the stars: $(cat smooth.err)"
"$BIN/shapesim-smooth" -q --area 4.0 <shapelets.jsonl >nostars.json || fail "smooth without stars failed"

# 10 arcmin² to I = 28.5: 12 stars per 4 arcmin² → 30 expected.
for seed in 1 2 3; do
  "$BIN/shapesim-sample" morph.json --area 10 --pixel-scale 0.04 --mag-limit 28.5 --seed $seed \
    >s$seed.jsonl 2>s$seed.err || fail "sample failed: $(cat s$seed.err)"
done
grep -q "stars: 3 per arcmin^2 to magnitude 28.5" s1.err || fail "sample did not say the stars: $(cat s1.err)"
python3 - <<'PY' || fail "the field's stars are not drawn as counted"
import json, math
real = [19.1, 20.3, 20.4, 21.7, 22.0, 22.2, 23.1, 23.4, 23.6, 24.2, 24.8, 24.9]
bins = {math.floor(m / 0.5) for m in real}
total = 0
for seed in (1, 2, 3):
    stars = [json.loads(l) for l in open(f"s{seed}.jsonl")]
    stars = [r for r in stars if r["kind"] == "star"]
    total += len(stars)
    for r in stars:
        assert math.floor(r["mag"] / 0.5) in bins and r["mag"] <= 28.5, r["mag"]
# 90 expected over the three seeds: Poisson σ 9.5.
assert abs(total - 90) < 4 * math.sqrt(90), total
PY
"$BIN/shapesim-sample" morph.json --area 10 --pixel-scale 0.04 --mag-limit 28.5 --seed 1 \
  --star-density 0 -q >none.jsonl || fail "sample --star-density 0 failed"
! grep -q '"kind":"star"' none.jsonl || fail "--star-density 0 still drew stars"
"$BIN/shapesim-sample" morph.json --area 10 --pixel-scale 0.04 --mag-limit 28.5 --seed 1 \
  --star-count 3 -q >three.jsonl || fail "sample --star-count 3 failed"
[ "$(grep -c '"kind":"star"' three.jsonl)" -eq 3 ] || fail "--star-count 3 did not give 3 stars"
"$BIN/shapesim-sample" nostars.json --area 10 --pixel-scale 0.04 --mag-limit 28.5 --seed 1 \
  -q >plain.jsonl || fail "sample on a model without stars failed"
! grep -q '"kind":"star"' plain.jsonl || fail "a model without star counts drew stars"
# The galaxies are the same draw with or without the field's stars.
cmp -s <(grep -v '"kind":"star"' plain.jsonl) <(grep -v '"kind":"star"' none.jsonl) ||
  fail "the field's stars changed the galaxies"

rc=0
"$BIN/shapesim-smooth" --stars stars.jsonl <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "needs the field they were counted in"
rc=0
"$BIN/shapesim-smooth" --area 4 --stars other.fits=stars.jsonl <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "none of the counted --field images"
rc=0
"$BIN/shapesim-smooth" --area 4 --stars missing.jsonl <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 "missing.jsonl"
exit 0
