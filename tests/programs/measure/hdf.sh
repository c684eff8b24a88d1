#!/usr/bin/env bash
# shapesim-measure on the shipped HDF cut: one shapesim.morph/1 record per galaxy that
# shapesim-detect finds (same ids, same detection), C, A, S, Gini, M20 where measurable,
# identical output for -j 1 and -j 2 and for the asymmetry's AVX2 lanes and scalar code
# (SHAPESIM_SIMD=none); bad input fails with one line.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-measure
cd "$TMPDIR"
hdf_sources
weight=$HDF_DATA/hdfn_f814w_v2_weight.fits
"$BIN/$prog" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 -j 2 >morph.jsonl 2>err ||
  fail "exit $?: $(cat err)"
"$BIN/$prog" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 -j 1 -q >morph1.jsonl ||
  fail "-j 1 failed"
cmp -s morph.jsonl morph1.jsonl || fail "-j 1 and -j 2 differ"
SHAPESIM_SIMD=none "$BIN/$prog" "$HDF_IMAGE" --weight "$weight" --zero-point 22.08 -j 2 -q \
  >morph_scalar.jsonl || fail "SHAPESIM_SIMD=none failed"
cmp -s morph.jsonl morph_scalar.jsonl || fail "the AVX2 lanes and the scalar code differ"
python3 - <<'PY' || fail "the records break the checks"
import json
src = [json.loads(l) for l in open("sources.jsonl")]
rows = [json.loads(l) for l in open("morph.jsonl")]
assert [r["id"] for r in rows] == [s["id"] for s in src], "ids differ from shapesim-detect's"
for r, s in zip(rows, src):
    assert r["schema"] == "shapesim.morph/1"
    assert abs(r["x"] - s["x"]) < 1e-9 and abs(r["mag"] - s["mag"]) < 1e-9, r["id"]
bright = [r for r in rows if r["mag"] < 25]
assert len(bright) >= 4, len(bright)
for r in bright:
    for key in ("r_petro", "c", "a_sym", "s", "gini", "m20", "e1", "e2"):
        assert key in r, (r["id"], key)
    assert 1.5 < r["c"] < 6 and -0.2 < r["a_sym"] < 1.5 and 0 < r["gini"] < 1, r
    assert "small" not in r["flags"] and "faint" not in r["flags"], r
faint = [r for r in rows if "faint" in r["flags"]]
assert faint, "no faint flags on the HDF's faintest objects"
PY
rc=0; "$BIN/$prog" nosuch.fits >out 2>err || rc=$?
expect_error "$rc" 1 'nosuch.fits'
rc=0; "$BIN/$prog" "$HDF_IMAGE" --min-snr -1 >out 2>err || rc=$?
expect_error "$rc" 2 'min-snr'
exit 0
