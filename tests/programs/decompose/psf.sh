#!/usr/bin/env bash
# PSF mode: the shipped TinyTim WFPC2 F814W PSF, with the WF pixel and the drizzle drop,
# modelled at the HDF pixel scale with max |residual| below 1% of the peak (issue 4).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
data=$(cd ../../../share/data/hdfn && pwd)
cd "$TMPDIR"
"$BIN/shapesim-decompose" --psf-image "$data/wfpc2_f814w_tinytim_psf.fits" \
  --like "$data/hdfn_f814w_v2.fits" --psf-box 0.0996 0.05 --models psf.fits -q >psf.jsonl ||
  fail "PSF mode failed"
[ "$(wc -l <psf.jsonl)" -eq 1 ] || fail "expected one record"
grep -q '"schema":"shapesim.shapelet/1","id":"psf"' psf.jsonl || fail "not a PSF shapelet record"
grep -q '"flags":\["converged"\]' psf.jsonl || fail "PSF residual target not reached: $(head -c 300 psf.jsonl)"
res=$(grep -o '"psf_max_residual":[0-9.e+-]*' psf.jsonl | cut -d: -f2)
awk -v r="$res" 'BEGIN { exit !(r < 0.01) }' || fail "max residual $res ≥ 1% of the peak"
for plane in data model residual; do
  grep -a -q "EXTNAME = 'psf.$plane'" psf.fits || fail "no psf.$plane HDU"
done
# A cap too low for the residual target: flagged and said on stderr (issue 15).
"$BIN/shapesim-decompose" --psf-image "$data/wfpc2_f814w_tinytim_psf.fits" \
  --like "$data/hdfn_f814w_v2.fits" --psf-box 0.0996 0.05 --psf-n-max-cap 4 >low.jsonl 2>low.err ||
  fail "PSF mode with a low cap failed"
grep -q '"flags":\["residual_above_target"\]' low.jsonl || fail "no residual_above_target flag"
grep -q 'warning: the PSF model misses its residual target' low.err || fail "no warning: $(cat low.err)"
# PSF mode needs a target scale.
rc=0
"$BIN/shapesim-decompose" --psf-image "$data/wfpc2_f814w_tinytim_psf.fits" >out 2>err || rc=$?
expect_error "$rc" 2 "needs --like IMAGE or --pixel-scale"
exit 0
