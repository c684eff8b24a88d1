#!/usr/bin/env bash
# shapesim-smooth on the HDF models (detect → decompose → smooth): one shapesim.morphology/1
# document whose points are the models not flagged edge, bright_star, noise or bad_fit (whatever
# stopped their order search); --require 'converged|n_max_cap' is the paper's selection;
# --delta zeroes every λ and keeps the shapes as fitted (--keep-negative), which otherwise move
# to their nearest non-negative shapes where they ring below zero; the same
# input gives the same bytes; bad input gives one clear stderr line and a non-zero exit.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-smooth
data=$(cd ../../../share/data/hdfn && pwd)

cd "$TMPDIR"
hdf_models

"$BIN/$prog" -q <shapelets.jsonl >morph.json || fail "exit $?"
"$BIN/$prog" -q <shapelets.jsonl >again.json || fail "second run failed"
cmp -s morph.json again.json || fail "two runs differ"
"$BIN/$prog" -q --delta <shapelets.jsonl >delta.json || fail "--delta failed"
"$BIN/$prog" -q --keep-negative <shapelets.jsonl >fitted.json || fail "--keep-negative failed"
"$BIN/$prog" -q --require 'converged|n_max_cap' <shapelets.jsonl >strict.json ||
  fail "--require 'converged|n_max_cap' failed"
python3 - <<'PY' || fail "the morphology documents break the checks"
import json, math
records = [json.loads(l) for l in open("shapelets.jsonl")]
want = [r["id"] for r in records
        if not {"edge", "bright_star", "saturated", "noise", "bad_fit", "holes", "unsupported"} & set(r["flags"])
        and r.get("mag") is not None
        and r["coeffs"][0][0] > 0]
m = json.load(open("morph.json"))
assert m["schema"] == "shapesim.morphology/1", m["schema"]
assert [p["id"] for p in m["points"]] == want, "points are not the unflagged models"
# decompose's positivity flag: "holes" exactly where the model dips below −10% of its peak or
# holds more than 10% of its light below zero (null: no positive peak or total).
for r in records:
    h, n = r["hole_depth"], r["negative_light"]
    assert ("holes" in r["flags"]) == (h is None or n is None or h > 0.1 or n > 0.1), (r["id"], h, n, r["flags"])
