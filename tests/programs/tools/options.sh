#!/usr/bin/env bash
# One set of option names (issue 18): every program takes its input as the first argument or
# -i/--input and writes its output to stdout or -o/--output (the same bytes); the PSF record is
# --psf wherever a PSF record is read (--psf-field wherever a PSFEx model is); the old names (--psf-model, --out, --k) still give the
# same results, with one warning line each on stderr (none under -q).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
cd "$TMPDIR"
programs=(detect decompose smooth sample lens render measure)
for p in "${programs[@]}"; do
  help=$("$BIN/shapesim-$p" --help)
  for option in '-i \[ --input \]' '-o \[ --output \]' '-q \[ --quiet \]' '-v \[ --verbose \]' \
    '--config FILE' '--print-params'; do
    grep -qE -- "^  $option" <<<"$help" || fail "shapesim-$p --help: no $option"
  done
done
for p in detect decompose render measure; do
  grep -qE -- '^  --psf FILE' <<<"$("$BIN/shapesim-$p" --help)" || fail "shapesim-$p: no --psf FILE"
done
for p in decompose render measure; do
  grep -qE -- '^  --psf-field FILE' <<<"$("$BIN/shapesim-$p" --help)" || fail "shapesim-$p: no --psf-field FILE"
done
for p in detect measure; do
  grep -q -- '--psf-model (now --psf)' <<<"$("$BIN/shapesim-$p" --help)" ||
    fail "shapesim-$p --help does not list the old --psf-model"
done

# The HDF cut's catalogues and a PSF record.
hdf_morphology
"$BIN/shapesim-decompose" -q --psf-image "$HDF_DATA/wfpc2_f814w_tinytim_psf.fits" --like "$HDF_IMAGE" --psf-box 0.0996 0.05 >psf.jsonl ||
  fail "PSF model failed"

# Input: the first argument, -i or stdin; output: stdout or -o, the same bytes.
"$BIN/shapesim-sample" morph.json --area 0.2 --seed 3 -q >a.jsonl || fail "sample failed"
"$BIN/shapesim-sample" -i morph.json --area 0.2 --seed 3 -q -o b.jsonl || fail "sample -i -o failed"
cmp -s a.jsonl b.jsonl || fail "sample: -i/-o differ from argument/stdout"
"$BIN/shapesim-smooth" -q -o m.json <shapelets.jsonl || fail "smooth -o failed"
cmp -s m.json morph.json || fail "smooth: -o differs from stdout"
"$BIN/shapesim-smooth" -q shapelets.jsonl >m1.json || fail "smooth ARG failed"
"$BIN/shapesim-smooth" -q -i shapelets.jsonl -o m2.json || fail "smooth -i failed"
cmp -s m1.json m2.json || fail "smooth: the first argument and -i differ"
"$BIN/shapesim-render" a.jsonl --area 0.2 --noise-free -q -o a.fits || fail "render ARG failed"
"$BIN/shapesim-render" -i a.jsonl --area 0.2 --noise-free -q -o b.fits || fail "render -i failed"
cmp -s a.fits b.fits || fail "render: argument and -i differ"
"$BIN/shapesim-measure" -i "$HDF_IMAGE" --zero-point 22.08 -q -o m1.jsonl || fail "measure -i -o failed"
"$BIN/shapesim-measure" "$HDF_IMAGE" --zero-point 22.08 -q >m2.jsonl || fail "measure failed"
cmp -s m1.jsonl m2.jsonl || fail "measure: -i/-o differ from argument/stdout"
"$BIN/shapesim-detect" -i "$HDF_IMAGE" --zero-point 22.08 -q -o s1.jsonl || fail "detect -i -o failed"
"$BIN/shapesim-detect" "$HDF_IMAGE" --zero-point 22.08 -q >s2.jsonl || fail "detect failed"
cmp -s s1.jsonl s2.jsonl || fail "detect: -i/-o differ from argument/stdout"
"$BIN/shapesim-decompose" -q sources.jsonl -o d.jsonl || fail "decompose ARG -o failed"
cmp -s d.jsonl shapelets.jsonl || fail "decompose: argument/-o differ from stdin/stdout"

# Old names: the same output, one warning each (none with -q).
"$BIN/shapesim-detect" "$HDF_IMAGE" --zero-point 22.08 --psf psf.jsonl -q >new.jsonl || fail "detect --psf failed"
"$BIN/shapesim-detect" "$HDF_IMAGE" --zero-point 22.08 --psf-model psf.jsonl >old.jsonl 2>err ||
  fail "detect --psf-model failed"
cmp -s new.jsonl old.jsonl || fail "detect: --psf-model and --psf differ"
grep -q '^shapesim-detect: warning: --psf-model is now --psf;' err || fail "no warning: $(cat err)"
"$BIN/shapesim-smooth" --lambda-factor 2 -q <shapelets.jsonl >new.json || fail "--lambda-factor failed"
"$BIN/shapesim-smooth" --k 2 -q <shapelets.jsonl >old.json 2>err || fail "--k failed"
cmp -s new.json old.json || fail "smooth: --k and --lambda-factor differ"
[ ! -s err ] || fail "a warning under -q: $(cat err)"
"$BIN/shapesim-measure" --compare a=m1.jsonl b=m2.jsonl -o new -q || fail "measure --compare -o failed"
"$BIN/shapesim-measure" --compare a=m1.jsonl b=m2.jsonl --out old -q || fail "measure --compare --out failed"
for f in table.md distances.md; do cmp -s new/$f old/$f || fail "measure --compare: --out and -o differ in $f"; done
# Old and new together are one option given twice: a usage error.
rc=0; "$BIN/shapesim-smooth" --k 2 --lambda-factor 3 <shapelets.jsonl >out 2>"$TMPDIR/err" || rc=$?
expect_error "$rc" 2 "^shapesim-smooth: .*lambda-factor.*(see --help)$"
