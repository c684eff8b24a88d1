#!/usr/bin/env bash
# shapesim-table (issue 37): a JSON-lines catalogue as a FITS binary table and as ECSV, read
# back by astropy (an independent reader) with every value, type and unit; nulls as NaN; a
# nested object flattened, flags joined, coefficient arrays left out and named; the FITS file
# passes fitsverify; the same input gives the same bytes. Bad input: one line, exit 1 or 2,
# nothing written.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
check_help shapesim-table
check_version shapesim-table
cd "$TMPDIR"

cat >cat.jsonl <<'J'
{"schema":"shapesim.truth/1","id":"g0","kind":"galaxy","ra":150.1,"dec":2.2,"x":10.5,"y":3,"flux":12.5,"mag":24.0,"e1":0.1,"n_max":4,"flags":["a","b"],"psf":{"beta":0.3,"n":2},"coeffs":[[1,0],[0.5,0.1]]}
{"schema":"shapesim.truth/1","id":"s 1","kind":"star","ra":150.2,"dec":-2.2,"x":1,"y":2.25,"flux":7,"mag":null,"n_max":0,"flags":[],"ok":true}
J
"$BIN/shapesim-table" cat.jsonl -o cat.fits --flux-unit electron/s 2>err || fail "FITS: $(cat err)"
grep -q "left out coeffs" err || fail "coeffs not named: $(cat err)"
"$BIN/shapesim-table" -q --flux-unit electron/s <cat.jsonl >cat.ecsv || fail "ECSV failed"
"$BIN/shapesim-table" -q cat.jsonl -o again.fits --flux-unit electron/s || fail "second run failed"
cmp cat.fits again.fits || fail "not the same bytes"
if command -v fitsverify >/dev/null; then
  fitsverify -q cat.fits | grep -q "^verification OK" || fail "fitsverify: $(fitsverify cat.fits | tail -5)"
fi

/usr/bin/python3 - <<'PY' || fail "astropy read the tables otherwise"
import math, warnings
warnings.simplefilter("error")
from astropy.table import Table
for name in ("cat.fits", "cat.ecsv"):
    # electron is no FITS-standard unit: astropy warns on the FITS table's flux and keeps it.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore" if name.endswith("fits") else "error",
                                message="'electron/s' did not parse as fits unit")
        t = Table.read(name)
    assert t.colnames == ["id", "kind", "ra", "dec", "x", "y", "flux", "mag", "e1", "n_max",
                          "flags", "psf_beta", "psf_n", "ok"], (name, t.colnames)
    units = {c: str(t[c].unit) if t[c].unit is not None else "" for c in t.colnames}
    # astropy masks a FITS table's NaN: fill the mask back with NaN.
    t = Table([t[c].filled(math.nan) if getattr(t[c], "mask", None) is not None and t[c].dtype.kind == "f"
               else t[c] for c in t.colnames], meta=t.meta)
    assert units["ra"] == "deg" and units["x"] == "pix" and units["mag"] == "mag", units
    assert units["flux"] in ("electron / s", "electron/s") and units["psf_beta"] == "arcsec", units
    assert units["e1"] == "" and units["n_max"] == "", units
    assert list(t["id"]) == ["g0", "s 1"] and list(t["kind"]) == ["galaxy", "star"]
    assert list(t["ra"]) == [150.1, 150.2] and list(t["dec"]) == [2.2, -2.2]
    assert list(t["y"]) == [3.0, 2.25] and t["y"].dtype.kind == "f", t["y"].dtype
    assert t["n_max"].dtype.kind == "i" and list(t["n_max"]) == [4, 0]
    assert t["mag"][0] == 24.0 and math.isnan(t["mag"][1]), list(t["mag"])
    assert t["e1"][0] == 0.1 and math.isnan(t["e1"][1])
    flags = t["flags"].filled("") if hasattr(t["flags"], "filled") else t["flags"]
    assert list(flags) == ["a,b", ""], list(t["flags"])  # an empty text: masked in FITS
    assert t["psf_beta"][0] == 0.3 and math.isnan(t["psf_beta"][1])
    assert t["ok"][1] == 1.0 and math.isnan(t["ok"][0]), list(t["ok"])  # a null: real
    assert t.meta.get("schema", t.meta.get("SCHEMA")) == "shapesim.truth/1", t.meta
print("astropy: FITS and ECSV agree with the records")
PY

# Bad input: one line, nothing written.
printf '{"schema":"shapesim.truth/1","id":"a","n":1}\n{"schema":"shapesim.object/1","id":"b"}\n' >mixed.jsonl
rc=0; "$BIN/shapesim-table" mixed.jsonl -o mixed.fits >out 2>err || rc=$?
expect_error "$rc" 1 "mixed.jsonl:2: schema: schema shapesim.object/1 in a table of shapesim.truth/1"
[ ! -e mixed.fits ] || fail "a refused table left mixed.fits"
printf '{"schema":"s/1","id":"a"}\n{"schema":"s/1","id":7}\n' >types.jsonl
rc=0; "$BIN/shapesim-table" types.jsonl -o types.ecsv >out 2>err || rc=$?
expect_error "$rc" 1 "types.jsonl:2: id: a number in a column of text"
[ ! -e types.ecsv ] || fail "a refused table left types.ecsv"
rc=0; "$BIN/shapesim-table" cat.jsonl -o cat.txt >out 2>err || rc=$?
expect_error "$rc" 2 "cannot tell the format from 'cat.txt': give --format fits|ecsv"
rc=0; "$BIN/shapesim-table" cat.jsonl --format fits >out 2>err || rc=$?
expect_error "$rc" 2 "a FITS table needs a file"
rc=0; "$BIN/shapesim-table" -o e.ecsv </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 "no record to write"
[ ! -e e.ecsv ] || fail "an empty input left e.ecsv"
exit 0
