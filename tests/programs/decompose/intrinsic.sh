#!/usr/bin/env bash
# Forward modelling (--psf): the HDF's brightest galaxies fitted as intrinsic models through
# the TinyTim PSF. Re-convolved (the models file holds the convolution) they match the
# observed-frame models to within the noise: rms difference below 0.5σ a pixel, fluxes within
# 2σ; the records say "frame": "intrinsic"; smooth refuses to mix frames; render refuses an
# intrinsic object without --psf and draws it through the PSF with one.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
data=$(cd ../../../share/data/hdfn && pwd)
tools=$(cd ../tools && pwd)
cd "$TMPDIR"
hdf_sources
"$BIN/shapesim-decompose" --psf-image "$data/wfpc2_f814w_tinytim_psf.fits" \
  --like "$HDF_IMAGE" --psf-box 0.0996 0.05 -q >psf.jsonl || fail "PSF mode failed"
python3 -c 'import json, sys
keep = {"117", "106", "74", "256"}
for l in open("sources.jsonl"):
    if json.loads(l)["id"] in keep: sys.stdout.write(l)' >bright.jsonl
"$BIN/shapesim-decompose" -q -j 2 --models observed.fits <bright.jsonl >observed.jsonl ||
  fail "observed-frame fit failed"
"$BIN/shapesim-decompose" -q -j 2 --psf psf.jsonl --models intrinsic.fits <bright.jsonl \
  >intrinsic.jsonl || fail "intrinsic fit failed"
TOOLS=$tools python3 - <<'PY' || fail "intrinsic and observed-frame models disagree"
import json, math, os, sys
sys.path.insert(0, os.environ["TOOLS"])
from fitsdata import read
def read_image(path, name):
    return read(path, name)[3]
obs = {r["id"]: r for r in map(json.loads, open("observed.jsonl"))}
intr = {r["id"]: r for r in map(json.loads, open("intrinsic.jsonl"))}
assert set(obs) == set(intr) == {"117", "106", "74", "256"}, (set(obs), set(intr))
for i in obs:
    o, n = obs[i], intr[i]
    assert n["frame"] == "intrinsic" and "frame" not in o, i
    assert n["psf_n_max"] > 0 and n["psf_beta"] > 0, i
    # The intrinsic model is narrower than the observed one: the PSF is taken out.
    assert n["beta_pix"] < o["beta_pix"], (i, n["beta_pix"], o["beta_pix"])
    assert abs(n["flux"] - o["flux"]) < 2 * math.hypot(n["flux_err"], o["flux_err"]), i
    a = read_image("observed.fits", i + ".model")
    b = read_image("intrinsic.fits", i + ".model")
    sigma = o["noise_rms"]
    d = [(x - y) / sigma for ra, rb in zip(a, b) for x, y in zip(ra, rb)]
    rms = math.sqrt(sum(v * v for v in d) / len(d))
    print(f"  [measured] {i}: rms (intrinsic ⊗ PSF − observed) / σ = {rms:.3f}", file=sys.stderr)
    assert rms < 0.5, (i, rms)
PY
# One frame per morphology model.
cat observed.jsonl intrinsic.jsonl >mixed.jsonl
rc=0; "$BIN/shapesim-smooth" --require '' --reject '' <mixed.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'one morphology model holds one frame'
# Render: an intrinsic object needs --psf, and is drawn through it.
"$BIN/shapesim-smooth" -q --delta --reject '' --area 0.1 <intrinsic.jsonl >delta.json ||
  fail "smooth of intrinsic models failed"
grep -q '"frame":"intrinsic"' delta.json || fail "the morphology model lost the frame"
"$BIN/shapesim-sample" -q delta.json --size 0.2 --pixel-scale 0.03985 --count 3 --seed 1 \
  >objects.jsonl || fail "sample failed"
grep -q '"frame":"intrinsic"' objects.jsonl || fail "the objects lost the frame"
rc=0; "$BIN/shapesim-render" --size 0.2 --pixel-scale 0.03985 --noise-free -o nopsf.fits \
  <objects.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 'intrinsic model: give --psf'
[ ! -e nopsf.fits ] || fail "an image was written without the PSF"
"$BIN/shapesim-render" -q --size 0.2 --pixel-scale 0.03985 --noise-free --psf psf.jsonl \
  --galaxy-psf psf.jsonl -o drawn.fits <objects.jsonl || fail "render through the PSF failed"
exit 0
