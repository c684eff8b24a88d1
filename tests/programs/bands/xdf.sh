#!/usr/bin/env bash
# Several bands end to end on a 160² corner of the shipped XDF (issue 17): detect --bands
# measures every band in the detection's apertures and cuts its stamps in the same boxes;
# decompose fits the bands jointly (one centre, beta, n_max; the reference band the record's
# own); smooth --delta and sample carry every band; render --band draws each band with its own
# noise. Bad band input: one stderr line, exit 1, no output file.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
xdf=$(cd ../../../share/data/xdf && pwd)
cd "$TMPDIR"
cut='[200:359,200:359]'
for b in f435w f814w f160w; do
  case $b in f814w) ext=fits zp=25.959 ;; f435w) ext=fits.gz zp=25.684 ;; f160w) ext=fits.gz zp=25.946 ;; esac
  printf '{"schema":"shapesim.band/1","band":"%s","image":"%s","weight":"%s","zero_point":%s}\n' \
    $b "$xdf/${b}_sci.$ext$cut" "$xdf/${b}_wht.$ext$cut" $zp
done > bands.jsonl

"$BIN/shapesim-detect" -q "$xdf/detection_sci.fits.gz$cut" --weight "$xdf/detection_wht.fits.gz$cut" \
  --pixel-scale 0.06 --bands bands.jsonl --stamps stamps.fits > sources.jsonl || fail "detect --bands failed"
/usr/bin/python3 - <<'PY' || fail "detect --bands records"
import json
rows = [json.loads(l) for l in open("sources.jsonl")]
assert len(rows) >= 30, len(rows)
for r in rows:
    names = [b["band"] for b in r["bands"]]
    assert names == ["f435w", "f814w", "f160w"], names
    for b in r["bands"]:
        assert b["stamp_hdu"] == r["id"] + "." + b["band"], b
        assert b["flux_err"] > 0 and "flux_inner" in b
# Brighter galaxies: positive fluxes in every band.
bright = [r for r in rows if r["bands"][1]["flux"] > 10 * r["bands"][1]["flux_err"]]
assert len(bright) >= 5, len(bright)
PY

"$BIN/shapesim-decompose" -q -j 2 --reference-band f814w < sources.jsonl > joint.jsonl || fail "joint decompose failed"
/usr/bin/python3 - <<'PY' || fail "joint records"
import json, math
rows = [json.loads(l) for l in open("joint.jsonl")]
src = {json.loads(l)["id"]: json.loads(l) for l in open("sources.jsonl")}
assert len(rows) >= 30
ratios = []
for r in rows:
    assert r["band"] == "f814w" and [b["band"] for b in r["bands"]] == ["f814w", "f435w", "f160w"]
    ref = r["bands"][0]
    assert ref["coeffs"] == r["coeffs"] and abs(ref["flux"] - r["flux"]) <= 1e-12 * abs(r["flux"])
    assert abs(r["zero_point"] - 25.959) < 1e-12
    for b in r["bands"]:
        assert len(b["coeffs"]) == len(r["coeffs"]) and len(b["coeff_errors"]) == len(r["coeffs"])
        s = {x["band"]: x for x in src[r["id"]]["bands"]}[b["band"]]
        if s["flux"] > 10 * s["flux_err"] and "neighbour" not in r["flags"]:
            ratios.append(b["flux"] / s["flux"])
