#!/usr/bin/env bash
# Fields the project was not tuned on, through detect → decompose → smooth → sample → render →
# measure with the README's options only (issue 15): the shipped XDF F814W cutout (a bare
# header: no WCS, no zero point) and a ground-based frame (the same cutout through 0.8″ seeing,
# 0.24″ pixels, a 55 000 ADU sky left in, BITPIX 16 with BSCALE/BZERO: tests/examples/ground).
# Each field's δ-function simulation must give its galaxies back: the counts and the bright
# end's magnitudes of the real and simulated images, measured alike, agree.
source ../lib.sh
xdf=$(cd ../../../share/data/xdf && pwd)
cd "$TMPDIR"

# field NAME IMAGE STAR_SECTION [OPTIONS...]: the whole chain on IMAGE, its PSF from the star
# in STAR_SECTION; OPTIONS (pixel scale, weight, zero point, gain) go to detect and measure.
field() {
  local name=$1 image=$2 star=$3
  shift 3
  local like=(--like "$image") psf_scale=()
  if [[ " $* " == *" --pixel-scale "* ]]; then  # a bare header: the scale goes everywhere
    local scale
    scale=$(sed 's/.*--pixel-scale \([^ ]*\).*/\1/' <<<"$*")
    like+=(--pixel-scale "$scale")
    psf_scale=(--psf-pixel-scale "$scale")
  fi
  mkdir "$name" && cd "$name"
  "$BIN/shapesim-decompose" -q --psf-image "$image$star" "${psf_scale[@]}" "${like[@]}" >psf.jsonl ||
    fail "$name: PSF failed"
  "$BIN/shapesim-detect" -q "$image" "$@" --psf psf.jsonl --stamps stamps.fits \
    --stars stars.jsonl --noise-model noise.jsonl >sources.jsonl || fail "$name: detect failed"
  "$BIN/shapesim-decompose" -q -j 2 --psf psf.jsonl --stars stars.jsonl <sources.jsonl \
    >intrinsic.jsonl || fail "$name: decompose failed"
  "$BIN/shapesim-smooth" -q --delta "${like[@]}" <intrinsic.jsonl >delta.json ||
    fail "$name: smooth failed"
  "$BIN/shapesim-sample" -q delta.json "${like[@]}" --seed 7 >objects.jsonl ||
    fail "$name: sample failed"
  "$BIN/shapesim-render" -q --psf psf.jsonl --noise-model noise.jsonl "${like[@]}" --seed 7 \
    -o delta.fits <objects.jsonl || fail "$name: render failed"
  "$BIN/shapesim-measure" -q "$image" "$@" --psf psf.jsonl >real.morph.jsonl ||
    fail "$name: measure (real) failed"
  "$BIN/shapesim-measure" -q delta.fits --psf psf.jsonl >delta.morph.jsonl ||
    fail "$name: measure (δ) failed"
  cd ..
}

field xdf "$xdf/f814w_sci.fits" '[87:145,352:410]' --weight "$xdf/f814w_wht.fits" \
  --pixel-scale 0.06 --zero-point 25.959 --gain 50800
"$EXAMPLES/ground" "$xdf/f814w_sci.fits" ground.fits 0.06 25.959 0.8 4 15.3 7200 2 ||
  fail "ground: the frame could not be made"
field ground "$TMPDIR/ground.fits" '[14:45,80:111]'

# Real vs δ, measured alike (stars, stellarity > 0.9, left out). The δ simulation draws the
# kept models at the field's density, with replacement, so: the counts agree within Poisson
# (2σ + 1), and every δ galaxy brighter than 24 is a kept model's (within 0.2 mag), or a blend
# of drawn kept models (their light within 15 pixels, to 0.3 mag; seed 7 puts an I = 25.6
# galaxy 10 pixels from a copy of the XDF's I = 23.8 one): nothing bright is invented and no
# rejected model is drawn. The ground frame's brightest galaxy (the
# XDF's I = 20.3 spiral through the seeing) is modelled and kept, its magnitude within 0.15 of
# the measured one. On the XDF itself it is not yet: its fit stops at the n_max cap with χ²_r
# 5.2, is flagged bad_fit, and smooth leaves it out (issue 14).
python3 - <<'PY' || fail "the δ simulations do not give the fields back"
import json, math
rejected = {"edge", "bright_star", "saturated", "noise", "bad_fit", "holes", "unsupported"}
def mags(path):
    return sorted(r["mag"] for r in map(json.loads, open(path))
                  if r.get("mag") is not None and r["stellarity"] <= 0.9)
for name, limit in (("xdf", 27.0), ("ground", 25.0)):
    real, delta = mags(name + "/real.morph.jsonl"), mags(name + "/delta.morph.jsonl")
    kept = sorted(r["mag"] for r in map(json.loads, open(name + "/intrinsic.jsonl"))
                  if r.get("mag") is not None and not rejected & set(r["flags"]))
    n_real, n_delta = sum(m <= limit for m in real), sum(m <= limit for m in delta)
    print(f"{name}: {n_real} real, {n_delta} δ galaxies to {limit}; brightest real {real[:3]}, "
          f"δ {delta[:3]}, kept models {kept[:3]}")
    assert n_real >= 4, (name, "too few real galaxies", n_real)
    assert abs(n_delta - n_real) <= 2 * math.sqrt(n_real) + 1, (name, n_real, n_delta)
    # A δ galaxy brighter than 24 is a kept model's, or (random positions blend the draws) the
    # light of the drawn objects within 15 pixels of it together.
    drawn = [json.loads(l) for l in open(name + "/objects.jsonl")]
    for r in map(json.loads, open(name + "/delta.morph.jsonl")):
        if r.get("mag") is None or r["stellarity"] > 0.9 or r["mag"] >= 24:
            continue
        m = r["mag"]
        if min(abs(m - k) for k in kept) < 0.2:
            continue
        near = [o["mag"] for o in drawn if math.hypot(o["x"] - r["x"], o["y"] - r["y"]) < 15]
        together = -2.5 * math.log10(sum(10 ** (-0.4 * k) for k in near)) if near else 99
        assert abs(m - together) < 0.3 and all(min(abs(k - q) for q in kept) < 1e-6 for k in near
                                               if k < 24), (name, "δ galaxy of no kept model", m, near)
    if name == "ground":
        assert abs(kept[0] - real[0]) < 0.15, (name, real[0], kept[0])
PY

# The ground frame's PSF: its sky (≈ 55 000 ADU) was removed before the fit, and the model's
# FWHM is the seeing's, broadened by the XDF's own PSF and the 0.24″ pixel (0.8–1.0″).
python3 - <<'PY' || fail "the ground-based PSF is wrong"
import json, math
psf = json.loads(open("ground/psf.jsonl").readline())
fwhm = 2 * math.sqrt(2 * math.log(2)) * psf["beta"]  # the n_max 0 term's FWHM
assert 0.8 <= fwhm <= 1.0, fwhm
assert "converged" in psf["flags"], psf["flags"]
PY
