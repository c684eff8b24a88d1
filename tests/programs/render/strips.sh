#!/usr/bin/env bash
# The image is drawn and written in strips of rows (issue 16: memory bounded by a strip, not
# the image; the write overlaps the drawing on two threads): on 1 and 2 threads the pixels
# are those of one tile per half of the image (tiles are drawn whole), and a pixel a float
# cannot hold still promotes the image to BITPIX -64, drawn whole, with nothing lost.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_morphology
"$BIN/shapesim-sample" -q morph.json --like "$HDF_IMAGE" --seed 5 >objects.jsonl || fail "sample failed"
common=(-q --like "$HDF_IMAGE" --noise-rms 2e-5 --noise-correlation 1.84 --gain 865200 --seed 5)
for j in 1 2; do
  "$BIN/shapesim-render" "${common[@]}" -j "$j" -o "j$j.fits" <objects.jsonl || fail "render -j $j failed"
done
cmp -s j1.fits j2.fits || fail "-j 1 and -j 2 differ"
"$BIN/shapesim-render" "${common[@]}" --tile 1 1 512 200 -o low.fits <objects.jsonl || fail "low tile failed"
"$BIN/shapesim-render" "${common[@]}" --tile 1 201 512 512 -o high.fits <objects.jsonl || fail "high tile failed"
python3 - "$tools" <<'PY' || fail "the strips differ from the tiles"
import sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
_, nx, ny, rows = read("j1.fits", "SCI")
_, _, _, low = read("low.fits", "SCI")
_, _, _, high = read("high.fits", "SCI")
assert (nx, ny) == (512, 512), (nx, ny)
assert rows == low + high, "pixels differ"
PY
# One galaxy 10^45 times too bright: its centre is beyond a float.
head -1 objects.jsonl | python3 -c '
import json, sys
o = json.loads(sys.stdin.readline())
o["flux"] *= 1e45
o["coeffs"] = [[a * 1e45, b * 1e45] for a, b in o["coeffs"]]
o.pop("mag", None)
print(json.dumps(o))' >bright.jsonl
"$BIN/shapesim-render" -q --like "$HDF_IMAGE" --noise-free -o bright.fits <bright.jsonl ||
  fail "render of a pixel beyond a float failed"
python3 - "$tools" <<'PY' || fail "the bright image lost its pixels"
import sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
cards, nx, ny, rows = read("bright.fits", "SCI")
assert cards["BITPIX"] == "-64", cards["BITPIX"]
peak = max(max(r) for r in rows)
assert peak > 3.5e38, peak
PY
exit 0