flattened = [r["id"] for r in records if r["stop"] == "flattened" and r["id"] in want]
assert flattened, "no noise-limited fit kept: nothing tested"  # the cut's brightest are
paper = [i for i in want if {"converged", "n_max_cap"} & set(next(r for r in records if r["id"] == i)["flags"])]
strict = json.load(open("strict.json"))
assert [p["id"] for p in strict["points"]] == paper
assert len(paper) < len(want)
assert m["n_max"] == max(p["n_max"] for p in m["points"])
lam = m["lambda"]
assert lam["phase_deg"] == 15 and lam["beta"] > 0 and lam["mag"] > 0, lam
assert len(lam["coefficient"]) == ((m["n_max"] + 2) // 2) * ((m["n_max"] + 3) // 2)
# With --keep-negative every point's shape is a_nm/a_00 of its record (moduli kept by the
# alignment), c_00 = 1; by default the shapes that ring below zero are moved (positivity_change)
# and the others kept.
by_id = {r["id"]: r for r in records}
fitted = json.load(open("fitted.json"))
for p in fitted["points"]:
    c = by_id[p["id"]]["coeffs"]
    assert p["shape"][0] == [1.0, 0.0], p["id"]
    assert "positivity_change" not in p, p["id"]
    for (re, im), (pr, pi) in zip(c, p["shape"]):
        assert abs(math.hypot(re, im) / c[0][0] - math.hypot(pr, pi)) < 1e-9, p["id"]
moved = [p["id"] for p in m["points"] if p.get("positivity_change", 0) > 0]
assert 0 < len(moved) < len(m["points"]), len(moved)
for p, q in zip(m["points"], fitted["points"]):
    assert p["shape"][0] == [1.0, 0.0], p["id"]
    assert (p["shape"] != q["shape"]) == (p["id"] in moved), p["id"]
assert m["provenance"]["input_records"] == len(records)
d = json.load(open("delta.json"))
assert d["lambda"]["phase_deg"] == 0 and d["lambda"]["beta"] == 0 and d["lambda"]["mag"] == 0
assert all(v == 0 for v in d["lambda"]["coefficient"])
assert [p["shape"] for p in d["points"]] == [p["shape"] for p in fitted["points"]]
PY

# Capped at n_max 4, the bright galaxies end far above χ²_r 1.5: flagged bad_fit and dropped.
"$BIN/shapesim-decompose" -q -j 2 --n-max-cap 4 <sources.jsonl >capped.jsonl || fail "decompose --n-max-cap 4 failed"
"$BIN/$prog" -v <capped.jsonl >capped.json 2>capped.err || fail "smooth of capped fits failed"
grep -q 'dropped: bad_fit' capped.err || fail "no bad_fit dropped: $(cat capped.err)"
python3 -c 'import json
bad = {r["id"] for r in map(json.loads, open("capped.jsonl")) if "bad_fit" in r["flags"]}
assert bad and all(r["chi2r"] > 1.5 for r in map(json.loads, open("capped.jsonl")) if r["id"] in bad)
assert not bad & {p["id"] for p in json.load(open("capped.json"))["points"]}, bad' ||
  fail "bad fits reach the morphology model"

# --lambda-factor (the paper's k) scales every computed λ; overrides win.
"$BIN/$prog" -q --lambda-factor 2 --lambda-mag 0.5 <shapelets.jsonl >k2.json || fail "--lambda-factor 2 failed"
python3 -c 'import json
a, b = json.load(open("morph.json"))["lambda"], json.load(open("k2.json"))["lambda"]
assert abs(b["beta"] - a["beta"] / 2) < 1e-12 * a["beta"], (a["beta"], b["beta"])
assert b["mag"] == 0.5
assert all(abs(y - x / 2) <= 1e-12 * x for x, y in zip(a["coefficient"], b["coefficient"]))' ||
  fail "--lambda-factor / --lambda-mag do not act as documented"

# Bad input.
rc=0; "$BIN/$prog" <sources.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'schema: expected "shapesim.shapelet/1"'
[ ! -s out ] || fail "output written for a wrong schema"
rc=0; "$BIN/$prog" </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 'no record left to smooth'
rc=0; { head -n 3 shapelets.jsonl; echo '{"schema":"shapesim.shapelet/1",'; } | "$BIN/$prog" >out 2>err || rc=$?
expect_error "$rc" 1 '^shapesim-smooth: -:4: invalid JSON'
rc=0; "$BIN/$prog" --weight-field nosuch <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'nosuch'
rc=0; "$BIN/$prog" --lambda-factor -1 <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 '^shapesim-smooth: --lambda-factor: must be in'
rc=0; "$BIN/$prog" --like "$data/hdfn_f814w_v2.fits" --area 1 <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'give one of --like, --area and --field'
# --field: one field named by the records' image gives --area's density; records from an
# image no --field names, or a malformed --field, are refused.
"$BIN/$prog" -q --area 0.115643 <shapelets.jsonl >area.json || fail "--area failed"
"$BIN/$prog" -q --field "$HDF_IMAGE=0.115643" <shapelets.jsonl >field.json || fail "--field failed"
"$BIN/$prog" -q --area 0.115643 --weight-left-out <shapelets.jsonl >left.json || fail "--weight-left-out failed"
python3 -c 'import json
a, f = json.load(open("area.json")), json.load(open("field.json"))
[one] = f["source_fields"]
assert one["area_arcmin2"] == a["source_field"]["area_arcmin2"] and one["mags"] == a["source_field"]["mags"]
assert one["completeness"] > 28, one["completeness"]  # the turnover of the HDF counts
w = lambda m: [p.get("weight", 1) for p in m["points"]]
assert w(f) == w(a) == [1] * len(a["points"]), "one --field weighs its parents as --area does"
# --weight-left-out: a kept galaxy stands for the field galaxies left out in its 0.5-mag bin
# (noise detections, edges): weights of at least 1, above 1 where galaxies were left out.
import collections
left = json.load(open("left.json"))
mags = left["source_field"]["mags"]
all_bins = collections.Counter(int(m // 0.5) for m in mags)
kept_bins = collections.Counter(int(p["mag"] // 0.5) for p in left["points"])
for p, weight in zip(left["points"], w(left)):
    b = int(p["mag"] // 0.5)
    assert abs(weight - max(1, all_bins[b] / kept_bins[b])) < 1e-12, (p["id"], weight)
assert max(w(left)) > 1' ||
  fail "--field does not record the field as --area does"
rc=0; "$BIN/$prog" --field other.fits=1 <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'none of the --field images'
rc=0; "$BIN/$prog" --field "$HDF_IMAGE=big" <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'IMAGE=ARCMIN2\[@MAG\] or IMAGE=shapes'
# A shape-only field (isolated-galaxy cutouts): its models join the PDF with weight 0 and
# "shape_only", add nothing to the counts, and every id names its image; sample takes their
# shapes only with --neighbours.
python3 -c 'import json, sys
for l in open("shapelets.jsonl"):
    r = json.loads(l); r["image"] = "cutout.fits[1]"; print(json.dumps(r))' >cutout.jsonl
cat shapelets.jsonl cutout.jsonl | "$BIN/$prog" -v --field "$HDF_IMAGE=0.115643" \
  --field 'cutout.fits[1]=shapes' >shapes.json 2>err || fail "shape-only field failed: $(cat err)"
grep -q 'shape-only models from 1 field' err || fail "no shape-only summary: $(cat err)"
python3 -c 'import json
f, s = json.load(open("field.json")), json.load(open("shapes.json"))
assert s["source_fields"] == f["source_fields"], "a shape-only field changed the counts"
assert s["shape_fields"] == ["cutout.fits[1]"], s.get("shape_fields")
n = len(f["points"])
assert len(s["points"]) == 2 * n, (len(s["points"]), n)
for p, q in zip(f["points"], s["points"][:n]):
    assert q["id"] == "hdfn_f814w_v2:" + p["id"] and "shape_only" not in q and q["weight"] == p["weight"], q["id"]
for p, q in zip(f["points"], s["points"][n:]):
    assert q["id"] == "cutout[1]:" + p["id"] and q["shape_only"] is True and q["weight"] == 0, q["id"]' ||
  fail "shape-only points are not weight 0, flagged and named by their image"
"$BIN/shapesim-sample" shapes.json --size 1 --pixel-scale 0.04 --seed 3 --neighbours 8 -q >cond.jsonl ||
  fail "sample --neighbours on a shape-only model failed"
"$BIN/shapesim-sample" shapes.json --size 1 --pixel-scale 0.04 --seed 3 --neighbours 0 >plain.jsonl 2>err ||
  fail "sample on a shape-only model failed"
grep -q "shape-only models unused" err || fail "sample does not say the shape-only models go unused"
python3 -c 'import json
cond = [json.loads(l) for l in open("cond.jsonl")]
plain = [json.loads(l) for l in open("plain.jsonl")]
shaped = sum(r["parent"].startswith("cutout") for r in cond)
assert 0.3 < shaped / len(cond) < 0.7, (shaped, len(cond))
assert not any(r["parent"].startswith("cutout") for r in plain)
assert not any(r.get("mag_parent", "").startswith("cutout") for r in cond)' ||
  fail "shape-only parents: not drawn conditionally, or drawn for their magnitude"
rc=0; "$BIN/$prog" --field "cutout.fits[1]=shapes" <cutout.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'at least one field must give its area'
rc=0; "$BIN/$prog" --field "$HDF_IMAGE=1" --field "$HDF_IMAGE=shapes" <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'given twice'
rc=0; "$BIN/$prog" --like nosuch.fits <shapelets.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'nosuch.fits'
[ ! -s out ] || fail "output written for a missing --like image"
exit 0
