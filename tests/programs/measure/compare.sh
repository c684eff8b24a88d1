#!/usr/bin/env bash
# shapesim-measure --compare: a catalogue against itself gives KS D = 0, p = 1 and Wasserstein 0
# for every statistic, two identical Table rows and the seven figures (when gnuplot is there);
# a copy with 1.5× larger galaxies is told apart in size, not in magnitude; empty,
# single-object and wrong-typed catalogues give one clear line; --paper adds the published
# rows, and a bad one is named.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-measure
cd "$TMPDIR"
"$BIN/$prog" "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" --zero-point 22.08 \
  -j 2 -q >hdf.jsonl || fail "measuring the HDF failed"
"$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl -o same -q 2>err || fail "exit $?: $(cat err)"
python3 - <<'PY' || fail "self-comparison is not null: $(cat same/distances.md)"
rows = [l.strip().strip("|").split("|") for l in open("same/distances.md")][2:]
assert len(rows) == 9, len(rows)
for r in rows:
    d, p, w = (x.strip() for x in r[4:7])
    assert d == "0.000" and float(p) == 1.0 and float(w) == 0.0, r
table = [l.split("|")[2:] for l in open("same/table.md") if l.startswith("| a ") or l.startswith("| b ")]
assert len(table) == 2 and table[0] == table[1], table
PY
grep -q "^| catalogue | N (I ≤ 29) |" same/table.md || fail "the Table does not name the paper's band and cut"
# Another band and cuts (e.g. a K-band survey): the Table and figures say so; a name that would
# break gnuplot's quotes is refused.
"$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl -o k --band Ks --mag-counts 24 --mag-ca 22 -q ||
  fail "--band Ks failed"
grep -q "^| catalogue | N (Ks ≤ 24) |" k/table.md || fail "--band Ks: $(head -n 1 k/table.md)"
grep -q "C and A for Ks ≤ 22" k/table.md || fail "--band Ks: the cuts' note"
grep -q "Ks <= 24" k/figures.gp || fail "--band Ks: the figures' titles"
rc=0
"$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl -o q --band "I'x" >/dev/null 2>"$TMPDIR/err" || rc=$?
expect_error "$rc" 2 "^$prog: --band takes a plain name"
if command -v gnuplot >/dev/null; then
  for f in counts size size_mag ellipticity c_a c_rp a_s; do
    [ "$(head -c 4 "same/$f.png" | tail -c 3)" = "PNG" ] || fail "same/$f.png is not a PNG"
  done
fi
# A copy with every galaxy 1.5× larger is told apart in size (and not in magnitude).
python3 -c 'import json
with open("large.jsonl", "w") as out:
    for line in open("hdf.jsonl"):
        r = json.loads(line)
        if "fwhm" in r: r["fwhm"] *= 1.5
        out.write(json.dumps(r) + "\n")'
"$BIN/$prog" --compare hdf=hdf.jsonl large=large.jsonl -o scaled -q || fail "scaled run failed"
grep '^| fwhm_arcsec | large ' scaled/distances.md | awk -F'|' '{ exit !($7 < 0.001) }' ||
  fail "1.5x larger sizes are not rejected: $(grep '^| fwhm' scaled/distances.md)"
grep '^| mag | large ' scaled/distances.md | awk -F'|' '{ exit !($7 > 0.99) }' ||
  fail "magnitudes differ: $(grep '^| mag' scaled/distances.md)"
# Bad input.
: >empty.jsonl
rc=0; "$BIN/$prog" --compare a=hdf.jsonl b=empty.jsonl -o bad >out 2>err || rc=$?
expect_error "$rc" 1 'empty.jsonl: no records to compare'
head -n 1 hdf.jsonl >one.jsonl
"$BIN/$prog" --compare a=hdf.jsonl one=one.jsonl -o single -q || fail "a one-object catalogue fails"
sed -n 3p hdf.jsonl | sed 's/"c":[-0-9.e]*/"c":"nan"/' >typed.jsonl
rc=0; "$BIN/$prog" --compare a=hdf.jsonl b=typed.jsonl -o bad >out 2>err || rc=$?
expect_error "$rc" 1 'typed.jsonl:1: c'
rc=0; "$BIN/$prog" --compare a=hdf.jsonl -o bad >out 2>err || rc=$?
expect_error "$rc" 2 'at least two catalogues'
rc=0; "$BIN/$prog" --compare hdf.jsonl b=hdf.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 'NAME=FILE'
# --mag-limit measures exactly the records brighter than it, unchanged.
"$BIN/$prog" "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" --zero-point 22.08 \
  --mag-limit 27 -j 2 -q >bright.jsonl || fail "--mag-limit failed"
python3 -c 'import json
full = [l for l in open("hdf.jsonl") if json.loads(l).get("mag") is not None and json.loads(l)["mag"] <= 27]
bright = list(open("bright.jsonl"))
assert bright and bright == full, (len(bright), len(full))' || fail "--mag-limit 27 is not the bright subset"
# The paper's rows: printed beside ours; a wrong-typed or unnamed row is named, and no Table.
paper=$HDF_DATA/../paper/massey2004_table.jsonl
"$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl --paper "$paper" -o withpaper -q || fail "--paper failed"
grep -q '^| paper: HDF-N | – | 3.110 | 0.390 |' withpaper/table.md || fail "no paper row: $(cat withpaper/table.md)"
echo '{"schema":"shapesim.table_row/1","name":"x","c_mean":"3.1"}' >badpaper.jsonl
rc=0; "$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl --paper badpaper.jsonl -o badp >out 2>err || rc=$?
expect_error "$rc" 1 'badpaper.jsonl:1: c_mean'
[ ! -e badp/table.md ] || fail "a Table was written despite a bad --paper row"
echo '{"schema":"shapesim.table_row/1","c_mean":3.1}' >badpaper.jsonl
rc=0; "$BIN/$prog" --compare a=hdf.jsonl b=hdf.jsonl --paper badpaper.jsonl -o badp >out 2>err || rc=$?
expect_error "$rc" 1 'badpaper.jsonl:1: name'
exit 0
