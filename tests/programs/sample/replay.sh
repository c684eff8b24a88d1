#!/usr/bin/env bash
# The real field replayed: shapesim-sample --replay writes each HDF galaxy's fitted model where
# it was fitted, as fitted (coefficients, flux, position through the image's WCS); rendered with
# new noise at three seeds and measured as the real image is, shapesim-measure --compare-paired
# pairs every real galaxy with its replays. The bright half must come back in most replays at
# its real size (the models' fidelity); the draw options and another field are refused.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cd "$TMPDIR"
WEIGHT=$HDF_DATA/hdfn_f814w_v2_weight.fits
"$BIN/shapesim-detect" "$HDF_IMAGE" --weight "$WEIGHT" --zero-point 22.08 --gain 865200 \
  --stamps stamps.fits --noise-model noise.jsonl -q >sources.jsonl || fail "shapesim-detect failed"
"$BIN/shapesim-decompose" -q -j 2 <sources.jsonl >shapelets.jsonl || fail "shapesim-decompose failed"

"$BIN/shapesim-sample" --replay shapelets.jsonl --like "$HDF_IMAGE" >replay.jsonl 2>replay.err ||
  fail "sample --replay failed: $(cat replay.err)"
grep -q "fits replayed where they were fitted" replay.err || fail "no summary line: $(cat replay.err)"
python3 - <<'PY' || fail "the replay is not the fits as fitted"
import json
fits = [json.loads(l) for l in open("shapelets.jsonl")]
objs = {o["id"]: o for o in map(json.loads, open("replay.jsonl"))}
drawn = [f for f in fits if f.get("flux", 0) > 0 and f.get("coeffs")]
assert len(objs) == len(drawn) and len(drawn) > 200, (len(objs), len(drawn))
for f in drawn:
    o = objs[f["id"]]
    for k in ("x", "y", "beta", "pixel_scale", "n_max", "flux", "mag", "coeffs"):
        assert o[k] == f[k], (f["id"], k)
    assert o["parent"] == f["id"] and o["frame"] == "observed" and o["reach"] > 0
PY

# Rendered as shapesim-render draws the HDF (the observed-frame models hold its PSF: no
# convolution), with the sky's measured noise over the weight map, and measured alike.
for seed in 1 2 3; do
  "$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-model noise.jsonl --noise-weight "$WEIGHT" \
    --seed $seed -o replay$seed.fits <replay.jsonl || fail "render of the replay failed"
  "$BIN/shapesim-measure" -q --zero-point 22.08 --mag-limit 29 replay$seed.fits --weight "$WEIGHT" \
    >replay$seed.morph.jsonl || fail "measure of replay $seed failed"
done
"$BIN/shapesim-measure" -q --zero-point 22.08 --mag-limit 29 "$HDF_IMAGE" --weight "$WEIGHT" \
  >hdf.morph.jsonl || fail "measure of the HDF failed"
"$BIN/shapesim-measure" --compare-paired hdf=hdf.morph.jsonl r1=replay1.morph.jsonl \
  r2=replay2.morph.jsonl r3=replay3.morph.jsonl >paired.md 2>paired.err ||
  fail "--compare-paired failed: $(cat paired.err)"
grep -q "found in 3 replays" paired.md || fail "no paired table: $(cat paired.md)"
python3 - <<'PY' || fail "the replays are not the real galaxies: $(cat paired.md)"
rows = [l.split("|")[1:-1] for l in open("paired.md") if l.startswith("| ") and "–" in l]
assert len(rows) == 5, rows
def found(r): n, d = r[2].split()[0].split("/"); return int(n) / int(d)
def geo(r): return float(r[3].split("±")[0])
# The two brightest quarters: found in most replays, at their real size within 10%.
for r in rows[:2]:
    assert found(r) >= 0.7 and abs(geo(r) - 1) < 0.1, r
# All: within 10% in the geometric mean (the faint quarter is selected by its noise twice).
assert abs(geo(rows[4]) - 1) < 0.1, rows[4]
PY

# The draw's options, and another field, are refused in one line.
if "$BIN/shapesim-sample" --replay shapelets.jsonl --like "$HDF_IMAGE" --density 5 >x.jsonl 2>err; then
  fail "--replay took --density"
fi
grep -q "^shapesim-sample: --density: not with --replay" err || fail "wrong message: $(cat err)"
if "$BIN/shapesim-sample" --replay shapelets.jsonl --area 1 --pixel-scale 0.06 >x.jsonl 2>err; then
  fail "--replay took a field of another pixel scale"
fi
[ "$(wc -l <err)" = 1 ] && grep -q "shapelets.jsonl:1: pixel_scale: fit .* replay the fits on the image" err ||
  fail "wrong message for another field: $(cat err)"
[ ! -s x.jsonl ] || fail "a refused replay wrote records"
# A bad fit after good ones: its own line named, and still nothing written.
{ head -3 shapelets.jsonl; sed -n 1p shapelets.jsonl | sed 's/"pixel_scale":[0-9.e-]*/"pixel_scale":0.06/'; } >mixed.jsonl
if "$BIN/shapesim-sample" --replay mixed.jsonl --like "$HDF_IMAGE" >x.jsonl 2>err; then
  fail "--replay took a fit of another pixel scale after good ones"
fi
grep -q "^shapesim-sample: mixed.jsonl:4: pixel_scale: fit " err || fail "wrong line named: $(cat err)"
[ ! -s x.jsonl ] || fail "a replay refused at its fourth fit wrote records"
exit 0
