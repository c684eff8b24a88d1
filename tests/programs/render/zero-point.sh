#!/usr/bin/env bash
# The rendered image carries its objects' zero point (MAGZERO, when every object's mag and
# flux agree on one), so shapesim-measure gives the true magnitudes without --zero-point;
# objects that disagree leave the card out (issue 15).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_morphology
"$BIN/shapesim-smooth" -q --delta --like "$HDF_IMAGE" <shapelets.jsonl >delta.json || fail "smooth failed"
"$BIN/shapesim-sample" -q delta.json --like "$HDF_IMAGE" --seed 3 >objects.jsonl || fail "sample failed"
"$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-rms 2e-5 --seed 3 -o sim.fits <objects.jsonl ||
  fail "render failed"
zp=$(python3 "$tools/fitsdata.py" sim.fits header | sed -n 's/^MAGZERO=//p')
[ "$zp" = "22.08" ] || fail "MAGZERO is '$zp', not 22.08"
"$BIN/shapesim-measure" -q --mag-limit 29 sim.fits >without.jsonl || fail "measure failed"
"$BIN/shapesim-measure" -q --mag-limit 29 --zero-point 22.08 sim.fits >with.jsonl || fail "measure failed"
[ -s without.jsonl ] || fail "nothing measured"
cmp -s without.jsonl with.jsonl || fail "measure without --zero-point differs from with it"
# One object with another zero point: no card.
python3 -c 'import json, sys
rows = [json.loads(l) for l in open("objects.jsonl")]
rows[0]["mag"] += 0.5
sys.stdout.write("".join(json.dumps(r) + "\n" for r in rows))' >mixed.jsonl
"$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-rms 2e-5 --seed 3 -o mixed.fits <mixed.jsonl ||
  fail "render of mixed zero points failed"
python3 "$tools/fitsdata.py" mixed.fits header | grep '^MAGZERO=' >/dev/null && fail "MAGZERO written for disagreeing objects"
exit 0
