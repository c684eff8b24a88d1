#!/usr/bin/env bash
# pipelines/cosmos.mk, the one command that trains a model on RealGalaxyCatalogs (the COSMOS
# training samples), on two shipped catalogues whose PSF files are not shipped: every galaxy
# fitted through the stated PSF and flagged so, the model built from them weighted by the
# catalogues' WEIGHT, drawn by shapesim-sample; a second run does nothing; a missing
# catalogue fails with its name and leaves no model.
source ../lib.sh
root=$(cd ../../.. && pwd)
data=$root/share/data/cosmos_catalog
cd "$TMPDIR"
cats="$data/sample_23.5_n1/real_galaxy_catalog_23.5.fits $data/bright_pair/real_galaxy_catalog_23.5.fits"
make -s -f "$root/pipelines/cosmos.mk" BIN="$BIN" OUT=cos CATALOGS="$cats" >log 2>&1 ||
  fail "cosmos.mk failed: $(tail -5 log)"
[ "$(cat cos/fits/1.jsonl cos/fits/2.jsonl | wc -l)" -eq 12 ] || fail "expected 12 fits"
[ "$(cat cos/fits/*.jsonl | grep -c psf_substituted)" -eq 12 ] || fail "the substituted PSF is not flagged"
grep -q "PSF files are absent" log || fail "no warning of the substituted PSF"
python3 - <<'PY' || fail "the model is not the catalogues'"
import json
m = json.load(open("cos/model.json"))
assert m["frame"] == "intrinsic" and len(m["points"]) >= 8, (m["frame"], len(m["points"]))
assert all(19.7 < p["mag"] < 23.3 for p in m["points"])
PY
"$BIN/shapesim-sample" cos/model.json --area 1 --pixel-scale 0.03 --zero-point 25.94 --seed 1 -q >objects.jsonl ||
  fail "sample refused the model"
[ "$(grep -c '"galaxy"' objects.jsonl)" -gt 300 ] || fail "too few galaxies drawn"
before=$(stat -c %Y.%s cos/fits/1.jsonl cos/model.json)
sleep 1
make -s -f "$root/pipelines/cosmos.mk" BIN="$BIN" OUT=cos CATALOGS="$cats" >log 2>&1 || fail "a second run failed"
[ "$(stat -c %Y.%s cos/fits/1.jsonl cos/model.json)" = "$before" ] || fail "a second run fitted again"
rc=0; make -s -f "$root/pipelines/cosmos.mk" BIN="$BIN" OUT=bad CATALOGS=nosuch.fits >log 2>&1 || rc=$?
[ "$rc" -ne 0 ] && grep -q "nosuch.fits" log || fail "a missing catalogue: exit $rc, $(tail -2 log)"
[ ! -e bad/model.json ] || fail "a failed run left a model"
exit 0
