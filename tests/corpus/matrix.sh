#!/usr/bin/env bash
# The bad- and odd-input matrix (issue 15): every program on every case of the corpus.
#
#   tests/corpus/matrix.sh BIN [CORPUS_DIR] > matrix.md
#
# A case passes when the program either gives a result (exit 0; JSON output that parses, a
# FITS output that is whole) or fails cleanly: exit 1 or 2, exactly one line on stderr (under
# -q), no output file left behind. Anything else (a signal, a timeout, a sanitizer report, a
# second stderr line, an output file left by a failed run) is a FAIL: the script prints the
# matrix (Markdown: one row per case, one column per program) and exits 1 if any cell FAILs.
# The FITS cases are tests/corpus/cases/ (make corpus writes them); the JSON cases are its
# *.jsonl files plus, per program, its own valid input changed by mutate.py.
set -uo pipefail
shopt -s nullglob
BIN=$(cd "$1" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
corpus=$(cd "${2:-$here/cases}" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
ln -s "$corpus"/* .  # messages name the files as the corpus does
mkdir base

die() { echo "matrix.sh: $*" >&2; exit 1; }

# The valid inputs every JSON case is derived from, made by the programs from good.fits.
"$BIN/shapesim-detect" good.fits -q --stamps base/stamps.fits >base/sources.jsonl ||
  die "detect on good.fits failed"
"$BIN/shapesim-decompose" -q --psf-image 'good.fits[89:113,97:121]' --pixel-scale 0.04 \
  >base/psf.jsonl || die "the PSF of good.fits failed"
"$BIN/shapesim-decompose" -q --stamps base/stamps.fits <base/sources.jsonl >base/shapelets.jsonl ||
  die "decompose on good.fits failed"
"$BIN/shapesim-smooth" -q --like good.fits <base/shapelets.jsonl >base/model.json ||
  die "smooth failed"
"$BIN/shapesim-sample" -q base/model.json --like good.fits --seed 1 >base/objects.jsonl ||
  die "sample failed"
"$BIN/shapesim-measure" -q good.fits >base/morph.jsonl || die "measure failed"

failures=0
notes=()

# A message as the matrix shows it: `|` escaped for Markdown, and what depends on the bytes of
# an input rather than on the case (a JSON column, a fitted value printed to 17 digits)
# replaced by N and X, so the matrix does not move with the version string or a refit.
message() { sed -E 's/\|/\\|/g; s/column [0-9]+/column N/g; s/-?[0-9]+\.[0-9]{6,}(e[-+]?[0-9]+)?/X/g'; }

# run COLUMN CASE ARGS...: run one program (ARGS[0]) and set $cell to its verdict. A result is
# "ok N" (N records, or "ok" for an image); a clean failure is "error" with its message noted.
run() {
  local column=$1 case=$2 prog=$3 rc
  shift 3
  rm -rf out && mkdir out
  timeout 300 "$BIN/shapesim-$prog" -q "$@" >out.stdout 2>out.stderr
  rc=$?
  local lines
  lines=$(wc -l <out.stderr)
  if grep -qE 'Sanitizer|runtime error|terminate called|Assertion|Segmentation' out.stderr; then
    cell="**FAIL** (crash report)"
  elif [ "$rc" -eq 124 ]; then
    cell="**FAIL** (timeout)"
  elif [ "$rc" -ge 128 ]; then
    cell="**FAIL** (signal $((rc - 128)))"
  elif [ "$rc" -ne 0 ]; then
    if [ "$rc" -gt 2 ]; then
      cell="**FAIL** (exit $rc)"
    elif [ "$lines" -ne 1 ]; then
      cell="**FAIL** ($lines stderr lines)"
    elif [ -n "$(ls -A out)" ]; then
      cell="**FAIL** (left $(ls -A out | tr '\n' ' '))"
    else
      cell="error"
      notes+=("| $case | $column | \`$(message <out.stderr)\` |")
      return
    fi
  elif ! python3 "$here/check_output.py" out.stdout out/* >out.check 2>&1; then
    cell="**FAIL** (output: $(head -c 80 out.check))"
  else
    cell="ok $(cat out.check)"
    [ "$lines" -eq 0 ] || notes+=("| $case | $column | \`$(head -n 1 out.stderr | message)\` |")
    return
  fi
  failures=$((failures + 1))
  notes+=("| $case | $column | $cell: \`$(head -c 300 out.stderr | tr '\n' ' ' | sed 's/|/\\|/g')\` |")
}

# detect_and_decompose CASE NAME DETECT_ARGS...: two cells, detect's and (on its stamps)
# decompose's, or "—" when detect made no stamps.
detect_and_decompose() {
  local case=$1 name=$2
  shift 2
  run detect "$case" detect "$@" --stamps out/stamps.fits
  cells+=("$cell")
  if [ "$cell" != error ] && [ -s out/stamps.fits ]; then
    cp out/stamps.fits "stamps-$name.fits" && cp out.stdout "sources-$name.jsonl"
    run decompose "$case" decompose -i "sources-$name.jsonl" --stamps "stamps-$name.fits"
    cells+=("$cell")
  else
    cells+=("—")
  fi
}

echo "| case | detect | decompose | smooth | sample | render | render \`--psf\` | measure |"
echo "|---|---|---|---|---|---|---|---|"
row() {
  local line="|" cell
  for cell in "$@"; do line+=" $cell |"; done
  echo "$line"
}

# Images: every program that takes one. Headers without a WCS get --pixel-scale, as the
# error message tells a user to do.
for f in good bitpix8 bitpix16 bitpix32 bitpix-64 fpack extension no-wcs blank-ctype sip \
  row column tiny all-zero all-nan inf huge tiny-values some-nan hot-pixels saturated-star zero-border \
  truncated header-only empty text naxis0 cube; do
  c=$f.fits
  scale=()
  case $f in no-wcs | blank-ctype) scale=(--pixel-scale 0.04 --ra 189.2 --dec 62.2) ;; esac
  cells=("\`$c\`")
  detect_and_decompose "$c" "$f" "$c" "${scale[@]}"
  run smooth "$c" smooth -i base/shapelets.jsonl --like "$c" "${scale[@]:0:2}"
  cells+=("$cell")
  run sample "$c" sample base/model.json --like "$c" "${scale[@]}" --seed 1
  cells+=("$cell")
  run render "$c" render -i base/objects.jsonl --psf base/psf.jsonl --galaxy-psf base/psf.jsonl \
    --place-by-sky --like "$c" "${scale[@]}" --seed 1 -o out/sim.fits
  cells+=("$cell" "—")
  run measure "$c" measure "$c" "${scale[@]}"
  cells+=("$cell")
  row "${cells[@]}"
done

# Weight maps of good.fits: the programs that read one.
for f in weight weight-zeros weight-nan weight-all-zero weight-small; do
  c=$f.fits
  cells=("\`good.fits --weight $c\`")
  detect_and_decompose "$c" "$f" good.fits --weight "$c"
  cells+=("—" "—" "—" "—")
  run measure "$c" measure good.fits --weight "$c"
  cells+=("$cell")
  row "${cells[@]}"
done

# JSON: each program's JSON input replaced by the case (detect and render --psf read a PSF
# record, decompose sources, smooth shapelets, sample a model, render objects, measure
# --compare its own records).
json_row() {
  local label=$1 psf=$2 sources=$3 shapelets=$4 model=$5 objects=$6 morph=$7
  cells=("$label")
  run detect "$label" detect good.fits --psf "$psf" --stamps out/stamps.fits
  cells+=("$cell")
  run decompose "$label" decompose -i "$sources" --stamps base/stamps.fits
  cells+=("$cell")
  run smooth "$label" smooth -i "$shapelets"
  cells+=("$cell")
  run sample "$label" sample "$model" --like good.fits --seed 1
  cells+=("$cell")
  run render "$label" render -i "$objects" --psf base/psf.jsonl --galaxy-psf base/psf.jsonl \
    --like good.fits -o out/sim.fits
  cells+=("$cell")
  run render-psf "$label" render -i base/objects.jsonl --psf "$psf" --galaxy-psf base/psf.jsonl \
    --like good.fits -o out/sim.fits
  cells+=("$cell")
  run measure "$label" measure --compare "a=$morph" b=base/morph.jsonl -o out/compare
  cells+=("$cell")
  row "${cells[@]}"
}
for f in empty blank-lines not-json array nan-literal deep binary; do
  c=$f.jsonl
  json_row "\`$c\`" "$c" "$c" "$c" "$c" "$c" "$c"
done
for kind in truncated wrong-schema zeros negative huge nulls strings big-integers; do
  for input in psf.jsonl sources.jsonl shapelets.jsonl model.json objects.jsonl morph.jsonl; do
    python3 "$here/mutate.py" "$kind" <"base/$input" >"$kind-$input" ||
      die "mutate.py $kind $input failed"
  done
  json_row "each input: $kind" "$kind-psf.jsonl" "$kind-sources.jsonl" \
    "$kind-shapelets.jsonl" "$kind-model.json" "$kind-objects.jsonl" "$kind-morph.jsonl"
done

echo
echo "Messages (errors, and the first warning of a result):"
echo
echo "| case | program | stderr |"
echo "|---|---|---|"
printf '%s\n' "${notes[@]}"
[ "$failures" -eq 0 ] || { echo "matrix.sh: $failures cells FAIL" >&2; exit 1; }
