#!/usr/bin/env bash
# shapesim-measure against Debian's source-extractor run with the same settings
# (share/data/sextractor/hdf.sex) on the HDF cut: objects matched within 1 px, and for the
# matched galaxies brighter than I = 28 the scatters of mag, FWHM, a, b and θ stay within
# bounds (printed: the numbers the README states). Skipped when source-extractor is absent.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-measure
command -v source-extractor >/dev/null || exit 77
sex=$(cd ../../../share/data/sextractor && pwd)
cd "$TMPDIR"
"$BIN/$prog" "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" --zero-point 22.08 \
  -j 2 -q --with-stars >morph.jsonl || fail "shapesim-measure failed"
(cd "$sex" && source-extractor "$HDF_IMAGE" -c hdf.sex -CATALOG_NAME "$TMPDIR/hdf.cat" \
  -WEIGHT_IMAGE "$HDF_DATA/hdfn_f814w_v2_weight.fits") || fail "source-extractor failed"
python3 - <<'PY' || fail "shapesim-measure and source-extractor disagree"
import json, math
cols, rows = {}, []
for line in open("hdf.cat"):
    if line.startswith("#"):
        p = line.split()
        cols[p[2]] = int(p[1]) - 1
    else:
        rows.append([float(x) for x in line.split()])
ours = [json.loads(l) for l in open("morph.jsonl")]
pairs = []
for r in ours:
    best = min(rows, key=lambda s: (s[cols["X_IMAGE"]] - r["x"]) ** 2 + (s[cols["Y_IMAGE"]] - r["y"]) ** 2)
    if math.hypot(best[cols["X_IMAGE"]] - r["x"], best[cols["Y_IMAGE"]] - r["y"]) < 1.0:
        pairs.append((r, best))
bright = [(r, s) for r, s in pairs if s[cols["MAG_AUTO"]] < 28]
def rms(v): return math.sqrt(sum(x * x for x in v) / len(v))
def med(v): v = sorted(v); return v[len(v) // 2]
dmag = [r["mag"] - s[cols["MAG_AUTO"]] for r, s in bright]
dfwhm = [r["fwhm"] / s[cols["FWHM_IMAGE"]] - 1 for r, s in bright if s[cols["FWHM_IMAGE"]] > 0]
da = [r["a"] / s[cols["A_IMAGE"]] - 1 for r, s in bright]
db = [r["b"] / s[cols["B_IMAGE"]] - 1 for r, s in bright]
dt = [((r["theta"] - s[cols["THETA_IMAGE"]] + 90) % 180) - 90 for r, s in bright
      if s[cols["B_IMAGE"]] / s[cols["A_IMAGE"]] < 0.8]
print(f"matched {len(pairs)} of {len(ours)} (SExtractor {len(rows)}); I < 28: {len(bright)}")
print(f"mag: median {med(dmag):+.4f}, rms {rms(dmag):.4f}")
print(f"FWHM: median {med(dfwhm):+.4f}, rms {rms(dfwhm):.4f} (relative)")
print(f"a: median {med(da):+.4f}, rms {rms(da):.4f}; b: median {med(db):+.4f}, rms {rms(db):.4f}")
print(f"theta (b/a < 0.8, {len(dt)}): median {med(dt):+.3f} deg, rms {rms(dt):.3f} deg")
assert len(pairs) >= 0.8 * len(ours), len(pairs)
assert len(bright) >= 25, len(bright)
assert abs(med(dmag)) < 0.05 and rms(dmag) < 0.2, (med(dmag), rms(dmag))
assert abs(med(da)) < 0.02 and abs(med(db)) < 0.02 and rms(da) < 0.1, (med(da), med(db), rms(da))
assert abs(med(dt)) < 1.0 and rms(dt) < 5.0, (med(dt), rms(dt))
assert abs(med(dfwhm)) < 0.15, med(dfwhm)
PY

# Detection counts at the same settings (issue 39: within 10% of SExtractor's), on the HDF and
# on a deep simulated field of white noise where most detections at 1.3σ are the noise's own
# peaks: libsep's count (every object above the threshold, as shapesim-detect logs it) against
# SExtractor's rows.
models=$(cd "$sex/../models" && pwd)
field=(--pixels 1024 --pixel-scale 0.03 --ra 150 --dec 2)
"$BIN/shapesim-sample" -q "$models/merged.json" "${field[@]}" --zero-point 25.94 --mag-limit 31 \
  --seed 3 -o objects.jsonl || fail "sample failed"
"$BIN/shapesim-render" -q objects.jsonl --psf-analytic gaussian:0.1 "${field[@]}" \
  --noise-rms 0.0003 -o deep.fits || fail "render failed"
(cd "$sex" && source-extractor "$TMPDIR/deep.fits" -c hdf.sex -CATALOG_NAME "$TMPDIR/deep.cat" \
  -WEIGHT_TYPE NONE -MAG_ZEROPOINT 25.94) || fail "source-extractor failed on the simulated field"
count_ours() { sed -n 's/^shapesim-detect: \([0-9]*\) objects above 1.3σ.*/\1/p' "$1"; }
"$BIN/shapesim-detect" "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" >/dev/null 2>err ||
  fail "detect failed on the HDF"
hdf_ours=$(count_ours err)
"$BIN/shapesim-detect" deep.fits >/dev/null 2>err || fail "detect failed on the simulated field"
deep_ours=$(count_ours err)
python3 - "$hdf_ours" "$deep_ours" <<'PY' || fail "detection counts differ from SExtractor's by more than 10%"
import sys
def rows(f): return sum(1 for l in open(f) if not l.startswith("#"))
for name, ours, cat in (("HDF", int(sys.argv[1]), "hdf.cat"), ("simulated", int(sys.argv[2]), "deep.cat")):
    theirs = rows(cat)
    print(f"{name}: {ours} detections, SExtractor {theirs} ({ours / theirs - 1:+.1%})")
    assert abs(ours / theirs - 1) <= 0.10, (name, ours, theirs)
PY
exit 0
