#!/usr/bin/env bash
# A runaway model (issue 39): a galaxy of β = 10⁶″ (and 100″) on a 300² field is drawn with
# the field's pixels at most, not its nominal stamp (once 9.7 GB for 10⁶″, 3 GB for 100″): the
# render's peak memory stays under 200 MiB, and two tiles still add up to the whole image. A
# line without end (300 MB of NUL bytes) is one error line, not unbounded memory.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
field=(--pixels 300 --pixel-scale 0.2 --ra 150.1 --dec 2.2 --psf-analytic moffat:0.7 --noise-free)
for beta in 1e6 100; do
  printf '{"schema":"shapesim.object/1","id":"g0","kind":"galaxy","ra":150.1,"dec":2.2,"mag":20,"flux":1000,"beta":%s,"pixel_scale":0.2,"n_max":2,"coeffs":[[1,0],[0,0],[0.3,0],[0.1,0.05]]}\n' \
    "$beta" >b$beta.jsonl
  "$BIN/shapesim-render" b$beta.jsonl "${field[@]}" -o b$beta.fits 2>err || fail "beta $beta: $(cat err)"
  mib=$(sed -n 's/.*peak memory \([0-9.]*\) MiB.*/\1/p' err)
  [ -n "$mib" ] || fail "no peak memory line: $(cat err)"
  python3 -c "import sys; sys.exit(0 if float('$mib') < 200 else 1)" || fail "beta $beta: peak memory $mib MiB"
  "$BIN/shapesim-render" b$beta.jsonl "${field[@]}" -q --tile 1 1 300 120 -o low$beta.fits || fail "low tile"
  "$BIN/shapesim-render" b$beta.jsonl "${field[@]}" -q --tile 1 121 300 300 -o high$beta.fits || fail "high tile"
  python3 - "$tools" $beta <<'PY' || fail "beta $2: tiles differ from the whole"
import sys
sys.path.insert(0, sys.argv[1])
from fitsdata import read
b = sys.argv[2]
_, nx, ny, whole = read(f"b{b}.fits", "SCI")
_, _, _, low = read(f"low{b}.fits", "SCI")
_, _, _, high = read(f"high{b}.fits", "SCI")
assert whole == low + high, "pixels differ"
assert max(max(r) for r in whole) > 0, "nothing drawn"
PY
done

# n_max past the records' cap (200) is refused where the record is read, before any work.
python3 -c "
import json
print(json.dumps({'schema': 'shapesim.object/1', 'id': 'g0', 'kind': 'galaxy', 'ra': 150.1, 'dec': 2.2,
                  'mag': 20, 'flux': 1000, 'beta': 1.0, 'pixel_scale': 0.2, 'n_max': 1000,
                  'coeffs': [[1, 0]] + [[0, 0]] * 251000}))" >n1000.jsonl
rc=0; "$BIN/shapesim-render" n1000.jsonl "${field[@]}" -q -o n.fits >out 2>err || rc=$?
expect_error "$rc" 1 "^shapesim-render: n1000.jsonl:1: n_max: must be in \\[0, 200\\], got 1000$"
[ ! -e n.fits ] || fail "a refused n_max left n.fits"

# Input without a newline is refused once a line passes 256 MiB, not buffered without limit.
rc=0; head -c 300000000 /dev/zero | "$BIN/shapesim-render" "${field[@]}" -q -o z.fits >out 2>err || rc=$?
expect_error "$rc" 1 "^shapesim-render: -:1: a line longer than 256 MiB: not a JSON-lines catalogue"
[ ! -e z.fits ] || fail "a refused input left z.fits"
exit 0