ratios.sort()
median = ratios[len(ratios) // 2]
# The models' fluxes against the forced Kron fluxes: the Kron aperture misses a few per cent.
assert len(ratios) >= 5 and 0.95 < median < 1.2, (len(ratios), median)
PY

# --band-psf: that band is fitted through its PSF (the star's, from F814W), the others as seen.
"$BIN/shapesim-decompose" -q --psf-image "$xdf/f814w_sci.fits[87:145,352:410]" --psf-pixel-scale 0.06 \
  --pixel-scale 0.06 > psf.jsonl || fail "PSF mode failed"
"$BIN/shapesim-decompose" -q -j 2 --reference-band f814w --band-psf f160w=psf.jsonl \
  < sources.jsonl > psf.joint.jsonl || fail "--band-psf failed"
/usr/bin/python3 - <<'PY' || fail "--band-psf did not change the F160W fits"
import json
plain = [json.loads(l) for l in open("joint.jsonl")]
through = [json.loads(l) for l in open("psf.joint.jsonl")]
assert len(plain) == len(through)
changed = sum(a["bands"][2]["coeffs"] != b["bands"][2]["coeffs"] for a, b in zip(plain, through))
assert changed >= len(plain) // 2, changed
PY

# A bands file of one band: every record carries that band; --no-bands fits the detection image.
sed -n 2p bands.jsonl > one.jsonl
"$BIN/shapesim-detect" -q "$xdf/detection_sci.fits.gz$cut" --weight "$xdf/detection_wht.fits.gz$cut" \
  --pixel-scale 0.06 --bands one.jsonl --stamps one.fits > one.sources.jsonl || fail "one band: detect"
"$BIN/shapesim-decompose" -q < one.sources.jsonl > one.joint.jsonl || fail "one band: decompose"
"$BIN/shapesim-decompose" -q --no-bands < one.sources.jsonl > none.jsonl || fail "--no-bands failed"
/usr/bin/python3 - <<'PY' || fail "one-band records"
import json
one = [json.loads(l) for l in open("one.joint.jsonl")]
none = [json.loads(l) for l in open("none.jsonl")]
assert len(one) == len(none) >= 30
assert all([b["band"] for b in r["bands"]] == ["f814w"] and r["band"] == "f814w" for r in one)
assert all("bands" not in r for r in none)
PY

"$BIN/shapesim-smooth" -q --delta --reject edge,noise < joint.jsonl > delta.json || fail "smooth failed"
# The parents' flux ratios: as measured with --keep-colour-noise, deconvolved from their noise
# by default (no band's spread larger, the noisiest's smaller).
"$BIN/shapesim-smooth" -q --delta --reject edge,noise --keep-colour-noise < joint.jsonl > noisy.json \
  || fail "smooth --keep-colour-noise failed"
/usr/bin/python3 - <<'PY' || fail "colour deconvolution"
import json, statistics
records = {r["id"]: r for r in map(json.loads, open("joint.jsonl"))}
# Packed polar order: n = 0, 1, …; m = n mod 2, …, n in steps of 2. The (even n, m = 0) slots.
EVEN, k = set(), 0
for n in range(40):
    for m in range(n % 2, n + 1, 2):
        if m == 0:
            EVEN.add(k)
        k += 1
def ratios(name):
    m = json.load(open(name))
    bands = [b["band"] for b in m["bands"]]
    out = {b: [] for b in bands}
    for p in m["points"]:
        even = lambda shape: sum(c[0] for k, c in enumerate(shape) if k in EVEN)
        for b, shape in zip(bands, p["bands"]):
            out[b].append(even(shape) / even(p["shape"]))
    return m, out
noisy, raw = ratios("noisy.json")
clean, denoised = ratios("delta.json")
assert noisy["provenance"]["options"]["keep_colour_noise"] is True
assert clean["provenance"]["options"]["keep_colour_noise"] is False
ids = [p["id"] for p in noisy["points"]]
for b, values in raw.items():
    for i, v in zip(ids, values):
        f = {x["band"]: x["flux"] for x in records[i]["bands"]}
        assert abs(v - f[b] / f["f814w"]) <= 1e-9 * abs(v) + 1e-12, (b, i)
assert denoised["f814w"] == raw["f814w"]
narrower = 0
for b in raw:
    if b == "f814w":
        continue
    s0, s1 = statistics.stdev(raw[b]), statistics.stdev(denoised[b])
    assert s1 <= s0 * 1.0001, (b, s0, s1)
    narrower += s1 < 0.8 * s0
assert narrower >= 1, narrower  # F160W's, its noisiest: about halved
PY
"$BIN/shapesim-sample" -q delta.json --size 0.16 --pixel-scale 0.06 --seed 3 --zero-point 25.959 \
  > objects.jsonl || fail "sample failed"
for b in f435w f814w f160w; do
  "$BIN/shapesim-render" -q --band $b --noise-rms 0.001 --size 0.16 --pixel-scale 0.06 --seed 3 \
    -o $b.fits --truth $b.truth.jsonl < objects.jsonl || fail "render --band $b failed"
  grep -a "BAND    = '$b" $b.fits >/dev/null || fail "$b.fits: no BAND keyword"
done
"$BIN/shapesim-render" -q --band f435w --noise-free --size 0.16 --pixel-scale 0.06 --seed 3 \
  -o clean.fits --truth clean.truth.jsonl < objects.jsonl || fail "noise-free render failed"
/usr/bin/python3 - <<'PY' || fail "per-band truth"
import json, math
objs = {json.loads(l)["id"]: json.loads(l) for l in open("objects.jsonl")}
for band in ("f435w", "f814w", "f160w"):
    for l in open(band + ".truth.jsonl"):
        t = json.loads(l)
        b = {x["band"]: x for x in objs[t["id"]]["bands"]}[band]
        # The truth's flux is the image's: the model's, plus the negative light clipped.
        drawn = t["flux"] - t.get("clipped_flux", 0.0)
        assert abs(drawn - b["flux"]) <= 1e-9 * abs(t["flux"]) + 1e-12, (band, t["id"])
PY
# Each band its own noise realisation of the one seed.
cmp -s f435w.fits f814w.fits && fail "two bands drew the same image"

# Bad band input.
bad() {
  local want=$1 rc=0
  shift
  "$@" >out 2>err || rc=$?
  expect_error "$rc" 1 "$want"
}
bad "^shapesim-render: .*object .* has no band \"u\"" \
  "$BIN/shapesim-render" --band u --size 0.16 --pixel-scale 0.06 -o u.fits -i objects.jsonl
[ ! -e u.fits ] || fail "render left u.fits behind"
rc=0
"$BIN/shapesim-decompose" --band-psf f160w -i sources.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 "^shapesim-decompose: --band-psf takes NAME=FILE"  # a usage error
bad "^shapesim-decompose: .*no band k (--reference-band)" \
  "$BIN/shapesim-decompose" --reference-band k -i sources.jsonl
{ head -1 bands.jsonl; head -1 bands.jsonl; } > twice.jsonl
bad "^shapesim-detect: twice.jsonl:2: band: band \"f435w\" appears twice" \
  "$BIN/shapesim-detect" -q "$xdf/detection_sci.fits.gz$cut" --pixel-scale 0.06 --bands twice.jsonl --stamps s2.fits
sed 's/f160w_sci/f999w_sci/' bands.jsonl > missing.jsonl
bad "^shapesim-detect: .*f999w_sci" \
  "$BIN/shapesim-detect" -q "$xdf/detection_sci.fits.gz$cut" --pixel-scale 0.06 --bands missing.jsonl --stamps s3.fits
[ ! -e s2.fits ] && [ ! -e s3.fits ] || fail "detect left a stamps file behind"
printf '{"schema":"shapesim.band/1","band":"x","image":"%s"}\n' "$xdf/f435w_sci.fits.gz" > big.jsonl
bad "^shapesim-detect: .*band x: the band image is 500×500 pixels but the detection image 160×160" \
  "$BIN/shapesim-detect" -q "$xdf/detection_sci.fits.gz$cut" --pixel-scale 0.06 --bands big.jsonl
exit 0
